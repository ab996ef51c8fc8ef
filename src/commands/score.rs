//! `kitti2pgm score`: the CLI over [`kitti2pgm::report::score`].

use std::fmt::Write as _;

use anyhow::Context;
use kitti2pgm::label::Class;
use kitti2pgm::pipeline::SUMMARY_FILE;
use kitti2pgm::project::PgmSpec;
use kitti2pgm::report::imageset;
use kitti2pgm::report::score::{
    confusion_chart, frame_chart, report, score, score_frame, score_shards, Predictions, Protocol,
    ScoreOptions, ScoreReport,
};
use kitti2pgm::report::stats::{converted_frames, npy_path};
use kitti2pgm::write::write_png;

use super::{progress, Global};
use crate::cli::ScoreArgs;
use crate::Outcome;

/// The map the ground truth was made with: its convert summary's, else the default with the
/// first frame's rows and columns.
fn gt_spec(a: &ScoreArgs, first: &kitti2pgm::kitti::FrameId) -> anyhow::Result<PgmSpec> {
    let summary = a.gt.join(SUMMARY_FILE);
    if let Ok(text) = std::fs::read_to_string(&summary) {
        let v: serde_json::Value = serde_json::from_str(&text)
            .with_context(|| format!("{}: not JSON", summary.display()))?;
        if !v["spec"].is_null() {
            return serde_json::from_value(v["spec"].clone()).with_context(|| {
                format!("{}: `spec` is not a map specification", summary.display())
            });
        }
    }
    let (shape, _) = kitti2pgm::write::npy::read_f32(&npy_path(&a.gt, first))?;
    Ok(PgmSpec {
        rows: shape[0] as usize,
        cols: shape[1] as usize,
        ..PgmSpec::default()
    })
}

fn png(img: &image::RgbImage, path: &std::path::Path) -> anyhow::Result<()> {
    Ok(write_png(path, img)?)
}

/// Ground truth shards, when `--gt` names shards (a .mcap file, a folder of them, or a convert
/// folder holding only shards/).
fn gt_shards(gt: &std::path::Path) -> anyhow::Result<Option<Vec<std::path::PathBuf>>> {
    if gt.is_file() && gt.extension().is_some_and(|e| e == "mcap") {
        return Ok(Some(vec![gt.to_path_buf()]));
    }
    if !gt.is_dir() {
        anyhow::bail!("{}: no such ground-truth folder or shard", gt.display());
    }
    if gt.join("lidar_2d").is_dir() {
        return Ok(None);
    }
    for dir in [gt.to_path_buf(), gt.join("shards")] {
        let mut v: Vec<_> = std::fs::read_dir(&dir)
            .into_iter()
            .flatten()
            .flatten()
            .map(|e| e.path())
            .filter(|p| p.extension().is_some_and(|e| e == "mcap"))
            .collect();
        if !v.is_empty() {
            v.sort();
            return Ok(Some(v));
        }
    }
    anyhow::bail!(
        "{}: neither a convert output folder (lidar_2d/) nor shards (*.mcap)",
        gt.display()
    )
}

fn shard_spec(first: &std::path::Path) -> anyhow::Result<PgmSpec> {
    let md = kitti2pgm::write::shard::Shard::open(first)?.metadata()?;
    let v: serde_json::Value = serde_json::from_str(&md.params)
        .with_context(|| format!("{}: shard parameters are not JSON", first.display()))?;
    serde_json::from_value(v["spec"].clone()).with_context(|| {
        format!(
            "{}: no map specification in the shard parameters",
            first.display()
        )
    })
}

pub fn run(a: ScoreArgs, g: &Global) -> anyhow::Result<Outcome> {
    let preds = Predictions::index(&a.pred)?;
    let shards = gt_shards(&a.gt)?;
    let listed = a.imageset.as_ref().map(|l| imageset::read(l)).transpose()?;
    let spec = match (&shards, &listed) {
        (Some(s), _) => shard_spec(&s[0])?,
        (None, Some(l)) => gt_spec(&a, l.first().context("the ImageSet list is empty")?)?,
        (None, None) => gt_spec(
            &a,
            converted_frames(&a.gt)?
                .first()
                .context("no converted frame")?,
        )?,
    };
    let opts = ScoreOptions {
        protocol: if a.points {
            Protocol::Points
        } else {
            Protocol::Cells
        },
        missing_as_background: a.missing_as_background,
        raw: a.raw.clone(),
        spec,
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(g.threads)
        .build()?;
    let context = || format!("scoring {} against {}", a.pred.display(), a.gt.display());
    let (scores, frames): (Vec<_>, Vec<kitti2pgm::kitti::FrameId>) = match &shards {
        Some(sh) => {
            let pb = progress::bar(
                listed.as_ref().map_or(0, |l| l.len() as u64),
                g.progress,
                "scoring",
            );
            let only: Option<std::collections::BTreeSet<_>> =
                listed.clone().map(|l| l.into_iter().collect());
            let (s, _) = pool
                .install(|| {
                    score_shards(
                        sh,
                        only.as_ref(),
                        &preds,
                        &opts,
                        &Default::default(),
                        &|n| pb.inc(n),
                    )
                })
                .with_context(context)?;
            pb.finish_and_clear();
            let ids = s
                .iter()
                .map(|x| x.id.parse().expect("ids come from the shards"))
                .collect();
            (s, ids)
        }
        None => {
            let frames = match listed.clone() {
                Some(l) => l,
                None => converted_frames(&a.gt)?,
            };
            let pb = progress::bar(frames.len() as u64, g.progress, "scoring");
            let s = pool
                .install(|| score(&a.gt, &frames, &preds, &opts, &|n| pb.inc(n)))
                .with_context(context)?;
            pb.finish_and_clear();
            (s, frames)
        }
    };
    let rep = report(opts.protocol, &scores, a.per_frame);
    if let Some(p) = &a.confusion {
        png(&confusion_chart(&rep.confusion), p)?;
    }
    if let Some(n) = a.worst {
        let mut ranked: Vec<(f64, usize)> = scores
            .iter()
            .enumerate()
            .filter_map(|(i, s)| s.confusion.miou_present().map(|m| (m, i)))
            .collect();
        ranked.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
        ranked.truncate(n);
        std::fs::create_dir_all(&a.worst_dir)
            .with_context(|| format!("creating {}", a.worst_dir.display()))?;
        let mut maps = match &shards {
            Some(sh) => {
                let want: std::collections::BTreeSet<String> =
                    ranked.iter().map(|(_, i)| scores[*i].id.clone()).collect();
                let only: std::collections::BTreeSet<_> =
                    ranked.iter().map(|(_, i)| frames[*i].clone()).collect();
                pool.install(|| score_shards(sh, Some(&only), &preds, &opts, &want, &|_| {}))?
                    .1
            }
            None => Default::default(),
        };
        for (rank, (m, i)) in ranked.iter().enumerate() {
            let id = &frames[*i];
            let frame_maps = match maps.remove(&id.to_string()) {
                Some(fm) => fm,
                None => score_frame(&a.gt, id, &preds, &opts, true)?
                    .1
                    .expect("asked for"),
            };
            let img = frame_chart(&id.to_string(), &frame_maps, spec.rows, spec.cols, Some(*m));
            png(&img, &a.worst_dir.join(format!("{:03}_{id}.png", rank + 1)))?;
        }
    }
    if a.json {
        println!("{}", serde_json::to_string_pretty(&rep)?);
    } else {
        print!("{}", table(&rep));
    }
    Ok(Outcome::Ok)
}

fn table(r: &ScoreReport) -> String {
    let mut t = String::new();
    let f = |v: Option<f64>| v.map(|x| format!("{x:.4}")).unwrap_or_else(|| "-".into());
    let what = if r.protocol == Protocol::Cells {
        "cells"
    } else {
        "points"
    };
    let _ = writeln!(
        t,
        "{} frames, {} {what} scored ({} frames without prediction scored as background)",
        r.frames, r.elements, r.missing_frames
    );
    let _ = writeln!(
        t,
        "\n{:<12} {:>8} {:>10} {:>8} {:>12}",
        "class", "IoU", "precision", "recall", "support"
    );
    for c in Class::ALL {
        let s = &r.classes[c.name()];
        let _ = writeln!(
            t,
            "{:<12} {:>8} {:>10} {:>8} {:>12}",
            c.name(),
            f(s.iou),
            f(s.precision),
            f(s.recall),
            s.support
        );
    }
    let _ = writeln!(
        t,
        "\nmIoU (car, pedestrian, cyclist; absent classes left out): {:.4}",
        r.miou
    );
    let _ = writeln!(t, "\nconfusion (rows: truth, columns: prediction)");
    let _ = write!(t, "{:<12}", "");
    for c in Class::ALL {
        let _ = write!(t, "{:>13}", c.name());
    }
    let _ = writeln!(t);
    for g in Class::ALL {
        let _ = write!(t, "{:<12}", g.name());
        for p in Class::ALL {
            let _ = write!(t, "{:>13}", r.confusion.m[g as usize][p as usize]);
        }
        let _ = writeln!(t);
    }
    if let Some(pf) = &r.per_frame {
        let _ = writeln!(
            t,
            "\n{:<28} {:>8} {:>8} {:>11} {:>8} {:>10}",
            "frame", "car", "ped", "cyclist", "mIoU*", "elements"
        );
        for p in pf {
            let _ = writeln!(
                t,
                "{:<28} {:>8} {:>8} {:>11} {:>8} {:>10}",
                p.id,
                f(p.iou["car"]),
                f(p.iou["pedestrian"]),
                f(p.iou["cyclist"]),
                f(p.miou_present),
                p.elements
            );
        }
        let _ = writeln!(t, "(* mean over the object classes present in the frame)");
    }
    t
}
