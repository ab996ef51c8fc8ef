//! `kitti2pgm infer`: the CLI over [`kitti2pgm::infer`].

use kitti2pgm::infer::{
    infer, InferOptions, InferSummary, Model, ModelOptions, ModelSpec, Progress,
};
use kitti2pgm::report::truth::GroundTruth;

use super::{durability, progress, Global};
use crate::cli::InferArgs;
use crate::Outcome;

pub fn run(a: InferArgs, g: &Global) -> anyhow::Result<Outcome> {
    // Parameters first: a usage error before anything is read.
    let method = a.knn.method(a.method);
    method.validate()?;
    let spec = match &a.map_from {
        Some(dir) => Some(ModelSpec::for_map(GroundTruth::open(dir)?.params)),
        None => None,
    };
    let model = Model::open(
        &a.model,
        &ModelOptions {
            onnxruntime: a.onnxruntime.clone(),
            threads: a.model_threads,
            spec,
        },
    )?;
    let opts = InferOptions {
        out: a.out.clone(),
        method,
        maps: a.maps,
        dataset: a.dataset,
        topic: a.topic.clone(),
        viz: a.viz.clone(),
        as_labels: a.as_labels.clone(),
        overwrite: a.overwrite,
        durability: durability(a.sync),
    };
    let pb = progress::bar(0, g.progress, "inferring");
    let pool = g.pool()?;
    let s = pool.install(|| {
        infer(&model, &a.input, &opts, &|p| match p {
            Progress::Frames(n) => pb.set_length(n),
            Progress::Done(n) => pb.inc(n),
        })
    })?;
    pb.finish_and_clear();
    if a.json {
        println!("{}", serde_json::to_string_pretty(&s)?);
    } else {
        print!("{}", table(&s, &model));
    }
    for f in &s.failures {
        eprintln!("kitti2pgm: {}: {}", f.frame, f.error);
    }
    Ok(match (s.failures.is_empty(), s.frames) {
        (true, 0) => Outcome::Failed(format!(
            "{}: no scan to run the model on",
            a.input.display()
        )),
        (true, _) => Outcome::Ok,
        (false, 0) => Outcome::Failed("no scan could be run".into()),
        (false, _) => Outcome::Partial,
    })
}

/// The summary as a table.
fn table(s: &InferSummary, model: &Model) -> String {
    use std::fmt::Write;
    let mut t = String::new();
    let map = &model.spec.map;
    let _ = writeln!(t, "model            {}  ({})", s.model.display(), s.digest);
    let _ = writeln!(
        t,
        "map              {} x {}, {:.0} deg, class map {}{}",
        map.spec.rows,
        map.spec.cols,
        map.spec.fov.0,
        map.class_map.name,
        if model.recorded {
            ""
        } else {
            "  (given: --map-from)"
        }
    );
    let _ = writeln!(t, "method           {:>10}", s.method);
    let _ = writeln!(t, "frames           {:>10}", s.frames);
    for (what, path) in [
        ("predictions", &s.written_to),
        ("labels in", &s.labels_in),
        ("replay", &s.viz),
    ] {
        if let Some(p) = path {
            let _ = writeln!(t, "{what:<16} {}", p.display());
        }
    }
    let _ = writeln!(t, "points           {:>10}", s.points);
    let _ = writeln!(
        t,
        "not predicted    {:>10}  (outside the map)",
        s.not_predicted
    );
    let total: u64 = s.classes.iter().map(|(_, n)| n).sum::<u64>().max(1);
    let _ = writeln!(t, "\nclass            points        %");
    for (name, n) in &s.classes {
        let _ = writeln!(
            t,
            "{name:<16} {n:>10} {:>7.3}%",
            100.0 * *n as f64 / total as f64
        );
    }
    let sec = &s.seconds;
    let busy = (sec.read_project + sec.model + sec.unproject + sec.write).max(1e-9);
    let _ = writeln!(t, "\nstage            seconds   share");
    for (name, v) in [
        ("read+project", sec.read_project),
        ("model", sec.model),
        ("unproject", sec.unproject),
        ("write", sec.write),
    ] {
        let _ = writeln!(t, "{name:<16} {v:>7.3} {:>6.1}%", 100.0 * v / busy);
    }
    let _ = writeln!(t, "wall             {:>7.3}", s.wall_seconds);
    t
}
