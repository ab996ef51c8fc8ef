//! SCORE: one frame, cell or point protocol.

use std::path::Path;

use super::confusion::Confusion;
use super::predictions::{read_cell_prediction, Predictions};
use super::{FrameMaps, FrameScore, Protocol, ScoreOptions};
use crate::error::{Error, Result};
use crate::format::label_file;
use crate::kitti::velodyne::Scan;
use crate::kitti::{discover_as, Drive, FrameId, Layout};
use crate::project::unproject::{unproject, Method, PointsInMap};
use crate::project::{project_with_point_cells, EMPTY};
use crate::report::truth::GroundTruth;

/// Scores one frame against its ground truth (`u8::MAX` in empty cells); the point protocol
/// reads the `.label` files of the ground truth's convert folder.
pub fn score_frame(
    gt: &GroundTruth,
    id: &FrameId,
    truth: Vec<u8>,
    preds: &Predictions,
    opts: &ScoreOptions,
    want_maps: bool,
) -> Result<(FrameScore, Option<FrameMaps>)> {
    let spec = &gt.params.spec;
    let map = &gt.params.class_map;
    let (rows, cols) = (spec.rows, spec.cols);
    let cells = rows * cols;
    let pred_file = preds.files.get(id);
    let pred_shard = preds.in_shard.get(id);
    if pred_file.is_none() && pred_shard.is_none() && !opts.missing_as_background {
        return Err(Error::MissingPrediction {
            root: preds.root.clone(),
            frame: id.to_string(),
            expected: None,
        });
    }
    let missing = pred_file.is_none() && pred_shard.is_none();
    let needs_scan = opts.protocol == Protocol::Points || (preds.points && !missing);
    // Per point: (cell, file index) of each point in the field of view, from the scan.
    let mut point_cells: Vec<(u32, u32)> = Vec::new();
    let mut cell_winner_file: Vec<u32> = Vec::new();
    // The projection and the points' ranges, kept for the kNN (--unproject knn).
    let mut scan_cells: Option<(crate::project::Projection, Vec<f32>)> = None;
    if needs_scan {
        let raw = opts.raw.as_ref().ok_or_else(|| Error::NeedsScans {
            frame: id.to_string(),
            what: if opts.protocol == Protocol::Points {
                "the point protocol"
            } else {
                "scoring .label predictions per cell"
            },
        })?;
        let drive = raw_drive(raw, id)?;
        let scan = Scan::read(&drive.scan_path(id.frame))?;
        let proj = project_with_point_cells(&scan.points, spec);
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
        // The points' ranges only where the kNN compares them.
        if matches!(opts.unproject, Method::Knn(_)) {
            let range = scan.points.iter().map(crate::project::norm).collect();
            scan_cells = Some((proj, range));
        }
    }
    // Predicted class per cell.
    let pred_cells: Vec<u8> = match (pred_file, preds.points) {
        (None, _) => match pred_shard {
            Some(&(k, chunk)) => preds.shard_prediction(k, chunk, id, (rows, cols), map)?,
            None => vec![0; cells],
        },
        (Some(p), false) => read_cell_prediction(p, (rows, cols), map)?.labels,
        (Some(p), true) => {
            let pl = label_file::read_classes(p, map)?;
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
    let mut c = Confusion::new(map.len());
    match opts.protocol {
        Protocol::Cells => {
            for (t, p) in truth.iter().zip(&pred_cells) {
                if *t != u8::MAX && map.is_scored(*t) {
                    c.count(*t, *p);
                }
            }
        }
        Protocol::Points => {
            let gt_dir = gt.dir.as_ref().ok_or_else(|| {
                Error::Config("the point protocol needs a convert output folder as ground truth (its .label files)".into())
            })?;
            let lp = gt_dir.label_path(id);
            let gt_points = label_file::read_classes(&lp, map)?;
            let pred_points = match (pred_file, preds.points) {
                (Some(p), true) => Some(label_file::read_classes(p, map)?),
                _ => None,
            };
            // Map predictions reach the points by the chosen method (kept points, in the
            // order of point_cells).
            let carried: Option<Vec<u8>> = match (&pred_points, &opts.unproject, &scan_cells) {
                (None, Method::Knn(_), Some((proj, range))) => {
                    let m = PointsInMap {
                        rows,
                        cols,
                        point_cell: &proj.point_cell,
                        point_range: range,
                        cell_range: &proj.cell_range,
                    };
                    Some(
                        unproject(&m, &pred_cells, &opts.unproject, map)?
                            .into_iter()
                            .flatten()
                            .collect(),
                    )
                }
                _ => None,
            };
            for (k, &(cell, fi)) in point_cells.iter().enumerate() {
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
                    None => match &carried {
                        Some(c) => c[k],
                        None => pred_cells[cell as usize],
                    },
                };
                if map.is_scored(t) {
                    c.count(t, p);
                }
            }
            // SemanticKITTI's benchmark scores every point of the scan: map predictions leave
            // the points outside the map unlabeled (the background class), and they count.
            if id.layout == Layout::Sequence && pred_points.is_none() {
                let mut inside = vec![false; gt_points.len()];
                for &(_, fi) in &point_cells {
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

/// The drive of a frame under `raw` (a KITTI raw root, date folder or drive folder; a
/// SemanticKITTI root or sequence; an object root or split).
pub fn raw_drive(raw: &Path, id: &FrameId) -> Result<Drive> {
    let name = id.drive_name();
    if id.layout != Layout::Raw {
        // A SemanticKITTI root or sequence, an object root or split.
        return discover_as(raw, Some(id.layout))?
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
