//! REPORT: class-balance and channel statistics of converted ground truth, per split.
//!
//! Reads the frames through [`GroundTruth`] (a convert folder, its `lidar_2d`, a bare folder of
//! maps, or shards), the `.label` files when the convert folder has them (points), and, given
//! the raw root, the tracklets (instances, poses, state / occlusion / truncation). Frames are
//! processed in parallel; their sums are added in frame order, so the figures are identical
//! whatever the thread count. JSON keys are documented in `docs/stats.md`; the trainer reads
//! `normalisation`, `class_weights` and `class_map`.

mod acc;

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use serde::Serialize;

use crate::error::{Error, Result};
use crate::format::summary::{self, ConvertSummary};
use crate::label::{ClassCounts, ClassMap};
use crate::report::truth::GroundTruth;
use crate::source::kitti::tracklets::{Occlusion, PoseState, Tracklets, Truncation};
use crate::source::kitti::{discover, FrameId};
use acc::Acc;

/// Version of the JSON layout; bumped when a key changes meaning.
pub const STATS_VERSION: u32 = 2;

/// A named list of frames.
#[derive(Debug, Clone)]
pub struct SplitFrames {
    /// Split name (`train`, `val`, `all`, ...).
    pub name: String,
    /// Where the list came from (for errors), if a file.
    pub source: Option<PathBuf>,
    /// The frames.
    pub frames: Vec<FrameId>,
}

/// Per-class numbers keyed by class name.
pub type PerClass<T> = BTreeMap<String, T>;

/// Tracklet-level figures of a split.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct TrackletStats {
    /// Distinct tracklets with a pose at a frame of the split, per class.
    pub instances: PerClass<u64>,
    /// Poses at frames of the split, per class.
    pub poses: PerClass<u64>,
    /// Poses by `state` (all object types; keys: the enum's names).
    pub state: BTreeMap<PoseState, u64>,
    /// Poses by `occlusion`.
    pub occlusion: BTreeMap<Occlusion, u64>,
    /// Poses by `truncation`.
    pub truncation: BTreeMap<Truncation, u64>,
    /// Poses by object type.
    pub object_types: BTreeMap<String, u64>,
}

/// Figures of one split.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SplitStats {
    /// Frames.
    pub frames: u64,
    /// Valid cells (range > 0) per class.
    pub cells: PerClass<u64>,
    /// Points per class, from the `.label` files (`None` when they were not written).
    pub points: Option<PerClass<u64>>,
    /// Frames with at least one cell of the class.
    pub frames_with: PerClass<u64>,
    /// Share of each object class among the labelled (non-background) cells.
    pub share_of_labelled_cells: PerClass<f64>,
    /// Share of each object class among the labelled points, when known.
    pub share_of_labelled_points: Option<PerClass<f64>>,
    /// Filled cells / all cells.
    pub fill_ratio: f64,
    /// Filled share of each row (row 0 first).
    pub row_fill: Vec<f64>,
    /// Share of filled cells that have a colour (9-channel maps; `None` otherwise).
    pub rgb_coverage: Option<f64>,
    /// Mean of each input channel over valid cells.
    pub channel_mean: BTreeMap<String, f64>,
    /// Standard deviation of each input channel over valid cells.
    pub channel_std: BTreeMap<String, f64>,
    /// Tracklet figures (with the raw root).
    pub tracklets: Option<TrackletStats>,
}

/// Normalisation constants in channel order (the label channel left out).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Normalisation {
    /// The split they come from.
    pub from_split: String,
    /// Channel names, in tensor order without `label`.
    pub channels: Vec<String>,
    /// SqueezeSeg's INPUT_MEAN.
    pub mean: Vec<f64>,
    /// SqueezeSeg's INPUT_STD.
    pub std: Vec<f64>,
}

/// Suggested class loss weights in class id order, the most frequent labelled class = 1 (car on
/// KITTI); 0 for ignored classes and for classes absent from the split.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ClassWeights {
    /// The split the frequencies come from.
    pub from_split: String,
    /// 1 / frequency of valid cells.
    pub inverse_frequency: Vec<f64>,
    /// sqrt(1 / frequency).
    pub sqrt_inverse_frequency: Vec<f64>,
    /// The class map's reference weights (SqueezeSeg's [1/15, 1, 10, 10]), when it has some.
    pub reference: Option<Vec<f64>>,
}

/// The whole report.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Stats {
    /// JSON layout version.
    pub version: u32,
    /// Map rows.
    pub rows: usize,
    /// Columns.
    pub cols: usize,
    /// Channel names of the tensors.
    pub channels: Vec<String>,
    /// The classes of the ground truth.
    pub class_map: ClassMap,
    /// Where the map parameters come from (recorded, or assumed for a bare folder).
    pub provenance: String,
    /// Per split, in the order given.
    pub splits: BTreeMap<String, SplitStats>,
    /// Order of the splits as given.
    pub split_order: Vec<String>,
    /// For each class, the share of its cells in each split.
    pub class_split_share: PerClass<BTreeMap<String, f64>>,
    /// For each class, the share of its points in each split (when `.label` files exist).
    pub class_split_share_points: Option<PerClass<BTreeMap<String, f64>>>,
    /// Normalisation constants.
    pub normalisation: Normalisation,
    /// Class weights.
    pub class_weights: ClassWeights,
    /// The folder's conversion summary, when present (collisions, fallbacks).
    pub convert_summary: Option<ConvertSummary>,
}

fn tracklet_stats(raw: &Path, frames: &[FrameId], map: &ClassMap) -> Result<TrackletStats> {
    let drives = discover(raw)?;
    let mut by_drive: BTreeMap<(String, u32), Vec<u32>> = BTreeMap::new();
    for id in frames {
        by_drive
            .entry((id.date.clone(), id.drive))
            .or_default()
            .push(id.frame);
    }
    let mut instances = vec![0u64; map.len()];
    let mut poses = vec![0u64; map.len()];
    let mut st = TrackletStats::default();
    for d in drives {
        let Some(fs) = by_drive.get(&(d.date.clone(), d.number)) else {
            continue;
        };
        let path = d.tracklets_path();
        if !path.exists() {
            continue;
        }
        let t = Tracklets::read(&path)?;
        let mut seen = BTreeSet::new();
        for &f in fs {
            for (i, tr, p) in t.at(f) {
                let k = map.class_of_object(tr.object_type.as_str()) as usize;
                poses[k] += 1;
                if seen.insert(i) {
                    instances[k] += 1;
                }
                *st.state.entry(p.state).or_default() += 1;
                *st.occlusion.entry(p.occlusion).or_default() += 1;
                *st.truncation.entry(p.truncation).or_default() += 1;
                *st.object_types
                    .entry(tr.object_type.as_str().to_string())
                    .or_default() += 1;
            }
        }
    }
    st.instances = map.keyed(&instances);
    st.poses = map.keyed(&poses);
    Ok(st)
}

/// Share of each labelled class among the labelled (non-background, scored) elements.
fn shares(a: &ClassCounts, map: &ClassMap) -> PerClass<f64> {
    let labelled = map.labelled();
    let total: u64 = labelled.iter().map(|&c| a.get(c)).sum();
    labelled
        .iter()
        .map(|&c| {
            let v = if total == 0 {
                0.0
            } else {
                a.get(c) as f64 / total as f64
            };
            (map.name(c).to_string(), v)
        })
        .collect()
}

/// The splits to report: `splits`, or one split `all` over every frame; each list checked to
/// name converted frames only, and not all empty.
fn checked_splits(gt: &GroundTruth, splits: &[SplitFrames]) -> Result<Vec<SplitFrames>> {
    let splits: Vec<SplitFrames> = if splits.is_empty() {
        vec![SplitFrames {
            name: "all".into(),
            source: None,
            frames: gt.frames.clone(),
        }]
    } else {
        splits.to_vec()
    };
    let present: BTreeSet<&FrameId> = gt.frames.iter().collect();
    for s in &splits {
        if let Some(missing) = s.frames.iter().find(|id| !present.contains(id)) {
            let n = s.frames.iter().filter(|id| !present.contains(id)).count();
            let path = s.source.clone().unwrap_or_else(|| gt.path.clone());
            return Err(Error::Input {
                path,
                message: format!(
                    "names {n} frame(s) not converted in {}, first {missing}",
                    gt.path.display()
                ),
            });
        }
    }
    if splits.iter().all(|s| s.frames.is_empty()) {
        return Err(Error::Input {
            path: gt.path.clone(),
            message: "the split lists are empty".into(),
        });
    }
    Ok(splits)
}

/// One split's totals, added in frame order.
fn split_acc(
    gt: &GroundTruth,
    s: &SplitFrames,
    per_frame: &BTreeMap<FrameId, Acc>,
    inputs: usize,
) -> Result<Acc> {
    let mut acc = Acc::new(gt.params.spec.rows, gt.params.class_map.len(), inputs);
    let mut sorted: Vec<&FrameId> = s.frames.iter().collect();
    sorted.sort();
    for id in sorted {
        let a = per_frame.get(id).ok_or_else(|| Error::Input {
            path: gt.path.clone(),
            message: format!("frame {id} is listed, but no map of it was found"),
        })?;
        if a.sum.len() != acc.sum.len() {
            return Err(Error::Input {
                path: gt.path.clone(),
                message: format!("frame {id} has {} input channels, the map {} (mixed 6- and 9-channel outputs?)", a.sum.len(), acc.sum.len()),
            });
        }
        acc.add(a);
    }
    Ok(acc)
}

/// A split's figures from its totals.
fn split_stats(
    gt: &GroundTruth,
    acc: &Acc,
    inputs: &[String],
    tracklets: Option<TrackletStats>,
) -> SplitStats {
    let map = &gt.params.class_map;
    let (rows, cols) = (gt.params.spec.rows, gt.params.spec.cols);
    let filled = acc.cells.total();
    let per_row = (acc.frames * cols as u64).max(1) as f64;
    let mut mean = BTreeMap::new();
    let mut std = BTreeMap::new();
    for (j, name) in inputs.iter().enumerate() {
        let n = filled.max(1) as f64;
        let m = acc.sum[j] / n;
        mean.insert(name.clone(), m);
        std.insert(name.clone(), (acc.sum_sq[j] / n - m * m).max(0.0).sqrt());
    }
    SplitStats {
        frames: acc.frames,
        cells: map.keyed(&acc.cells.0),
        points: acc.points_known.then(|| map.keyed(&acc.points.0)),
        frames_with: map.keyed(&acc.frames_with.0),
        share_of_labelled_cells: shares(&acc.cells, map),
        share_of_labelled_points: acc.points_known.then(|| shares(&acc.points, map)),
        fill_ratio: filled as f64 / (acc.frames * (rows * cols) as u64).max(1) as f64,
        row_fill: acc.row_filled.iter().map(|&r| r as f64 / per_row).collect(),
        rgb_coverage: gt
            .params
            .channels()
            .has_rgb()
            .then(|| acc.rgb_cells as f64 / filled.max(1) as f64),
        channel_mean: mean,
        channel_std: std,
        tracklets,
    }
}

/// Each class's share per split, of what `get` counts.
fn split_share(
    accs: &[(String, Acc)],
    map: &ClassMap,
    get: &dyn Fn(&Acc) -> &ClassCounts,
) -> PerClass<BTreeMap<String, f64>> {
    map.ids()
        .map(|c| {
            let total: u64 = accs.iter().map(|(_, a)| get(a).get(c)).sum();
            let m = accs
                .iter()
                .map(|(n, a)| {
                    let v = if total == 0 {
                        0.0
                    } else {
                        get(a).get(c) as f64 / total as f64
                    };
                    (n.clone(), v)
                })
                .collect();
            (map.name(c).to_string(), m)
        })
        .collect()
}

/// Loss weights from a split's labelled cells: inverse frequency scaled so that the most
/// frequent labelled class (car on KITTI) gets 1, and its square root.
fn class_weights(map: &ClassMap, base_name: &str, base: &Acc) -> ClassWeights {
    let total = base.cells.total().max(1) as f64;
    let inv: Vec<f64> = map
        .ids()
        .map(|c| {
            let f = base.cells.get(c) as f64 / total;
            if f > 0.0 && map.is_scored(c) {
                1.0 / f
            } else {
                0.0
            }
        })
        .collect();
    let most = map
        .labelled()
        .into_iter()
        .filter(|&c| inv[c as usize] > 0.0)
        .max_by_key(|&c| base.cells.get(c));
    let scale = most.map_or(1.0, |c| inv[c as usize]);
    ClassWeights {
        from_split: base_name.to_string(),
        inverse_frequency: inv.iter().map(|w| w / scale).collect(),
        sqrt_inverse_frequency: inv.iter().map(|w| (w / scale).sqrt()).collect(),
        reference: map.reference_weights.clone(),
    }
}

/// Computes the report. `splits` empty means one split `all` over every frame.
pub fn stats(
    gt: &GroundTruth,
    splits: &[SplitFrames],
    raw: Option<&Path>,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<Stats> {
    let map = &gt.params.class_map;
    let splits = checked_splits(gt, splits)?;
    let wanted: BTreeSet<FrameId> = splits
        .iter()
        .flat_map(|s| s.frames.iter().cloned())
        .collect();
    let dir = gt.dir.as_ref();
    let per_frame: BTreeMap<FrameId, Acc> = gt
        .map_frames(Some(&wanted), &|f| Acc::of_frame(&f, map, dir), progress)?
        .into_iter()
        .collect();
    let channels = gt.params.channels();
    let inputs: Vec<String> = channels
        .inputs()
        .names()
        .into_iter()
        .map(String::from)
        .collect();
    let (rows, cols) = (gt.params.spec.rows, gt.params.spec.cols);
    let mut accs = Vec::new();
    let mut out_splits = BTreeMap::new();
    for s in &splits {
        let acc = split_acc(gt, s, &per_frame, inputs.len())?;
        let tracklets = raw.map(|r| tracklet_stats(r, &s.frames, map)).transpose()?;
        out_splits.insert(s.name.clone(), split_stats(gt, &acc, &inputs, tracklets));
        accs.push((s.name.clone(), acc));
    }
    let class_split_share = split_share(&accs, map, &|a| &a.cells);
    let class_split_share_points = accs
        .iter()
        .all(|(_, a)| a.points_known)
        .then(|| split_share(&accs, map, &|a| &a.points));
    // Constants come from `train` when there is one, else from the first split.
    let (base_name, base) = accs.iter().find(|(n, _)| n == "train").unwrap_or(&accs[0]);
    let bs = &out_splits[base_name];
    let normalisation = Normalisation {
        from_split: base_name.clone(),
        channels: inputs.clone(),
        mean: inputs.iter().map(|c| bs.channel_mean[c]).collect(),
        std: inputs.iter().map(|c| bs.channel_std[c]).collect(),
    };
    let class_weights = class_weights(map, base_name, base);
    let convert_summary = match dir {
        Some(d) => summary::read(&d.summary_path())?,
        None => None,
    };
    Ok(Stats {
        version: STATS_VERSION,
        rows,
        cols,
        channels: channels.names().into_iter().map(String::from).collect(),
        class_map: map.clone(),
        provenance: gt.provenance_note(),
        split_order: splits.iter().map(|s| s.name.clone()).collect(),
        splits: out_splits,
        class_split_share,
        class_split_share_points,
        normalisation,
        class_weights,
        convert_summary,
    })
}
