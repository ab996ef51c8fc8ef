//! SCORE against a SemanticKITTI root, with the benchmark's own protocol.
//!
//! `evaluate_semantics.py` of the SemanticKITTI API: every point of every scan counts, with
//! its ground truth from `sequences/<NN>/labels/<frame6>.label` and its prediction from
//! `sequences/<NN>/predictions/<frame6>.label` (both raw ids, both through the learning map);
//! points whose ground truth is an ignored class (0, `unlabeled`) are not counted; IoU = TP /
//! (TP + FP + FN) per class, and mIoU the mean over the 19 other classes, a class absent from
//! truth and prediction counting 0 (`AbsentInMiou::Zero`). Per-point `.label` files that
//! `convert` wrote (class ids, `labels/<NN>/<frame6>.label`) are read as class ids.

use std::path::Path;

use rayon::prelude::*;

use super::confusion::Confusion;
use super::predictions::{PredictionKind, Predictions};
use super::{FrameScore, ScoreOptions};
use crate::error::{Error, Result};
use crate::format::label_file;
use crate::label::{ClassId, ClassMap};
use crate::report::truth::GroundTruth;
use crate::source::kitti::{Drive, FrameId};

/// What the entries of a `.label` file are.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum LabelIds {
    /// SemanticKITTI's raw ids (the benchmark's `.../predictions/` and the dataset's `labels/`),
    /// read through the learning map.
    Raw,
    /// Class ids of the class map (`convert`'s `labels/`).
    Class,
}

impl LabelIds {
    /// The ids of a prediction file: raw in a `predictions/` folder, class ids elsewhere.
    fn of_prediction(path: &Path) -> LabelIds {
        let dir = path.parent().and_then(|d| d.file_name());
        if dir.is_some_and(|n| n == "predictions") {
            LabelIds::Raw
        } else {
            LabelIds::Class
        }
    }
}

/// The classes of a `.label` file holding `ids`.
fn classes(path: &Path, ids: LabelIds, map: &ClassMap) -> Result<Vec<ClassId>> {
    if ids == LabelIds::Class {
        return label_file::read_classes(path, map).map_err(|e| match e {
            Error::NotAClass { path, what, value, map, max, .. } => Error::NotAClass {
                path,
                what,
                value,
                map,
                max,
                hint: Some("raw SemanticKITTI ids (the benchmark's) are read from sequences/<NN>/predictions/<frame6>.label, class ids from convert's labels/<NN>/<frame6>.label"),
            },
            other => other,
        });
    }
    map.classes_of_raw(&label_file::read_raw(path)?, path)
}

fn score_one(
    drive: &Drive,
    id: &FrameId,
    preds: &Predictions,
    opts: &ScoreOptions,
    map: &ClassMap,
) -> Result<FrameScore> {
    let truth_path = drive.point_labels_path(id.frame);
    let truth = classes(&truth_path, LabelIds::Raw, map)?;
    // The truth is checked against its scan first, so that a truncated truth file is blamed,
    // not the prediction.
    let scan_path = drive.scan_path(id.frame);
    // A KITTI .bin by its size, a PCD (another sensor's scans) by its header.
    let scan_points = match crate::source::points_in_file(&scan_path) {
        Some(n) => n,
        None => {
            std::fs::metadata(&scan_path).map_err(|e| Error::io(&scan_path, e))?;
            return Err(Error::format(
                &scan_path,
                "not a readable scan (.bin, .pcd)",
            ));
        }
    };
    if truth.len() as u64 != scan_points {
        return Err(Error::LabelCount {
            path: truth_path,
            labels: truth.len(),
            scan: scan_path,
            points: scan_points as usize,
            note: Some("truncated ground truth?"),
        });
    }
    let pred = match preds.files.get(id) {
        Some(p) if preds.kind == PredictionKind::Points => Some(classes(p, LabelIds::of_prediction(p), map)?),
        Some(p) => {
            return Err(Error::Input {
                path: p.clone(),
                message: "a SemanticKITTI root is scored per point: predictions are .label files (PRED/sequences/<NN>/predictions/<frame6>.label, raw ids, the benchmark's layout)".into(),
            })
        }
        None if opts.missing_as_background => None,
        None => {
            return Err(Error::MissingPrediction {
                root: preds.root.clone(),
                frame: id.to_string(),
                expected: Some(format!(
                    "PRED/sequences/{:02}/predictions/{:06}.label",
                    id.drive, id.frame
                )),
            })
        }
    };
    if let Some(p) = &pred {
        if p.len() != truth.len() {
            return Err(Error::LabelCount {
                path: preds.files[id].clone(),
                labels: p.len(),
                scan: truth_path.clone(),
                points: truth.len(),
                note: Some("counted in the ground truth's label file"),
            });
        }
    }
    let mut c = Confusion::new(map.len());
    for (k, t) in truth.iter().enumerate() {
        if map.is_scored(*t) {
            c.count(*t, pred.as_ref().map_or(map.background, |p| p[k]));
        }
    }
    Ok(FrameScore {
        id: id.clone(),
        confusion: c,
        missing: pred.is_none(),
    })
}

/// Scores every labelled frame of the SemanticKITTI root (or those of `only`), in parallel
/// chunks; results in frame order.
pub fn score_dataset(
    gt: &GroundTruth,
    drives: &[Drive],
    only: Option<&std::collections::BTreeSet<FrameId>>,
    preds: &Predictions,
    opts: &ScoreOptions,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<Vec<FrameScore>> {
    let map = &gt.params.class_map;
    if let Some(missing) = only.and_then(|o| o.iter().find(|id| !gt.frames.contains(id))) {
        return Err(Error::FrameNotFound {
            path: gt.path.clone(),
            frame: missing.to_string(),
        });
    }
    let ids: Vec<&FrameId> = gt
        .frames
        .iter()
        .filter(|id| only.is_none_or(|o| o.contains(id)))
        .collect();
    let mut out = Vec::with_capacity(ids.len());
    for chunk in ids.chunks(64) {
        let part: Vec<Result<FrameScore>> = chunk
            .par_iter()
            .map(|id| {
                let drive = drives
                    .iter()
                    .find(|d| d.number == id.drive)
                    .expect("the frame comes from one of the drives");
                let r = score_one(drive, id, preds, opts, map);
                progress(1);
                r
            })
            .collect();
        for r in part {
            out.push(r?);
        }
    }
    Ok(out)
}
