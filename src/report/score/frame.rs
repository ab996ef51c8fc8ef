//! SCORE: one frame, cell or point protocol.

use std::path::Path;

use super::confusion::Confusion;
use super::predictions::{read_cell_prediction, PredictionKind, Predictions};
use super::{FrameMaps, FrameScore, Protocol, ScoreOptions};
use crate::error::{Error, Result};
use crate::format::label_file;
use crate::project::unproject::{unproject, Method, PointsInMap};
use crate::project::EMPTY;
use crate::report::truth::GroundTruth;
use crate::source::kitti::{discover_as, DatasetKind, Drive, FrameId};

/// Where a scan's points fall in the map, for the point protocol and per-point predictions.
#[derive(Default)]
struct ScanCells {
    /// (cell, file index) of each point in the field of view.
    point_cells: Vec<(u32, u32)>,
    /// The file index of each cell's point (`u32::MAX` for an empty cell).
    cell_winner_file: Vec<u32>,
    /// The projection and the points' ranges, kept for the kNN.
    knn: Option<(crate::project::Projection, Vec<f32>)>,
    /// The scan file.
    path: std::path::PathBuf,
}

/// The likely cause of a label file shorter than the point it is read at.
const SHORT_LABELS: Option<&'static str> =
    Some("at least: counted up to its last point in the map");

/// Projects the frame's scan with the ground truth's map.
fn scan_cells(gt: &GroundTruth, id: &FrameId, opts: &ScoreOptions) -> Result<ScanCells> {
    let raw = opts.raw.as_ref().ok_or_else(|| Error::NeedsScans {
        frame: id.to_string(),
        what: if opts.protocol == Protocol::Points {
            "the point protocol"
        } else {
            "scoring .label predictions per cell"
        },
    })?;
    let drive = raw_drive(raw, id)?;
    let path = drive.scan_path(id.frame);
    let (scan, proj) =
        crate::project::project_scan(&gt.params.spec, gt.params.sensor.as_ref(), &path)?;
    let file_idx = scan.file_indices();
    let cell_winner_file = proj
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
    let point_cells = proj
        .point_cell
        .iter()
        .zip(&file_idx)
        .filter(|(c, _)| **c != EMPTY)
        .map(|(c, f)| (*c, *f))
        .collect();
    // The points' ranges only where the kNN compares them.
    let knn = matches!(opts.unproject, Method::Knn(_)).then(|| {
        let range = scan.points.iter().map(crate::project::norm).collect();
        (proj, range)
    });
    Ok(ScanCells {
        point_cells,
        cell_winner_file,
        knn,
        path,
    })
}

/// The predicted class of every cell: a map prediction, a shard's, per-point labels taken at
/// each cell's point, or background when the prediction is missing.
fn predicted_cells(
    preds: &Predictions,
    id: &FrameId,
    gt: &GroundTruth,
    scan: &ScanCells,
) -> Result<Vec<u8>> {
    let (map, spec) = (&gt.params.class_map, &gt.params.spec);
    let shape = (spec.rows, spec.cols);
    Ok(
        match (preds.files.get(id), preds.kind == PredictionKind::Points) {
            (None, _) => match preds.in_shard.get(id) {
                Some(&(k, chunk)) => preds.shard_prediction(k, chunk, id, shape, map)?,
                None => vec![0; shape.0 * shape.1],
            },
            (Some(p), false) => read_cell_prediction(p, shape, map)?.labels,
            (Some(p), true) => {
                let pl = label_file::read_predicted_classes(p, map)?;
                let winners = scan.cell_winner_file.iter().filter(|&&f| f != u32::MAX);
                let n = winners.map(|&f| f as usize + 1).max().unwrap_or(0);
                if pl.len() < n {
                    return Err(Error::LabelCount {
                        path: p.clone(),
                        labels: pl.len(),
                        scan: scan.path.clone(),
                        points: n,
                        note: SHORT_LABELS,
                    });
                }
                scan.cell_winner_file
                    .iter()
                    .map(|&f| match f {
                        u32::MAX => 0,
                        f => pl[f as usize].unwrap_or(map.background),
                    })
                    .collect()
            }
        },
    )
}

/// Scores one frame against its ground truth (`u8::MAX` in empty cells); the point protocol
/// reads the `.label` files of the ground truth's convert folder. The frame's truth and
/// predicted label maps come back with the score.
pub fn score_frame(
    gt: &GroundTruth,
    id: &FrameId,
    truth: Vec<u8>,
    preds: &Predictions,
    opts: &ScoreOptions,
) -> Result<(FrameScore, FrameMaps)> {
    let map = &gt.params.class_map;
    let missing = !preds.files.contains_key(id) && !preds.in_shard.contains_key(id);
    if missing && !opts.missing_as_background {
        return Err(Error::MissingPrediction {
            root: preds.root.clone(),
            frame: id.to_string(),
            expected: None,
        });
    }
    let needs_scan =
        opts.protocol == Protocol::Points || (preds.kind == PredictionKind::Points && !missing);
    let scan = if needs_scan {
        scan_cells(gt, id, opts)?
    } else {
        ScanCells::default()
    };
    let pred_cells = predicted_cells(preds, id, gt, &scan)?;
    let mut c = Confusion::new(map.len());
    match opts.protocol {
        Protocol::Cells => {
            for (t, p) in truth.iter().zip(&pred_cells) {
                if *t != u8::MAX && map.is_scored(*t) {
                    c.count(*t, *p);
                }
            }
        }
        Protocol::Points => count_points(&mut c, gt, id, preds, opts, &scan, &pred_cells)?,
    }
    let maps = FrameMaps {
        truth,
        pred: pred_cells,
    };
    Ok((
        FrameScore {
            id: id.clone(),
            confusion: c,
            missing,
        },
        maps,
    ))
}

/// The point protocol: every point in the map against its `.label` truth; a SemanticKITTI
/// frame's points outside the map count as background.
fn count_points(
    c: &mut Confusion,
    gt: &GroundTruth,
    id: &FrameId,
    preds: &Predictions,
    opts: &ScoreOptions,
    scan: &ScanCells,
    pred_cells: &[u8],
) -> Result<()> {
    let map = &gt.params.class_map;
    let gt_dir = gt.dir.as_ref().ok_or_else(|| {
        Error::Config(
            "the point protocol needs a convert output folder as ground truth (its .label files)"
                .into(),
        )
    })?;
    let lp = gt_dir.label_path(id);
    let gt_points = label_file::read_classes(&lp, map)?;
    let pred_file = preds
        .files
        .get(id)
        .filter(|_| preds.kind == PredictionKind::Points);
    let pred_points = pred_file
        .map(|p| label_file::read_predicted_classes(p, map))
        .transpose()?;
    // Map predictions reach the points by the chosen method (kept points, in the order of
    // point_cells).
    let carried = match (&pred_points, &scan.knn) {
        (None, Some((proj, range))) => Some(carry(gt, proj, range, pred_cells, opts)?),
        _ => None,
    };
    let short = |file: &Path, n: usize, fi: u32| Error::LabelCount {
        path: file.into(),
        labels: n,
        scan: scan.path.clone(),
        points: fi as usize + 1,
        note: SHORT_LABELS,
    };
    for (k, &(cell, fi)) in scan.point_cells.iter().enumerate() {
        let t = *gt_points
            .get(fi as usize)
            .ok_or_else(|| short(&lp, gt_points.len(), fi))?;
        let p = match (&pred_points, pred_file, &carried) {
            // A point the file says was not predicted counts as background.
            (Some(pp), Some(file), _) => pp
                .get(fi as usize)
                .ok_or_else(|| short(file, pp.len(), fi))?
                .unwrap_or(map.background),
            (_, _, Some(c)) => c[k],
            _ => pred_cells[cell as usize],
        };
        if map.is_scored(t) {
            c.count(t, p);
        }
    }
    // SemanticKITTI's benchmark scores every point of the scan: map predictions leave the
    // points outside the map unlabeled (the background class), and they count.
    if id.dataset == DatasetKind::Sequence && pred_points.is_none() {
        let mut inside = vec![false; gt_points.len()];
        for &(_, fi) in &scan.point_cells {
            if let Some(v) = inside.get_mut(fi as usize) {
                *v = true;
            }
        }
        for (t, _) in gt_points.iter().zip(&inside).filter(|(_, i)| !**i) {
            if map.is_scored(*t) {
                c.count(*t, map.background);
            }
        }
    }
    Ok(())
}

/// A map prediction carried to the points in the map by the kNN.
fn carry(
    gt: &GroundTruth,
    proj: &crate::project::Projection,
    range: &[f32],
    pred_cells: &[u8],
    opts: &ScoreOptions,
) -> Result<Vec<u8>> {
    let m = PointsInMap::of(proj, range);
    Ok(
        unproject(&m, pred_cells, &opts.unproject, &gt.params.class_map)?
            .into_iter()
            .flatten()
            .collect(),
    )
}

/// The drive of a frame under `raw` (a KITTI raw root, date folder or drive folder; a
/// SemanticKITTI root or sequence; an object root or split).
pub fn raw_drive(raw: &Path, id: &FrameId) -> Result<Drive> {
    let name = id.drive_name();
    if id.dataset != DatasetKind::Raw {
        // A SemanticKITTI root or sequence, an object root or split.
        return discover_as(raw, Some(id.dataset))?
            .drives
            .into_iter()
            .find(|d| d.number == id.drive)
            .ok_or_else(|| Error::Input {
                path: raw.into(),
                message: format!("no {name} for frame {id}"),
            });
    }
    for candidate in [
        raw.join(&id.date).join(&name),
        raw.join(&name),
        raw.to_path_buf(),
    ] {
        if candidate.file_name().and_then(|n| n.to_str()) == Some(name.as_str())
            && candidate.is_dir()
        {
            return Ok(Drive::from_dir(&candidate).expect("a drive folder name"));
        }
    }
    Err(Error::Input {
        path: raw.into(),
        message: format!("drive {name} of frame {id} not found"),
    })
}
