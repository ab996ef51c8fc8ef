//! `kitti2pgm score`: the CLI over [`kitti2pgm::report::score`].

use std::collections::BTreeSet;
use std::fmt::Write as _;

use anyhow::Context;
use kitti2pgm::draw::charts::{confusion_chart, frame_chart};
use kitti2pgm::format::{imageset, png};
use kitti2pgm::label::ClassMap;
use kitti2pgm::project::unproject::Method;
use kitti2pgm::report::score::{
    per_frame, predictions_without_truth, report, score, worst, PredictionKind, Predictions,
    Protocol, ScoreOptions, ScoreReport,
};
use kitti2pgm::report::truth::{GroundTruth, Provenance};
use kitti2pgm::source::kitti::FrameId;

use super::completeness;

use super::{progress, Global};
use crate::cli::ScoreArgs;
use crate::Outcome;
use kitti2pgm::project::unproject::MethodKind;

/// The frames to score: an ImageSet list, or an ImageSet folder's val.txt (what a model is
/// evaluated on); `None` for every frame.
fn only_frames(imageset: Option<&std::path::PathBuf>) -> anyhow::Result<Option<BTreeSet<FrameId>>> {
    let Some(l) = imageset else { return Ok(None) };
    let list = if l.is_dir() {
        l.join("val.txt")
    } else {
        l.clone()
    };
    if !list.is_file() {
        anyhow::bail!(
            "{}: no such frame list (give an ImageSet list such as OUT/ImageSet/val.txt, or the ImageSet folder for its val.txt)",
            list.display()
        );
    }
    Ok(Some(imageset::read(&list)?.into_iter().collect()))
}

/// The scoring options: the point protocol for a SemanticKITTI root, `--points` or a
/// back-projection; map predictions of a SemanticKITTI conversion with the scans at hand are
/// carried to the points by RangeNet++'s kNN by default, as the benchmark scores points.
fn options(
    a: &ScoreArgs,
    gt: &GroundTruth,
    preds: &Predictions,
) -> (ScoreOptions, Option<MethodKind>) {
    let dataset = matches!(gt.source, kitti2pgm::report::truth::Source::Dataset(_));
    let sequence = gt
        .frames
        .iter()
        .any(|f| f.dataset == kitti2pgm::source::kitti::DatasetKind::Sequence);
    let by_default = sequence
        && a.raw.is_some()
        && !a.points
        && preds.kind != PredictionKind::Points
        && !dataset;
    let unproject = a.unproject.or(by_default.then_some(MethodKind::Knn));
    let opts = ScoreOptions {
        protocol: if a.points || dataset || unproject.is_some() {
            Protocol::Points
        } else {
            Protocol::Cells
        },
        missing_as_background: a.missing_as_background,
        raw: a.raw.clone(),
        unproject: unproject.map_or(Method::Cell, |m| a.knn.method(m)),
    };
    (opts, unproject)
}

/// Refuses pictures (`--confusion`, `--worst`'s folder) over an input.
fn refuse_pictures_over_inputs(a: &ScoreArgs) -> anyhow::Result<()> {
    use kitti2pgm::fs::Role;
    let mut inputs = vec![
        (Role::GroundTruth, a.gt.as_path()),
        (Role::Predictions, a.pred.as_path()),
    ];
    inputs.extend(a.raw.as_deref().map(|p| (Role::Dataset, p)));
    inputs.extend(a.imageset.as_deref().map(|p| (Role::List, p)));
    let worst = a.worst.map(|_| a.worst_dir.as_path());
    for out in a.confusion.as_deref().into_iter().chain(worst) {
        kitti2pgm::fs::refuse_overlap(out, &inputs)?;
    }
    Ok(())
}

pub fn run(a: ScoreArgs, g: &Global) -> anyhow::Result<Outcome> {
    refuse_pictures_over_inputs(&a)?;
    a.knn
        .method(kitti2pgm::project::unproject::MethodKind::Knn)
        .validate()?;
    let preds = Predictions::index(&a.pred)?;
    let gt = GroundTruth::open_with(&a.gt, completeness(a.partial))?;
    if gt.provenance == Provenance::Assumed || gt.partial.is_some() {
        eprintln!("kitti2pgm: {}", gt.provenance_note());
    }
    let only = only_frames(a.imageset.as_ref())?;
    let (opts, unproject) = options(&a, &gt, &preds);
    let map = &gt.params.class_map;
    let pool = g.pool()?;
    let context = || format!("scoring {} against {}", a.pred.display(), a.gt.display());
    let total = only.as_ref().map_or(gt.frames.len(), |o| o.len());
    let pb = progress::bar(total as u64, g.progress, "scoring");
    let none = BTreeSet::new();
    let (scores, _) = pool
        .install(|| score(&gt, only.as_ref(), &preds, &opts, &none, &|n| pb.inc(n)))
        .with_context(context)?;
    pb.finish_and_clear();
    let mut rep = report(opts.protocol, &scores, map);
    if a.per_frame {
        rep.per_frame = Some(per_frame(&scores, map));
    }
    rep.predictions_without_truth = predictions_without_truth(&gt, &preds);
    if let Some(first) = rep.predictions_without_truth.first() {
        eprintln!(
            "kitti2pgm: {} prediction(s) for frames not in the ground truth, not scored (first: {first})",
            rep.predictions_without_truth.len()
        );
    }
    if let Some(method) = unproject {
        // The same predictions per cell, for the 2D figures beside the 3D ones.
        let cells = ScoreOptions {
            protocol: Protocol::Cells,
            unproject: Method::Cell,
            ..opts.clone()
        };
        let (cell_scores, _) = pool
            .install(|| score(&gt, only.as_ref(), &preds, &cells, &none, &|_| {}))
            .with_context(context)?;
        let rep2d = report(Protocol::Cells, &cell_scores, map);
        if a.json {
            let j = serde_json::json!({
                "unproject": format!("{method:?}").to_lowercase(),
                "cells": rep2d,
                "points": rep,
            });
            println!("{}", serde_json::to_string_pretty(&j)?);
        } else {
            print!("{}", side_by_side(&rep2d, &rep, map));
        }
        return Ok(Outcome::Ok);
    }
    if let Some(p) = &a.confusion {
        png::write(p, &confusion_chart(&rep.confusion, map))?;
    }
    if let Some(n) = a.worst {
        if matches!(gt.source, kitti2pgm::report::truth::Source::Dataset(_)) {
            anyhow::bail!("--worst draws maps; a SemanticKITTI root holds points (score a converted folder for pictures)");
        }
        let worst_maps = |ids: &BTreeSet<FrameId>| {
            pool.install(|| score(&gt, Some(ids), &preds, &opts, ids, &|_| {}))
                .with_context(context)
        };
        draw_worst(&a, &gt, &scores, n, worst_maps)?;
    }
    if a.json {
        println!("{}", serde_json::to_string_pretty(&rep)?);
    } else {
        print!("{}", table(&rep, map, false));
    }
    Ok(Outcome::Ok)
}

/// Pictures of the `n` worst frames, ranked, into `--worst-dir`; `maps_of` scores the frames
/// again keeping their maps.
fn draw_worst(
    a: &ScoreArgs,
    gt: &GroundTruth,
    scores: &[kitti2pgm::report::score::FrameScore],
    n: usize,
    maps_of: impl Fn(
        &BTreeSet<FrameId>,
    ) -> anyhow::Result<(
        Vec<kitti2pgm::report::score::FrameScore>,
        std::collections::BTreeMap<FrameId, kitti2pgm::report::score::FrameMaps>,
    )>,
) -> anyhow::Result<()> {
    let map = &gt.params.class_map;
    let ranked = worst(scores, n, map);
    std::fs::create_dir_all(&a.worst_dir)
        .with_context(|| format!("creating {}", a.worst_dir.display()))?;
    let ids: BTreeSet<FrameId> = ranked.iter().map(|(i, _)| scores[*i].id.clone()).collect();
    let (_, mut maps) = maps_of(&ids)?;
    let shape = (gt.params.spec.rows, gt.params.spec.cols);
    for (rank, (i, m)) in ranked.iter().enumerate() {
        let id = &scores[*i].id;
        let frame_maps = maps.remove(id).expect("asked for");
        let img = frame_chart(&id.to_string(), &frame_maps, shape, Some(*m), map);
        png::write(&a.worst_dir.join(format!("{:03}_{id}.png", rank + 1)), &img)?;
    }
    Ok(())
}

/// A figure with 4 decimals, `-` when there is none.
fn figure(v: Option<f64>) -> String {
    v.map(|x| format!("{x:.4}")).unwrap_or_else(|| "-".into())
}

/// The width of the class column: the longest class name, at least "class".
fn name_width(map: &ClassMap) -> usize {
    map.names()
        .iter()
        .map(|n| n.len())
        .max()
        .unwrap_or(5)
        .max(5)
}

/// The cell (2D) and point (3D) figures of the same predictions, side by side.
fn side_by_side(cells: &ScoreReport, points: &ScoreReport, map: &ClassMap) -> String {
    let mut t = String::new();
    let f = figure;
    let _ = writeln!(
        t,
        "{} frames: {} cells (2D) and {} points (3D) scored",
        points.frames, cells.elements, points.elements
    );
    let w = name_width(map);
    let _ = writeln!(
        t,
        "\n{:<w$} {:>9} {:>9} {:>9} {:>12}",
        "class", "IoU 2D", "IoU 3D", "3D - 2D", "3D support"
    );
    for name in map.names() {
        let (c, p) = (&cells.classes[name], &points.classes[name]);
        let d = match (c.iou, p.iou) {
            (Some(a), Some(b)) => format!("{:+.4}", b - a),
            _ => "-".into(),
        };
        let _ = writeln!(
            t,
            "{:<w$} {:>9} {:>9} {:>9} {:>12}",
            name,
            f(c.iou),
            f(p.iou),
            d,
            p.support
        );
    }
    let _ = writeln!(
        t,
        "\n{:<w$} {:>9.4} {:>9.4} {:>+9.4}",
        "mIoU",
        cells.miou,
        points.miou,
        points.miou - cells.miou
    );
    let _ = writeln!(
        t,
        "{:<w$} {:>9} {:>9}",
        "accuracy",
        f(cells.accuracy),
        f(points.accuracy)
    );
    t
}

fn table(r: &ScoreReport, map: &ClassMap, full_confusion: bool) -> String {
    use kitti2pgm::label::classes::AbsentInMiou;
    let mut t = String::new();
    let f = figure;
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
    let w = name_width(map);
    let _ = writeln!(
        t,
        "\n{:<w$} {:>8} {:>10} {:>8} {:>12}",
        "class", "IoU", "precision", "recall", "support"
    );
    for name in map.names() {
        let s = &r.classes[name];
        let _ = writeln!(
            t,
            "{:<w$} {:>8} {:>10} {:>8} {:>12}",
            name,
            f(s.iou),
            f(s.precision),
            f(s.recall),
            s.support
        );
    }
    let rule = match r.miou_absent {
        AbsentInMiou::LeftOut => "a class absent from truth and prediction is left out",
        AbsentInMiou::Zero => {
            "a class absent from truth and prediction counts 0, as the benchmark's"
        }
    };
    let over = if r.miou_classes.len() <= 6 {
        r.miou_classes.join(", ")
    } else {
        let left: Vec<&str> = map
            .names()
            .into_iter()
            .filter(|n| !r.miou_classes.iter().any(|c| c == n))
            .collect();
        format!("all but {}", left.join(", "))
    };
    let _ = writeln!(
        t,
        "\nmIoU     {:.4}  (mean over {} classes: {over}; {rule})",
        r.miou,
        r.miou_classes.len(),
    );
    let _ = writeln!(
        t,
        "accuracy {}  (correct {what} over all scored)",
        f(r.accuracy)
    );
    // The matrix only where it fits a terminal: SemanticKITTI's 20 x 20 is in --json and
    // --confusion PNG.
    if full_confusion || map.len() <= 6 {
        confusion_rows(&mut t, r, map, w);
    } else {
        let _ = writeln!(
            t,
            "(the {}x{} confusion matrix: --json, or --confusion PNG for a picture)",
            map.len(),
            map.len()
        );
    }
    if let Some(pf) = &r.per_frame {
        per_frame_rows(&mut t, r, pf);
    }
    t
}

/// The confusion matrix, rows truth, columns prediction.
fn confusion_rows(t: &mut String, r: &ScoreReport, map: &ClassMap, w: usize) {
    let cw = w.max(9) + 1;
    let _ = writeln!(t, "\nconfusion (rows: truth, columns: prediction)");
    let _ = write!(t, "{:<w$}", "");
    for name in map.names() {
        let _ = write!(t, "{name:>cw$}");
    }
    let _ = writeln!(t);
    for (g, name) in map.names().iter().enumerate() {
        let _ = write!(t, "{name:<w$}");
        for v in &r.confusion.m[g] {
            let _ = write!(t, "{v:>cw$}");
        }
        let _ = writeln!(t);
    }
}

/// A row per frame: the IoU of each mIoU class and the frame's own mean.
fn per_frame_rows(t: &mut String, r: &ScoreReport, pf: &[kitti2pgm::report::score::FramePerf]) {
    let f = figure;
    let _ = write!(t, "\n{:<28}", "frame");
    for name in &r.miou_classes {
        let _ = write!(t, " {:>11}", name.chars().take(11).collect::<String>());
    }
    let _ = writeln!(t, " {:>8} {:>10}", "mIoU*", "elements");
    for p in pf {
        let _ = write!(t, "{:<28}", p.id.to_string());
        for name in &r.miou_classes {
            let _ = write!(t, " {:>11}", f(p.iou[name]));
        }
        let _ = writeln!(t, " {:>8} {:>10}", f(p.miou_present), p.elements);
    }
    let _ = writeln!(t, "(* mean over the object classes present in the frame)");
}
