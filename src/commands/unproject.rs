//! `kitti2pgm unproject`: the CLI over [`kitti2pgm::report::unproject`].

use kitti2pgm::format::imageset;
use kitti2pgm::report::score::Predictions;
use kitti2pgm::report::truth::GroundTruth;
use kitti2pgm::report::unproject::{
    refuse_viz_over_inputs, unproject_all, write_viz, UnprojectOptions, UnprojectSummary,
    NOT_PREDICTED,
};

use super::{completeness, durability, progress, Global};
use crate::cli::UnprojectArgs;
use crate::Outcome;

pub fn run(a: UnprojectArgs, g: &Global) -> anyhow::Result<Outcome> {
    // Parameters first: a usage error before anything is read.
    let method = a.knn.method(a.method);
    method.validate()?;
    let gt = GroundTruth::open_with(&a.gt, completeness(a.partial))?;
    if let Some(p) = &gt.partial {
        eprintln!("kitti2pgm: PARTIAL: {p}");
    }
    let preds = Predictions::index(&a.pred)?;
    let only = match &a.imageset {
        Some(l) => {
            let list = if l.is_dir() {
                l.join("val.txt")
            } else {
                l.clone()
            };
            Some(imageset::read(&list)?.into_iter().collect())
        }
        None => None,
    };
    let opts = UnprojectOptions {
        method,
        raw: a.raw.clone(),
        out: a.out.clone(),
        only,
        durability: durability(a.sync),
    };
    // `unproject_all` checks the output folder before any work; the --viz file is written
    // after the work, so it is checked here, before it.
    if let Some(viz) = &a.viz {
        refuse_viz_over_inputs(viz, &gt, &preds, &opts)?;
    }
    let total = opts.only.as_ref().map_or(gt.frames.len(), |o| o.len());
    let pb = progress::bar(total as u64, g.progress, "unprojecting");
    let pool = g.pool()?;
    let s = pool.install(|| unproject_all(&gt, &preds, &opts, &|n| pb.inc(n)))?;
    pb.finish_and_clear();
    if a.json {
        println!("{}", serde_json::to_string_pretty(&s)?);
    } else {
        print!("{}", table(&s, &gt));
    }
    for f in &s.failures {
        eprintln!("kitti2pgm: {}: {}", f.frame, f.error);
    }
    if let Some(viz) = &a.viz {
        let frames = &s.written;
        write_viz(&gt, &preds, &opts, frames, viz)?;
        if !a.json {
            println!("viz              {:>10}  ({})", frames.len(), viz.display());
        }
    }
    Ok(match (s.failures.is_empty(), s.frames) {
        (true, _) => Outcome::Ok,
        (false, 0) => Outcome::Failed("no frame could be carried back".into()),
        (false, _) => Outcome::Partial,
    })
}

/// The summary as a table.
fn table(s: &UnprojectSummary, gt: &GroundTruth) -> String {
    use std::fmt::Write;
    let mut t = String::new();
    let _ = writeln!(t, "method           {:>10}", s.method);
    let _ = writeln!(
        t,
        "frames written   {:>10}  (into {})",
        s.frames,
        s.written_to.display()
    );
    if s.not_carried > 0 {
        let _ = writeln!(
            t,
            "not carried      {:>10}  (ground-truth frames not listed, or of drives without any prediction)",
            s.not_carried
        );
    }
    let _ = writeln!(t, "points           {:>10}", s.points);
    let _ = writeln!(
        t,
        "not predicted    {:>10}  (outside the map's field of view: {})",
        s.not_predicted,
        if gt
            .frames
            .iter()
            .any(|f| f.dataset == kitti2pgm::source::kitti::DatasetKind::Sequence)
        {
            "raw id 0, unlabeled".to_string()
        } else {
            format!("class {NOT_PREDICTED:#06x}")
        }
    );
    t
}
