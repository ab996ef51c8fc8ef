//! IoU scoring of a model's predictions against converted ground truth.
//!
//! Cell protocol (SqueezeSeg's, the default): only cells whose ground-truth range is > 0 count;
//! true positives, false positives and false negatives are summed over the whole set (one
//! confusion matrix), then `IoU_c = TP / (TP + FP + FN)` per class; mIoU is the mean over car,
//! pedestrian and cyclist. Point protocol: the same per point of the scans that falls in the
//! map's field of view; a cell prediction applies to every point of its cell. See
//! `docs/evaluation.md`.
//!
//! Predictions are matched to ground-truth frames by frame id (the file stem; for `.label` files
//! the drive folder and the frame number). Formats, detected per file: H x W label maps (`.npy`,
//! integer or integral float), H x W x 4 class scores (`.npy`, argmax), SqueezeSeg-layout
//! H x W x 6 or 9 `.npy` (its label channel), and per-point `.label` files (low 16 bits).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use rayon::prelude::*;
use serde::Serialize;

use crate::error::{Error, Result};
use crate::kitti::velodyne::Scan;
use crate::kitti::{parse_drive_name, FrameId};
use crate::label::Class;
use crate::project::{project_with_point_cells, PgmSpec, EMPTY};
use crate::report::stats::{label_path, npy_path};
use crate::write::npy::{read_any, read_f32, NpyArray};
use crate::write::shard::{FrameMsg, Shard, FRAME_TOPIC};

/// Number of classes.
const K: usize = Class::COUNT;

/// A confusion matrix, `m[ground truth][prediction]`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct Confusion {
    /// Counts, ground truth by row, prediction by column.
    pub m: [[u64; K]; K],
}

impl Confusion {
    /// Adds another matrix.
    pub fn add(&mut self, o: &Confusion) {
        for g in 0..K {
            for p in 0..K {
                self.m[g][p] += o.m[g][p];
            }
        }
    }

    /// True positives of class `c`.
    pub fn tp(&self, c: usize) -> u64 {
        self.m[c][c]
    }

    /// False positives of class `c` (predicted c, truth other).
    pub fn fp(&self, c: usize) -> u64 {
        (0..K).filter(|&g| g != c).map(|g| self.m[g][c]).sum()
    }

    /// False negatives of class `c` (truth c, predicted other).
    pub fn fn_(&self, c: usize) -> u64 {
        (0..K).filter(|&p| p != c).map(|p| self.m[c][p]).sum()
    }

    /// `TP / (TP + FP + FN)`, or `None` when the class is absent from truth and prediction.
    pub fn iou(&self, c: usize) -> Option<f64> {
        let d = self.tp(c) + self.fp(c) + self.fn_(c);
        (d > 0).then(|| self.tp(c) as f64 / d as f64)
    }

    /// `TP / (TP + FP)`, or `None` when nothing was predicted as the class.
    pub fn precision(&self, c: usize) -> Option<f64> {
        let d = self.tp(c) + self.fp(c);
        (d > 0).then(|| self.tp(c) as f64 / d as f64)
    }

    /// `TP / (TP + FN)`, or `None` when the class is absent from the truth.
    pub fn recall(&self, c: usize) -> Option<f64> {
        let d = self.tp(c) + self.fn_(c);
        (d > 0).then(|| self.tp(c) as f64 / d as f64)
    }

    /// Mean IoU over car, pedestrian and cyclist. A class absent from both truth and prediction
    /// has no IoU and is left out of the mean (so a perfect prediction scores 1 on a set without
    /// cyclists); 0 when no object class is present at all. On SqueezeSeg's val set every class
    /// is present and this is its plain three-class mean.
    pub fn miou(&self) -> f64 {
        self.miou_present().unwrap_or(0.0)
    }

    /// Mean IoU over the object classes present in truth or prediction, `None` if none is.
    pub fn miou_present(&self) -> Option<f64> {
        let v: Vec<f64> = (1..K).filter_map(|c| self.iou(c)).collect();
        (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64)
    }

    /// Counted elements.
    pub fn total(&self) -> u64 {
        self.m.iter().flatten().sum()
    }
}

/// Which elements are scored.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum Protocol {
    /// Map cells with ground-truth range > 0 (SqueezeSeg).
    Cells,
    /// Scan points in the map's field of view.
    Points,
}

/// The kind of a prediction file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum PredFormat {
    /// H x W class ids (`.npy`).
    LabelMap,
    /// H x W x 4 class scores (`.npy`, argmax).
    ScoreMap,
    /// SqueezeSeg layout H x W x 6 or 9 (`.npy`, channel 5).
    SqueezeSeg,
    /// One u32 per point of the scan (`.label`, low 16 bits).
    PointLabels,
}

/// Topic of prediction messages in prediction shards (the trainer's `evaluate --format mcap`).
pub const PREDICTION_TOPIC: &str = "/kitti2pgm/prediction";

/// Predictions by frame id, all of one format family: `.npy` maps, `.label` files, or shards.
pub struct Predictions {
    /// The folder or file given.
    pub root: PathBuf,
    /// Files by frame (`.npy` or `.label`).
    pub files: BTreeMap<FrameId, PathBuf>,
    /// Whether they are per-point `.label` files (else `.npy` maps or shards).
    pub points: bool,
    /// Prediction shards, and where each frame's message is: (shard, chunk).
    shards: Vec<(Shard, mcap::read::Summary)>,
    in_shard: BTreeMap<FrameId, (usize, usize)>,
}

/// The frame messages of one chunk of a shard.
fn chunk_frames<'a>(
    shard: &'a Shard,
    summary: &'a mcap::read::Summary,
    chunk: usize,
) -> Result<impl Iterator<Item = Result<FrameMsg>> + 'a> {
    let index = &summary.chunk_indexes[chunk];
    let stream = summary.stream_chunk(shard.bytes(), index).map_err(|e| {
        Error::format(
            &shard.path,
            format!("chunk at byte {}: {e}", index.chunk_start_offset),
        )
    })?;
    Ok(stream.filter_map(move |m| match m {
        Ok(m) if m.channel.topic == PREDICTION_TOPIC || m.channel.topic == FRAME_TOPIC => Some(
            <FrameMsg as prost::Message>::decode(&m.data[..]).map_err(|e| {
                Error::format(&shard.path, format!("undecodable prediction message: {e}"))
            }),
        ),
        Ok(_) => None,
        Err(e) => Some(Err(Error::format(
            &shard.path,
            format!("corrupted or truncated: {e}"),
        ))),
    }))
}

fn frame_id_of(path: &Path) -> Option<FrameId> {
    let stem = path.file_stem()?.to_str()?;
    match path.extension()?.to_str()? {
        "npy" => stem.parse().ok(),
        "label" => {
            let drive = path.parent()?.file_name()?.to_str()?;
            let (date, number) = parse_drive_name(drive)?;
            (stem.len() == 10).then_some(())?;
            Some(FrameId {
                date,
                drive: number,
                frame: stem.parse().ok()?,
            })
        }
        _ => None,
    }
}

fn walk(dir: &Path, out: &mut Vec<PathBuf>) -> Result<()> {
    for e in std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))? {
        let p = e.map_err(|e| Error::io(dir, e))?.path();
        if p.is_dir() {
            walk(&p, out)?;
        } else {
            out.push(p);
        }
    }
    Ok(())
}

impl Predictions {
    /// Indexes the prediction files under `root` (a folder searched recursively, or one file).
    pub fn index(root: &Path) -> Result<Predictions> {
        let mut paths = Vec::new();
        if root.is_dir() {
            walk(root, &mut paths)?;
        } else if root.is_file() {
            paths.push(root.to_path_buf());
        } else {
            return Err(Error::Input {
                path: root.into(),
                message: "no such file or folder".into(),
            });
        }
        paths.sort();
        let mut files = BTreeMap::new();
        let (mut npy, mut label) = (None::<PathBuf>, None::<PathBuf>);
        let mcaps: Vec<PathBuf> = paths
            .iter()
            .filter(|p| p.extension().is_some_and(|e| e == "mcap"))
            .cloned()
            .collect();
        for p in paths {
            let Some(id) = frame_id_of(&p) else { continue };
            if p.extension().is_some_and(|e| e == "npy") {
                npy.get_or_insert(p.clone());
            } else {
                label.get_or_insert(p.clone());
            }
            if let Some(prev) = files.insert(id.clone(), p.clone()) {
                return Err(Error::Input {
                    path: p,
                    message: format!("second prediction for {id} (first: {})", prev.display()),
                });
            }
        }
        if let (Some(a), Some(b)) = (&npy, &label) {
            return Err(Error::Input {
                path: root.into(),
                message: format!(
                    "mixed formats: .npy maps ({}) and .label files ({})",
                    a.display(),
                    b.display()
                ),
            });
        }
        if let (Some(a), Some(b)) = (npy.as_ref().or(label.as_ref()), mcaps.first()) {
            return Err(Error::Input {
                path: root.into(),
                message: format!(
                    "mixed formats: prediction files ({}) and shards ({})",
                    a.display(),
                    b.display()
                ),
            });
        }
        let mut shards = Vec::new();
        let mut in_shard = BTreeMap::new();
        for p in &mcaps {
            let shard = Shard::open(p)?;
            let summary = shard.summary()?;
            for chunk in 0..summary.chunk_indexes.len() {
                for f in chunk_frames(&shard, &summary, chunk)? {
                    let f = f?;
                    let id: FrameId = f.id.parse().map_err(|e: String| Error::format(p, e))?;
                    if in_shard.insert(id.clone(), (shards.len(), chunk)).is_some() {
                        return Err(Error::Input {
                            path: p.clone(),
                            message: format!("second prediction for {id}"),
                        });
                    }
                }
            }
            shards.push((shard, summary));
        }
        if files.is_empty() && in_shard.is_empty() {
            return Err(Error::Input {
                path: root.into(),
                message:
                    "no prediction (<frame id>.npy, <drive>/<frame>.label or prediction shards)"
                        .into(),
            });
        }
        Ok(Predictions {
            root: root.into(),
            files,
            points: label.is_some(),
            shards,
            in_shard,
        })
    }
}

impl Predictions {
    /// The label map of frame `id` from prediction shard `k`, chunk `chunk`, checked.
    fn shard_prediction(
        &self,
        k: usize,
        chunk: usize,
        id: &FrameId,
        rows: usize,
        cols: usize,
    ) -> Result<Vec<u8>> {
        let (shard, summary) = &self.shards[k];
        let want = id.to_string();
        for f in chunk_frames(shard, summary, chunk)? {
            let f = f?;
            if f.id != want {
                continue;
            }
            if (f.height as usize, f.width as usize) != (rows, cols) || f.label.len() != rows * cols
            {
                return Err(Error::format(
                    &shard.path,
                    format!(
                        "prediction for {id} is {}x{} ({} labels), the ground truth {rows}x{cols}",
                        f.height,
                        f.width,
                        f.label.len()
                    ),
                ));
            }
            if let Some((i, v)) = f.label.iter().enumerate().find(|(_, v)| **v as usize >= K) {
                return Err(Error::format(
                    &shard.path,
                    format!(
                        "prediction for {id}: cell ({}, {}) is {v}, not a class id 0-{}",
                        i / cols,
                        i % cols,
                        K - 1
                    ),
                ));
            }
            return Ok(f.label);
        }
        Err(Error::format(
            &shard.path,
            format!("prediction for {id} vanished from its chunk"),
        ))
    }
}

/// A cell prediction map read from a `.npy`, as class ids.
#[derive(Debug, Clone)]
pub struct CellPrediction {
    /// Detected format.
    pub format: PredFormat,
    /// Class id per cell, row-major.
    pub labels: Vec<u8>,
}

/// The class id `v` stands for; `what` names the cell in the error (built only on failure).
#[inline]
fn class_of(v: f64, path: &Path, what: impl Fn() -> String) -> Result<u8> {
    if v.is_nan() {
        return Err(Error::format(path, format!("{} is NaN", what())));
    }
    // Range first, then integrality by a round trip (`fract` is a libm call).
    if !(0.0..K as f64).contains(&v) || (v as u8) as f64 != v {
        return Err(Error::format(
            path,
            format!("{} is {v}, not a class id 0-{}", what(), K - 1),
        ));
    }
    Ok(v as u8)
}

/// Reads a `.npy` prediction for an `rows x cols` map.
pub fn read_cell_prediction(path: &Path, rows: usize, cols: usize) -> Result<CellPrediction> {
    let NpyArray { shape, data, dtype } = read_any(path)?;
    let cells = rows * cols;
    let dims: Vec<usize> = shape.iter().map(|&d| d as usize).collect();
    let (format, depth) = match dims.as_slice() {
        [h, w] if *h == rows && *w == cols => (PredFormat::LabelMap, 1),
        [h, w, 1] if *h == rows && *w == cols => (PredFormat::LabelMap, 1),
        [h, w, c] if *h == rows && *w == cols && *c == K => (PredFormat::ScoreMap, K),
        [h, w, c] if *h == rows && *w == cols && (*c == 6 || *c == 9) => (PredFormat::SqueezeSeg, *c),
        other => {
            return Err(Error::format(
                path,
                format!("shape {other:?} ({dtype}) does not fit the {rows}x{cols} ground truth: expected {rows}x{cols} labels, {rows}x{cols}x{K} scores or {rows}x{cols}x6/9 SqueezeSeg maps"),
            ))
        }
    };
    let mut labels = Vec::with_capacity(cells);
    for i in 0..cells {
        let cell = &data[i * depth..(i + 1) * depth];
        let what = || format!("cell ({}, {})", i / cols, i % cols);
        let l = match format {
            PredFormat::LabelMap => class_of(cell[0], path, what)?,
            PredFormat::SqueezeSeg => class_of(cell[5], path, what)?,
            PredFormat::ScoreMap => {
                if let Some(k) = cell.iter().position(|v| v.is_nan()) {
                    return Err(Error::format(
                        path,
                        format!("{} score of class {k} is NaN", what()),
                    ));
                }
                // First maximum: ties go to the lower class id.
                let mut best = 0;
                for k in 1..K {
                    if cell[k] > cell[best] {
                        best = k;
                    }
                }
                best as u8
            }
            PredFormat::PointLabels => unreachable!("not a map"),
        };
        labels.push(l);
    }
    Ok(CellPrediction { format, labels })
}

/// Reads a per-point `.label` file as class ids (low 16 bits).
pub fn read_point_labels(path: &Path) -> Result<Vec<u8>> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    if bytes.len() % 4 != 0 {
        return Err(Error::format(
            path,
            format!("{} bytes, not a multiple of 4", bytes.len()),
        ));
    }
    bytes
        .chunks_exact(4)
        .enumerate()
        .map(|(i, w)| {
            let c = u32::from_le_bytes([w[0], w[1], w[2], w[3]]) & 0xffff;
            if c as usize >= K {
                Err(Error::format(
                    path,
                    format!("point {i} has label {c}, not a class id 0-{}", K - 1),
                ))
            } else {
                Ok(c as u8)
            }
        })
        .collect()
}

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
    /// The map the ground truth was made with (from its `convert_summary.json` when present).
    pub spec: PgmSpec,
}

/// The score of one frame.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FrameScore {
    /// Frame id.
    pub id: String,
    /// Its confusion matrix.
    pub confusion: Confusion,
    /// Whether its prediction was missing (scored as background).
    pub missing: bool,
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
    /// Frames scored.
    pub frames: u64,
    /// Frames without a prediction, scored as background.
    pub missing_frames: u64,
    /// Elements scored.
    pub elements: u64,
    /// Per class, keyed by name.
    pub classes: BTreeMap<&'static str, ClassScore>,
    /// Mean IoU over car, pedestrian, cyclist (classes absent from truth and prediction left out).
    pub miou: f64,
    /// Confusion matrix, rows = truth, columns = prediction, class id order.
    pub confusion: Confusion,
    /// Per frame, when asked for.
    pub per_frame: Option<Vec<FramePerf>>,
}

/// Per-frame figures in the report.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FramePerf {
    /// Frame id.
    pub id: String,
    /// IoU per class (`null` when absent).
    pub iou: BTreeMap<&'static str, Option<f64>>,
    /// Mean over the object classes present (`null` when none is).
    pub miou_present: Option<f64>,
    /// Elements scored.
    pub elements: u64,
}

impl FramePerf {
    /// From a frame's score.
    pub fn new(f: &FrameScore) -> FramePerf {
        FramePerf {
            id: f.id.clone(),
            iou: Class::ALL
                .iter()
                .map(|c| (c.name(), f.confusion.iou(*c as usize)))
                .collect(),
            miou_present: f.confusion.miou_present(),
            elements: f.confusion.total(),
        }
    }
}

/// Builds the report from the per-frame scores.
pub fn report(protocol: Protocol, frames: &[FrameScore], per_frame: bool) -> ScoreReport {
    let mut total = Confusion::default();
    for f in frames {
        total.add(&f.confusion);
    }
    let classes = Class::ALL
        .iter()
        .map(|c| {
            let k = *c as usize;
            (
                c.name(),
                ClassScore {
                    iou: total.iou(k),
                    precision: total.precision(k),
                    recall: total.recall(k),
                    support: total.m[k].iter().sum(),
                },
            )
        })
        .collect();
    ScoreReport {
        version: 1,
        protocol,
        frames: frames.len() as u64,
        missing_frames: frames.iter().filter(|f| f.missing).count() as u64,
        elements: total.total(),
        classes,
        miou: total.miou(),
        confusion: total,
        per_frame: per_frame.then(|| frames.iter().map(FramePerf::new).collect()),
    }
}

/// The ground truth and prediction label maps of one frame (for pictures).
#[derive(Debug, Clone)]
pub struct FrameMaps {
    /// Ground-truth class per cell (255 where range is 0).
    pub truth: Vec<u8>,
    /// Predicted class per cell (cell predictions; for point predictions, the winning point's).
    pub pred: Vec<u8>,
}

/// Scores one frame; returns its confusion and, when `want_maps`, its label maps.
pub fn score_frame(
    gt_dir: &Path,
    id: &FrameId,
    preds: &Predictions,
    opts: &ScoreOptions,
    want_maps: bool,
) -> Result<(FrameScore, Option<FrameMaps>)> {
    let truth = truth_from_npy(gt_dir, id, &opts.spec)?;
    score_with_truth(Some(gt_dir), id, truth, preds, opts, want_maps)
}

/// The ground-truth class of each cell of a converted frame (`u8::MAX` where range is 0).
fn truth_from_npy(gt_dir: &Path, id: &FrameId, spec: &PgmSpec) -> Result<Vec<u8>> {
    let (rows, cols) = (spec.rows, spec.cols);
    let gt_path = npy_path(gt_dir, id);
    let (shape, gt) = read_f32(&gt_path)?;
    let depth = match shape.as_slice() {
        [h, w, c] if *h as usize == rows && *w as usize == cols && (*c == 6 || *c == 9) => {
            *c as usize
        }
        other => {
            return Err(Error::format(
                &gt_path,
                format!("ground truth shape {other:?}, expected {rows}x{cols}x6 or 9"),
            ))
        }
    };
    Ok((0..rows * cols)
        .map(|i| {
            if gt[i * depth + 4] > 0.0 {
                gt[i * depth + 5] as u8
            } else {
                u8::MAX
            }
        })
        .collect())
}

/// The ground-truth class of each cell of a shard frame (`u8::MAX` where the mask is 0).
fn truth_from_msg(f: &FrameMsg, spec: &PgmSpec, shard: &Path) -> Result<Vec<u8>> {
    if (f.height as usize, f.width as usize) != (spec.rows, spec.cols) {
        return Err(Error::format(
            shard,
            format!(
                "frame {} is {}x{}, the other ground truth {}x{}",
                f.id, f.height, f.width, spec.rows, spec.cols
            ),
        ));
    }
    Ok(f.label
        .iter()
        .zip(&f.mask)
        .map(|(l, m)| if *m != 0 { *l } else { u8::MAX })
        .collect())
}

/// Scores one frame against its ground truth per cell; `gt_dir` (a convert folder) is needed
/// for the point protocol, whose ground truth is the `.label` files.
fn score_with_truth(
    gt_dir: Option<&Path>,
    id: &FrameId,
    truth: Vec<u8>,
    preds: &Predictions,
    opts: &ScoreOptions,
    want_maps: bool,
) -> Result<(FrameScore, Option<FrameMaps>)> {
    let (rows, cols) = (opts.spec.rows, opts.spec.cols);
    let cells = rows * cols;
    let pred_file = preds.files.get(id);
    let pred_shard = preds.in_shard.get(id);
    if pred_file.is_none() && pred_shard.is_none() && !opts.missing_as_background {
        return Err(Error::Input {
            path: preds.root.clone(),
            message: format!("no prediction for ground-truth frame {id} (use --missing-as-background to score it as background)"),
        });
    }
    let missing = pred_file.is_none() && pred_shard.is_none();
    let needs_scan = opts.protocol == Protocol::Points || (preds.points && !missing);
    // Per point: (cell, file index) of each point in the field of view, from the scan.
    let mut point_cells: Vec<(u32, u32)> = Vec::new();
    let mut cell_winner_file: Vec<u32> = Vec::new();
    if needs_scan {
        let raw = opts.raw.as_ref().ok_or_else(|| {
            Error::Config(format!(
                "{id}: {} needs the raw scans: pass --raw RAW_ROOT",
                if opts.protocol == Protocol::Points {
                    "the point protocol"
                } else {
                    "scoring .label predictions per cell"
                }
            ))
        })?;
        let drive_dir = raw_drive_dir(raw, id)?;
        let scan_path = drive_dir.join(format!("velodyne_points/data/{:010}.bin", id.frame));
        let scan = Scan::read(&scan_path)?;
        let proj = project_with_point_cells(&scan.points, &opts.spec);
        let file_idx = scan.file_indices();
        cell_winner_file = proj
            .cell_point
            .iter()
            .map(|&p| {
                if p == EMPTY {
                    u32::MAX
                } else {
                    file_idx[p as usize]
                }
            })
            .collect();
        point_cells = proj
            .point_cell
            .iter()
            .zip(&file_idx)
            .filter(|(c, _)| **c != EMPTY)
            .map(|(c, f)| (*c, *f))
            .collect();
    }
    // Predicted class per cell.
    let pred_cells: Vec<u8> = match (pred_file, preds.points) {
        (None, _) => match pred_shard {
            Some(&(k, chunk)) => preds.shard_prediction(k, chunk, id, rows, cols)?,
            None => vec![0; cells],
        },
        (Some(p), false) => read_cell_prediction(p, rows, cols)?.labels,
        (Some(p), true) => {
            let pl = read_point_labels(p)?;
            let n = cell_winner_file
                .iter()
                .filter(|&&f| f != u32::MAX)
                .map(|&f| f as usize + 1)
                .max()
                .unwrap_or(0);
            if pl.len() < n {
                return Err(Error::format(
                    p,
                    format!(
                        "{} point labels, but the scan has at least {n} points",
                        pl.len()
                    ),
                ));
            }
            cell_winner_file
                .iter()
                .map(|&f| if f == u32::MAX { 0 } else { pl[f as usize] })
                .collect()
        }
    };
    let mut c = Confusion::default();
    match opts.protocol {
        Protocol::Cells => {
            for (t, p) in truth.iter().zip(&pred_cells) {
                if *t != u8::MAX {
                    c.m[*t as usize][*p as usize] += 1;
                }
            }
        }
        Protocol::Points => {
            let gt_dir = gt_dir.ok_or_else(|| {
                Error::Config("the point protocol needs a convert output folder as ground truth (its .label files), not shards".into())
            })?;
            let lp = label_path(gt_dir, id);
            let gt_points = read_point_labels(&lp)?;
            let pred_points = match (pred_file, preds.points) {
                (Some(p), true) => Some(read_point_labels(p)?),
                _ => None,
            };
            for &(cell, fi) in &point_cells {
                let t = *gt_points.get(fi as usize).ok_or_else(|| {
                    Error::format(
                        &lp,
                        format!(
                            "{} point labels, but the scan has point {fi}",
                            gt_points.len()
                        ),
                    )
                })?;
                let p = match &pred_points {
                    Some(pp) => *pp.get(fi as usize).ok_or_else(|| {
                        Error::format(
                            pred_file.expect("present"),
                            format!("{} point labels, but the scan has point {fi}", pp.len()),
                        )
                    })?,
                    None => pred_cells[cell as usize],
                };
                c.m[t as usize][p as usize] += 1;
            }
        }
    }
    let maps = want_maps.then_some(FrameMaps {
        truth,
        pred: pred_cells,
    });
    Ok((
        FrameScore {
            id: id.to_string(),
            confusion: c,
            missing,
        },
        maps,
    ))
}

fn raw_drive_dir(raw: &Path, id: &FrameId) -> Result<PathBuf> {
    let name = format!("{}_drive_{:04}_sync", id.date, id.drive);
    for candidate in [
        raw.join(&id.date).join(&name),
        raw.join(&name),
        raw.to_path_buf(),
    ] {
        if candidate.file_name().and_then(|n| n.to_str()) == Some(name.as_str())
            && candidate.is_dir()
        {
            return Ok(candidate);
        }
    }
    Err(Error::Input {
        path: raw.into(),
        message: format!("drive {name} of frame {id} not found"),
    })
}

/// Frames per parallel chunk.
const CHUNK: usize = 64;

/// Scores every frame of `frames`, in parallel chunks; results come in frame order.
pub fn score(
    gt_dir: &Path,
    frames: &[FrameId],
    preds: &Predictions,
    opts: &ScoreOptions,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<Vec<FrameScore>> {
    let mut out = Vec::with_capacity(frames.len());
    for chunk in frames.chunks(CHUNK) {
        let part: Vec<Result<FrameScore>> = chunk
            .par_iter()
            .map(|id| {
                let r = score_frame(gt_dir, id, preds, opts, false).map(|(s, _)| s);
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

/// Scores the frames of ground-truth shards (cell protocol), streaming each shard; with
/// `only`, just those frames (every one of them must be in the shards). Results come sorted by
/// frame id. `maps_for` names frames whose label maps are returned too (for pictures).
pub fn score_shards(
    shards: &[PathBuf],
    only: Option<&std::collections::BTreeSet<FrameId>>,
    preds: &Predictions,
    opts: &ScoreOptions,
    maps_for: &std::collections::BTreeSet<String>,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<(Vec<FrameScore>, BTreeMap<String, FrameMaps>)> {
    if opts.protocol == Protocol::Points {
        return Err(Error::Config("the point protocol needs a convert output folder as ground truth (its .label files), not shards".into()));
    }
    type Part = Result<(Vec<FrameScore>, Vec<(String, FrameMaps)>)>;
    let parts: Vec<Part> = shards
        .par_iter()
        .map(|path| {
            let shard = Shard::open(path)?;
            let mut scores = Vec::new();
            let mut maps = Vec::new();
            for f in shard.frame_iter() {
                let f = f?;
                let id: FrameId = f.id.parse().map_err(|e: String| Error::format(path, e))?;
                if only.is_some_and(|o| !o.contains(&id)) {
                    continue;
                }
                let truth = truth_from_msg(&f, &opts.spec, path)?;
                let want = maps_for.contains(&f.id);
                let (s, m) = score_with_truth(None, &id, truth, preds, opts, want)?;
                if let Some(m) = m {
                    maps.push((f.id.clone(), m));
                }
                scores.push(s);
                progress(1);
            }
            Ok((scores, maps))
        })
        .collect();
    let mut scores = Vec::new();
    let mut maps = BTreeMap::new();
    for p in parts {
        let (s, m) = p?;
        scores.extend(s);
        maps.extend(m);
    }
    scores.sort_by(|a, b| a.id.cmp(&b.id));
    if let Some(o) = only {
        let have: std::collections::BTreeSet<&str> = scores.iter().map(|s| s.id.as_str()).collect();
        if let Some(missing) = o.iter().find(|id| !have.contains(id.to_string().as_str())) {
            return Err(Error::Input {
                path: shards.first().cloned().unwrap_or_default(),
                message: format!("ImageSet frame {missing} is not in the ground-truth shards"),
            });
        }
    }
    Ok((scores, maps))
}

/// A picture of the confusion matrix: rows = truth, columns = prediction, each cell shaded by
/// its share of the row (recall view), with the count and the share written in it.
pub fn confusion_chart(c: &Confusion) -> image::RgbImage {
    use crate::preview::{draw_text, text_width};
    let (cell, left, top) = (120u32, 112u32, 64u32);
    let mut img = image::RgbImage::from_pixel(
        left + K as u32 * cell + 16,
        top + K as u32 * cell + 40,
        image::Rgb([255, 255, 255]),
    );
    let black = [0, 0, 0];
    draw_text(&mut img, left, 8, "prediction", black, 1);
    draw_text(&mut img, 8, 8, "truth", black, 1);
    for k in 0..K {
        let name = Class::ALL[k].name();
        draw_text(
            &mut img,
            left + k as u32 * cell + (cell - text_width(name, 1)) / 2,
            top - 20,
            name,
            black,
            1,
        );
        draw_text(
            &mut img,
            8,
            top + k as u32 * cell + cell / 2 - 4,
            name,
            black,
            1,
        );
    }
    for g in 0..K {
        let row: u64 = c.m[g].iter().sum();
        for p in 0..K {
            let share = if row == 0 {
                0.0
            } else {
                c.m[g][p] as f64 / row as f64
            };
            let shade = (255.0 - share * 200.0) as u8;
            let colour = if g == p {
                [shade, 255, shade]
            } else {
                [255, shade, shade]
            };
            let (x0, y0) = (left + p as u32 * cell, top + g as u32 * cell);
            for x in x0..x0 + cell - 2 {
                for y in y0..y0 + cell - 2 {
                    img.put_pixel(x, y, image::Rgb(colour));
                }
            }
            let count = c.m[g][p].to_string();
            let pct = format!("{:.1}%", share * 100.0);
            draw_text(
                &mut img,
                x0 + (cell - text_width(&count, 1)) / 2,
                y0 + cell / 2 - 12,
                &count,
                black,
                1,
            );
            draw_text(
                &mut img,
                x0 + (cell - text_width(&pct, 1)) / 2,
                y0 + cell / 2 + 4,
                &pct,
                black,
                1,
            );
        }
    }
    let miou = format!("mIoU {:.3}", c.miou());
    draw_text(&mut img, left, top + K as u32 * cell + 12, &miou, black, 1);
    img
}

/// Side-by-side picture of one frame: prediction above ground truth, in the class colours
/// (empty cells black), rows doubled, with a caption.
pub fn frame_chart(
    id: &str,
    maps: &FrameMaps,
    rows: usize,
    cols: usize,
    miou: Option<f64>,
) -> image::RgbImage {
    use crate::preview::{draw_text, ROW_SCALE};
    let ph = rows as u32 * ROW_SCALE;
    let caption = 20u32;
    let mut img =
        image::RgbImage::from_pixel(cols as u32, 2 * (ph + caption), image::Rgb([255, 255, 255]));
    let m = miou
        .map(|v| format!("{v:.3}"))
        .unwrap_or_else(|| "-".into());
    draw_text(
        &mut img,
        4,
        6,
        &format!("{id} prediction, mIoU {m}"),
        [0, 0, 0],
        1,
    );
    draw_text(&mut img, 4, ph + caption + 6, "ground truth", [0, 0, 0], 1);
    for (panel, labels) in [&maps.pred, &maps.truth].iter().enumerate() {
        let y0 = panel as u32 * (ph + caption) + caption;
        for r in 0..rows {
            for c in 0..cols {
                let i = r * cols + c;
                let px = if maps.truth[i] == u8::MAX {
                    [0, 0, 0]
                } else {
                    Class::from_id(labels[i]).unwrap_or_default().colour()
                };
                for k in 0..ROW_SCALE {
                    img.put_pixel(c as u32, y0 + r as u32 * ROW_SCALE + k, image::Rgb(px));
                }
            }
        }
    }
    img
}
