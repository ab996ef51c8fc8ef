//! REPORT: map predictions carried back to every point of their scans (`kitti2pgm unproject`),
//! written in the source's own per-point layout.
//!
//! Each frame's cells are recomputed from its scan with the map the ground truth records (the
//! convert summary or the shard metadata), by the code `convert` projects with; the prediction's
//! classes then reach the points by [`Method`] ([`crate::project::unproject`]). Written:
//!
//! - SemanticKITTI: `OUT/sequences/<NN>/predictions/<frame6>.label`, the dataset's raw ids
//!   (`learning_map_inv`), as the benchmark takes them; a point outside the map is `0`
//!   (`unlabeled`);
//! - KITTI raw and object: `OUT/labels/<drive>/<frame>.label` as `convert` writes them (class in
//!   the low 16 bits, instance 0); a point outside the map is [`NOT_PREDICTED`].
//!
//! Points dropped when the scan was read (non-finite, beyond range) are outside the map too. A
//! frame whose scan has another point count than the conversion's `.label` file recorded (the
//! data changed since) fails, naming both; files are written atomically.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

mod viz;

use rayon::prelude::*;
use serde::Serialize;

use super::score::frame::raw_drive;
use super::score::predictions::Predictions;
use super::truth::GroundTruth;
use crate::error::{Error, Result};
use crate::format::layout::OutputDir;
use crate::format::{label_file, Durability};
use crate::label::{ClassId, ClassMap};
use crate::project::norm;
use crate::project::unproject::{unproject, Method, MethodKind, PointsInMap};
use crate::source::kitti::{DatasetKind, FrameId};
use crate::source::Scan;

pub use crate::format::label_file::NOT_PREDICTED;

pub use viz::{refuse_viz_over_inputs, write_viz};

/// What to carry back, from where, to where.
#[derive(Debug, Clone)]
pub struct UnprojectOptions {
    /// How a point gets its class.
    pub method: Method,
    /// The dataset root holding the scans (KITTI raw, SemanticKITTI or object).
    pub raw: PathBuf,
    /// The output folder.
    pub out: PathBuf,
    /// Only these frames (an ImageSet list); default: every ground-truth frame with a prediction.
    pub only: Option<BTreeSet<FrameId>>,
    /// Whether each file is flushed to the device before it is renamed into place.
    pub durability: Durability,
}

/// One frame that could not be carried back.
#[derive(Debug, Clone, Serialize)]
pub struct UnprojectFailure {
    /// The frame.
    pub frame: FrameId,
    /// What went wrong, naming the file.
    pub error: String,
}

/// What `unproject` did.
#[derive(Debug, Clone, Serialize)]
pub struct UnprojectSummary {
    /// The method (`cell` or `knn` in JSON).
    pub method: MethodKind,
    /// Frames written.
    pub frames: u64,
    /// Points written (every point of their scans).
    pub points: u64,
    /// Points outside the map's field of view (or dropped when read): `not predicted`.
    pub not_predicted: u64,
    /// Frames that failed (a frame without a prediction in a drive that has predictions, or
    /// one listed in `only`, among them).
    pub failures: Vec<UnprojectFailure>,
    /// Ground-truth frames not carried back: not listed in `only`, or of drives (sequences)
    /// without any prediction.
    pub not_carried: u64,
    /// Where the files are (`OUT/sequences` or `OUT/labels`).
    pub written_to: PathBuf,
    /// The frames written, in order.
    #[serde(skip)]
    pub written: Vec<FrameId>,
}

/// Refuses an output folder (`--out`) that is, lies inside or holds the ground truth, the
/// predictions or the dataset, or that is a conversion's folder (its journal would list files
/// this command replaces).
fn refuse_output_over_inputs(
    out: &Path,
    gt: &GroundTruth,
    preds: &Predictions,
    opts: &UnprojectOptions,
) -> Result<()> {
    use crate::fs::Role;
    crate::fs::refuse_overlap(
        out,
        &[
            (Role::GroundTruth, &gt.path),
            (Role::Predictions, &preds.root),
            (Role::Dataset, &opts.raw),
        ],
    )?;
    let journal = out.join(crate::format::journal::JOURNAL_FILE);
    if crate::fs::present(&journal) {
        return Err(Error::OutputOverInput {
            output: out.into(),
            how: crate::fs::Overlap::Holds,
            role: crate::fs::Role::Converted,
            input: journal,
        });
    }
    Ok(())
}

/// One frame: its scan read, projected, its points given their classes, written.
fn one(
    gt: &GroundTruth,
    preds: &Predictions,
    id: &FrameId,
    opts: &UnprojectOptions,
) -> Result<(u64, u64)> {
    let map: &ClassMap = &gt.params.class_map;
    let spec = &gt.params.spec;
    let pred = preds
        .cell_labels(id, (spec.rows, spec.cols), map)?
        .ok_or_else(|| Error::MissingPrediction {
            root: preds.root.clone(),
            frame: id.to_string(),
            expected: None,
        })?;
    let drive = raw_drive(&opts.raw, id)?;
    let scan_path = drive.scan_path(id.frame);
    let (scan, proj) =
        crate::project::project_scan(&gt.params.spec, gt.params.sensor.as_ref(), &scan_path)?;
    if let Some(dir) = &gt.dir {
        let recorded = dir.label_path(id);
        if let Ok(meta) = std::fs::metadata(&recorded) {
            let n = meta.len() / 4;
            if n != scan.file_len as u64 {
                return Err(Error::LabelCount {
                    path: recorded,
                    labels: n as usize,
                    scan: scan_path,
                    points: scan.file_len,
                    note: Some("the conversion's labels; the data changed since"),
                });
            }
        }
    }
    let point_range: Vec<f32> = scan.points.iter().map(norm).collect();
    let m = PointsInMap::of(&proj, &point_range);
    let classes = unproject(&m, &pred, &opts.method, map)?;
    let per_point = scan.to_file_order(&classes, None);
    let (_, missing) =
        label_file::write_predictions(&opts.out, id, &per_point, map, opts.durability)?;
    Ok((per_point.len() as u64, missing))
}

/// Carries every frame's prediction back to its points (frames in parallel; a failing frame is
/// recorded and the others go on). `progress` is called after each frame.
pub fn unproject_all(
    gt: &GroundTruth,
    preds: &Predictions,
    opts: &UnprojectOptions,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<UnprojectSummary> {
    refuse_output_over_inputs(&opts.out, gt, preds, opts)?;
    opts.method.validate()?;
    let map = &gt.params.class_map;
    let sequence = gt.frames.iter().any(|f| f.dataset == DatasetKind::Sequence);
    if sequence && map.learning_map_inv.is_empty() {
        return Err(Error::Config(format!(
            "class map {:?} has no learning_map_inv: SemanticKITTI predictions are written as the dataset's raw ids",
            map.name
        )));
    }
    let frames = frames_to_carry(gt, preds, opts.only.as_ref())?;
    let not_carried = (gt.frames.len() - frames.len()) as u64;
    let (points, missing) = (AtomicU64::new(0), AtomicU64::new(0));
    let mut failures: Vec<UnprojectFailure> = frames
        .par_iter()
        .filter_map(|id| {
            let r = one(gt, preds, id, opts);
            progress(1);
            match r {
                Ok((n, m)) => {
                    points.fetch_add(n, Ordering::Relaxed);
                    missing.fetch_add(m, Ordering::Relaxed);
                    None
                }
                Err(e) => Some(UnprojectFailure {
                    frame: (*id).clone(),
                    error: e.to_string(),
                }),
            }
        })
        .collect();
    if opts.only.is_none() {
        failures.extend(orphan_predictions(gt, preds));
    }
    failures.sort_by(|a, b| a.frame.cmp(&b.frame));
    let written: Vec<FrameId> = frames
        .iter()
        .filter(|f| failures.binary_search_by(|x| x.frame.cmp(f)).is_err())
        .map(|f| (*f).clone())
        .collect();
    Ok(UnprojectSummary {
        method: opts.method.kind(),
        frames: written.len() as u64,
        points: points.into_inner(),
        not_predicted: missing.into_inner(),
        failures,
        not_carried,
        written_to: opts.out.join(if sequence { "sequences" } else { "labels" }),
        written,
    })
}

/// The ground-truth frames to carry back: those of `only` (each must be in the ground truth),
/// or every frame of the drives (sequences) that have predictions; an error when there is none.
fn frames_to_carry<'a>(
    gt: &'a GroundTruth,
    preds: &Predictions,
    only: Option<&BTreeSet<FrameId>>,
) -> Result<Vec<&'a FrameId>> {
    let frames: Vec<&FrameId> = match only {
        Some(only) => {
            if let Some(missing) = only.iter().find(|id| !gt.frames.contains(id)) {
                return Err(Error::FrameNotFound {
                    path: gt.path.clone(),
                    frame: missing.to_string(),
                });
            }
            gt.frames.iter().filter(|f| only.contains(f)).collect()
        }
        // Every frame of a drive (sequence) that has predictions: one missing in such a drive
        // fails, named, instead of passing unnoticed.
        None => {
            let predicted: BTreeSet<String> = gt
                .frames
                .iter()
                .filter(|f| preds.has(f))
                .map(FrameId::drive_name)
                .collect();
            gt.frames
                .iter()
                .filter(|f| predicted.contains(&f.drive_name()))
                .collect()
        }
    };
    if frames.is_empty() {
        return Err(Error::Input {
            path: preds.root.clone(),
            message: "no prediction for any ground-truth frame".into(),
        });
    }
    Ok(frames)
}

/// A prediction for a frame the ground truth does not hold (a scan that is not there, a
/// misnamed file): named as a failure, not skipped silently.
fn orphan_predictions(gt: &GroundTruth, preds: &Predictions) -> Vec<UnprojectFailure> {
    let truth: BTreeSet<&FrameId> = gt.frames.iter().collect();
    preds
        .frame_ids()
        .into_iter()
        .filter(|id| !truth.contains(id))
        .map(|id| UnprojectFailure {
            error: format!(
                "{}: a prediction for a frame that is not in the ground truth {}",
                preds.path_of(id).display(),
                gt.path.display()
            ),
            frame: id.clone(),
        })
        .collect()
}

/// Per-point predictions as classes, from a `.label` file of frame `id`: SemanticKITTI's raw ids
/// (`.../predictions/`) through the learning map, class ids otherwise ([`NOT_PREDICTED`] and ids
/// unknown to the map: `None`).
pub fn read_point_predictions(
    path: &Path,
    id: &FrameId,
    map: &ClassMap,
) -> Result<Vec<Option<ClassId>>> {
    let raw = label_file::read_raw(path)?;
    let raw_ids = id.dataset == DatasetKind::Sequence
        && path
            .parent()
            .and_then(|p| p.file_name())
            .is_some_and(|n| n == "predictions");
    Ok(raw
        .iter()
        .map(|&v| {
            let low = v & 0xFFFF;
            if raw_ids {
                map.class_of_raw(low)
            } else {
                (low != NOT_PREDICTED && (low as usize) < map.len()).then_some(low as ClassId)
            }
        })
        .collect())
}

/// The per-point truth of frame `id`, in file order, when there is one: SemanticKITTI's own
/// labels under the dataset `raw`, else the `.label` file of the convert folder `gt`.
pub fn point_truth(
    raw: &Path,
    id: &FrameId,
    map: &ClassMap,
    gt: Option<&OutputDir>,
) -> Result<Option<Vec<Option<ClassId>>>> {
    if id.dataset == DatasetKind::Sequence {
        let path = raw_drive(raw, id)?.point_labels_path(id.frame);
        if path.is_file() {
            let raw_ids = label_file::read_raw(&path)?;
            return Ok(Some(
                raw_ids
                    .iter()
                    .map(|&v| map.class_of_raw(v & 0xFFFF))
                    .collect(),
            ));
        }
    }
    match gt.map(|d| d.label_path(id)).filter(|p| p.is_file()) {
        Some(p) => Ok(Some(
            label_file::read_raw(&p)?
                .iter()
                .map(|&v| {
                    let c = v & 0xFFFF;
                    ((c as usize) < map.len()).then_some(c as ClassId)
                })
                .collect(),
        )),
        None => Ok(None),
    }
}

/// A scan with its per-point predictions and truth, each per kept point (the scan's order).
pub struct PointFrame {
    /// The scan as its conversion read it ([`crate::sensor::read_scan`]).
    pub scan: Scan,
    /// The beam row of every kept point, where a sensor model gave them (`None`: KITTI's
    /// HDL-64E, rows from the scan order).
    pub beam_rows: Option<Vec<u8>>,
    /// Each point's predicted class (`None`: not predicted).
    pub pred: Vec<Option<ClassId>>,
    /// Each point's true class, when there is a truth ([`point_truth`]).
    pub truth: Option<Vec<Option<ClassId>>>,
}

/// Reads frame `id`'s scan under `raw` as the conversion with `sensor` read it (its declared
/// `.bin` layout, pose and beam rows), its per-point predictions from `pred_path` (which must
/// hold one entry per point of the scan) and its truth.
pub fn load_point_frame(
    raw: &Path,
    id: &FrameId,
    pred_path: &Path,
    map: &ClassMap,
    gt: Option<&OutputDir>,
    sensor: Option<&crate::sensor::SensorParams>,
) -> Result<PointFrame> {
    let scan_path = raw_drive(raw, id)?.scan_path(id.frame);
    let (scan, beams) = crate::sensor::read_scan(sensor, &scan_path)?;
    let pred = read_point_predictions(pred_path, id, map)?;
    if pred.len() != scan.file_len {
        return Err(Error::LabelCount {
            path: pred_path.into(),
            labels: pred.len(),
            scan: scan_path,
            points: scan.file_len,
            note: None,
        });
    }
    let truth = point_truth(raw, id, map, gt)?;
    let kept = scan.file_indices();
    let pick = |v: &[Option<ClassId>]| -> Vec<Option<ClassId>> {
        kept.iter()
            .map(|&i| v.get(i as usize).copied().flatten())
            .collect()
    };
    Ok(PointFrame {
        pred: pick(&pred),
        truth: truth.as_deref().map(pick),
        beam_rows: beams.map(|b| b.rows),
        scan,
    })
}
