//! REPORT: IoU scoring of a model's predictions against converted ground truth.
//!
//! Cell protocol (SqueezeSeg's, the default): only cells whose ground-truth range is > 0 count;
//! true positives, false positives and false negatives are summed over the whole set (one
//! confusion matrix), then `IoU_c = TP / (TP + FP + FN)` per class; mIoU is the mean over the
//! class map's `miou` classes (car, pedestrian and cyclist for the paper's map). Ground truth of
//! an ignored class is not scored. Point protocol: the same per point of the scans that falls in
//! the map's field of view; a cell prediction applies to every point of its cell. See
//! `docs/evaluation.md`.
//!
//! - [`confusion`]: the matrix and its figures;
//! - [`predictions`]: finding and reading predictions;
//! - [`frame`]: one frame.

pub mod benchmark;
pub mod confusion;
pub mod frame;
pub mod predictions;

use std::collections::{BTreeMap, BTreeSet};
use std::path::PathBuf;

use serde::Serialize;

use crate::error::Result;
use crate::label::ClassMap;
use crate::report::truth::GroundTruth;
use crate::source::kitti::FrameId;
pub use confusion::Confusion;
pub use frame::score_frame;
pub use predictions::{
    read_cell_prediction, CellPrediction, PredFormat, PredictionKind, Predictions,
};

/// Which elements are scored.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Protocol {
    /// Map cells with ground-truth range > 0 (SqueezeSeg).
    Cells,
    /// Scan points in the map's field of view.
    Points,
}

crate::named_enum!(Protocol, "scoring protocol", [
    Cells => "cells" [] "map cells with ground-truth range > 0 (SqueezeSeg's)",
    Points => "points" [] "scan points in the map's field of view",
]);

/// How to score.
#[derive(Debug, Clone)]
pub struct ScoreOptions {
    /// Cells or points.
    pub protocol: Protocol,
    /// Score a frame without a prediction as all background instead of failing.
    pub missing_as_background: bool,
    /// KITTI raw root: needed for the point protocol and for `.label` predictions under the
    /// cell protocol (the cell each point falls in is recomputed from the scan).
    pub raw: Option<PathBuf>,
    /// Point protocol with map predictions: how each point gets its class from the map
    /// ([`crate::project::unproject`]; default: its cell's).
    pub unproject: crate::project::unproject::Method,
}

/// The score of one frame.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FrameScore {
    /// Frame id.
    pub id: FrameId,
    /// Its confusion matrix.
    pub confusion: Confusion,
    /// Whether its prediction was missing (scored as background).
    pub missing: bool,
}

/// The ground truth and prediction label maps of one frame (for pictures).
#[derive(Debug, Clone)]
pub struct FrameMaps {
    /// Ground-truth class per cell (255 where range is 0).
    pub truth: Vec<u8>,
    /// Predicted class per cell (cell predictions; for point predictions, the winning point's).
    pub pred: Vec<u8>,
}

/// Per-class figures.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ClassScore {
    /// IoU (`null` when the class is absent from truth and prediction).
    pub iou: Option<f64>,
    /// Precision.
    pub precision: Option<f64>,
    /// Recall.
    pub recall: Option<f64>,
    /// Ground-truth elements of the class.
    pub support: u64,
}

/// The report (`--json` layout, documented in docs/evaluation.md).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ScoreReport {
    /// Layout version.
    pub version: u32,
    /// Cells or points.
    pub protocol: Protocol,
    /// The class names, in id order (the rows and columns of `confusion`).
    pub class_names: Vec<String>,
    /// The classes averaged into `miou`.
    pub miou_classes: Vec<String>,
    /// Frames scored.
    pub frames: u64,
    /// Frames without a prediction, scored as background.
    pub missing_frames: u64,
    /// Elements scored.
    pub elements: u64,
    /// Per class, keyed by name.
    pub classes: BTreeMap<String, ClassScore>,
    /// Mean IoU over `miou_classes`; a class absent from truth and prediction is left out or
    /// counts 0 as `miou_absent` says (the class map's rule: SemanticKITTI's counts 0).
    pub miou: f64,
    /// How absent classes enter `miou`.
    pub miou_absent: crate::label::classes::AbsentInMiou,
    /// Overall accuracy: correctly classified elements over all scored elements (`null` when
    /// none was scored), as the SemanticKITTI benchmark reports it beside mIoU.
    pub accuracy: Option<f64>,
    /// Confusion matrix, rows = truth, columns = prediction, class id order.
    pub confusion: Confusion,
    /// Predictions whose frame is not in the ground truth at all (not scored: named, so that a
    /// misnamed file is not lost silently).
    pub predictions_without_truth: Vec<String>,
    /// Per frame, when asked for.
    pub per_frame: Option<Vec<FramePerf>>,
}

/// Per-frame figures in the report.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FramePerf {
    /// Frame id.
    pub id: FrameId,
    /// IoU per class (`null` when absent).
    pub iou: BTreeMap<String, Option<f64>>,
    /// Mean over the mIoU classes present (`null` when none is).
    pub miou_present: Option<f64>,
    /// Elements scored.
    pub elements: u64,
}

impl FramePerf {
    /// From a frame's score.
    pub fn new(f: &FrameScore, map: &ClassMap) -> FramePerf {
        let iou: Vec<Option<f64>> = map.ids().map(|c| f.confusion.iou(c as usize)).collect();
        FramePerf {
            id: f.id.clone(),
            iou: map.keyed(&iou),
            miou_present: f.confusion.miou_present(&map.miou),
            elements: f.confusion.total(),
        }
    }
}

/// Builds the report from the per-frame scores (without the per-frame table: see
/// [`per_frame`]).
pub fn report(protocol: Protocol, frames: &[FrameScore], map: &ClassMap) -> ScoreReport {
    let mut total = Confusion::new(map.len());
    for f in frames {
        total.add(&f.confusion);
    }
    let scores: Vec<ClassScore> = map
        .ids()
        .map(|c| {
            let k = c as usize;
            ClassScore {
                iou: total.iou(k),
                precision: total.precision(k),
                recall: total.recall(k),
                support: total.m[k].iter().sum(),
            }
        })
        .collect();
    ScoreReport {
        version: 3,
        protocol,
        class_names: map.names().into_iter().map(String::from).collect(),
        miou_classes: map.miou.iter().map(|&c| map.name(c).to_string()).collect(),
        frames: frames.len() as u64,
        missing_frames: frames.iter().filter(|f| f.missing).count() as u64,
        elements: total.total(),
        classes: map.keyed(&scores),
        miou: total.miou_for(map),
        miou_absent: map.absent_in_miou,
        accuracy: total.accuracy(),
        confusion: total,
        predictions_without_truth: Vec::new(),
        per_frame: None,
    }
}

/// The per-frame table of a report ([`ScoreReport::per_frame`]).
pub fn per_frame(frames: &[FrameScore], map: &ClassMap) -> Vec<FramePerf> {
    frames.iter().map(|f| FramePerf::new(f, map)).collect()
}

/// Scores the frames of the ground truth (those of `only` when given), in parallel; results
/// come in frame order. The label maps of the frames in `maps_for` come back too (pictures).
pub fn score(
    gt: &GroundTruth,
    only: Option<&BTreeSet<FrameId>>,
    preds: &Predictions,
    opts: &ScoreOptions,
    maps_for: &BTreeSet<FrameId>,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<(Vec<FrameScore>, BTreeMap<FrameId, FrameMaps>)> {
    if let crate::report::truth::Source::Dataset(drives) = &gt.source {
        let scores = benchmark::score_dataset(gt, drives, only, preds, opts, progress)?;
        return Ok((scores, BTreeMap::new()));
    }
    let per_frame = gt.map_frames(
        only,
        &|f| {
            let (score, maps) = score_frame(gt, &f.id, f.truth(), preds, opts)?;
            Ok((score, maps_for.contains(&f.id).then_some(maps)))
        },
        progress,
    )?;
    let mut scores = Vec::with_capacity(per_frame.len());
    let mut maps = BTreeMap::new();
    for (id, (s, m)) in per_frame {
        if let Some(m) = m {
            maps.insert(id, m);
        }
        scores.push(s);
    }
    Ok((scores, maps))
}

/// The predictions whose frame is not among the ground truth's frames.
pub fn predictions_without_truth(gt: &GroundTruth, preds: &Predictions) -> Vec<String> {
    let truth: BTreeSet<&FrameId> = gt.frames.iter().collect();
    preds
        .frame_ids()
        .into_iter()
        .filter(|id| !truth.contains(id))
        .map(|id| id.to_string())
        .collect()
}

/// The indices of the `n` frames of lowest mIoU (over the mIoU classes present), worst first;
/// frames where none is present are left out, ties go to the earlier frame.
pub fn worst(scores: &[FrameScore], n: usize, map: &ClassMap) -> Vec<(usize, f64)> {
    let mut ranked: Vec<(usize, f64)> = scores
        .iter()
        .enumerate()
        .filter_map(|(i, s)| s.confusion.miou_present(&map.miou).map(|m| (i, m)))
        .collect();
    ranked.sort_by(|x, y| x.1.total_cmp(&y.1).then(x.0.cmp(&y.0)));
    ranked.truncate(n);
    ranked
}
