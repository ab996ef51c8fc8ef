//! Class-balance and channel statistics of a `convert` output folder, per split.
//!
//! Reads `DIR/lidar_2d/*.npy` (cells), `DIR/labels/<drive>/<frame>.label` when present (points),
//! and, given the raw root, the tracklets (instances, poses, state / occlusion / truncation). The
//! frames are processed in parallel in fixed-size chunks whose partial sums are added in frame
//! order, so memory stays constant and the figures are identical whatever the thread count.
//! JSON keys are documented in `docs/stats.md`; the trainer reads `normalisation` and
//! `class_weights`.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use rayon::prelude::*;
use serde::Serialize;

use crate::error::{Error, Result};
use crate::kitti::tracklets::Tracklets;
use crate::kitti::{discover, FrameId};
use crate::label::Class;
use crate::project::frame::{LIDAR_CHANNELS, RGB_CHANNELS};
use crate::write::npy::read_f32;

/// SqueezeSeg's default class loss weights (background, car, pedestrian, cyclist).
pub const SQUEEZESEG_WEIGHTS: [f64; 4] = [1.0 / 15.0, 1.0, 10.0, 10.0];

/// Version of the JSON layout; bumped when a key changes meaning.
pub const STATS_VERSION: u32 = 1;

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
pub type PerClass<T> = BTreeMap<&'static str, T>;

fn per_class<T: Copy>(a: [T; 4]) -> PerClass<T> {
    Class::ALL
        .iter()
        .map(|c| (c.name(), a[*c as usize]))
        .collect()
}

/// Tracklet-level figures of a split.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct TrackletStats {
    /// Distinct tracklets with a pose at a frame of the split, per class.
    pub instances: PerClass<u64>,
    /// Poses at frames of the split, per class.
    pub poses: PerClass<u64>,
    /// Poses by `state` (all object types).
    pub state: BTreeMap<String, u64>,
    /// Poses by `occlusion`.
    pub occlusion: BTreeMap<String, u64>,
    /// Poses by `truncation`.
    pub truncation: BTreeMap<String, u64>,
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
    pub channel_mean: BTreeMap<&'static str, f64>,
    /// Standard deviation of each input channel over valid cells.
    pub channel_std: BTreeMap<&'static str, f64>,
    /// Tracklet figures (with the raw root).
    pub tracklets: Option<TrackletStats>,
}

/// Normalisation constants in channel order (the label channel left out).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Normalisation {
    /// The split they come from.
    pub from_split: String,
    /// Channel names, in tensor order without `label`.
    pub channels: Vec<&'static str>,
    /// SqueezeSeg's INPUT_MEAN.
    pub mean: Vec<f64>,
    /// SqueezeSeg's INPUT_STD.
    pub std: Vec<f64>,
}

/// Suggested class loss weights (background, car, pedestrian, cyclist), car = 1.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ClassWeights {
    /// The split the frequencies come from.
    pub from_split: String,
    /// 1 / frequency of valid cells, scaled so that car = 1.
    pub inverse_frequency: [f64; 4],
    /// sqrt(1 / frequency), scaled so that car = 1.
    pub sqrt_inverse_frequency: [f64; 4],
    /// SqueezeSeg's defaults [1/15, 1, 10, 10].
    pub squeezeseg_default: [f64; 4],
}

/// The whole report.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Stats {
    /// JSON layout version.
    pub version: u32,
    /// Map shape (rows, cols) and channel names.
    pub rows: usize,
    /// Columns.
    pub cols: usize,
    /// Channel names of the tensors.
    pub channels: Vec<&'static str>,
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
    /// `convert_summary.json` of the folder, when present (collisions, fallbacks).
    pub convert_summary: Option<serde_json::Value>,
}

/// Lists the converted frames of `dir` (`lidar_2d/*.npy` whose stem is a frame id), sorted.
pub fn converted_frames(dir: &Path) -> Result<Vec<FrameId>> {
    let l2d = dir.join("lidar_2d");
    let rd = std::fs::read_dir(&l2d).map_err(|e| Error::io(&l2d, e))?;
    let mut ids = Vec::new();
    for e in rd {
        let p = e.map_err(|e| Error::io(&l2d, e))?.path();
        if p.extension().is_some_and(|x| x == "npy") {
            if let Some(id) = p
                .file_stem()
                .and_then(|s| s.to_str())
                .and_then(|s| s.parse::<FrameId>().ok())
            {
                ids.push(id);
            }
        }
    }
    if ids.is_empty() {
        return Err(Error::Input {
            path: l2d,
            message: "no converted frame (<frame id>.npy) here".into(),
        });
    }
    ids.sort();
    Ok(ids)
}

pub use crate::write::{label_path, npy_path};

/// Sums of one frame or chunk.
#[derive(Debug, Clone)]
struct Acc {
    frames: u64,
    cells: [u64; 4],
    points: [u64; 4],
    points_known: bool,
    frames_with: [u64; 4],
    row_filled: Vec<u64>,
    rgb_cells: u64,
    sum: Vec<f64>,
    sum_sq: Vec<f64>,
}

impl Acc {
    fn new(rows: usize, inputs: usize) -> Acc {
        Acc {
            frames: 0,
            cells: [0; 4],
            points: [0; 4],
            points_known: true,
            frames_with: [0; 4],
            row_filled: vec![0; rows],
            rgb_cells: 0,
            sum: vec![0.0; inputs],
            sum_sq: vec![0.0; inputs],
        }
    }

    fn add(&mut self, o: &Acc) {
        self.frames += o.frames;
        for k in 0..4 {
            self.cells[k] += o.cells[k];
            self.points[k] += o.points[k];
            self.frames_with[k] += o.frames_with[k];
        }
        self.points_known &= o.points_known;
        for (a, b) in self.row_filled.iter_mut().zip(&o.row_filled) {
            *a += b;
        }
        self.rgb_cells += o.rgb_cells;
        for i in 0..self.sum.len() {
            self.sum[i] += o.sum[i];
            self.sum_sq[i] += o.sum_sq[i];
        }
    }
}

/// Input channel indices (all but `label`, index 5).
fn input_indices(depth: usize) -> Vec<usize> {
    (0..depth).filter(|&c| c != 5).collect()
}

fn frame_acc(dir: &Path, id: &FrameId, shape: &[u64; 3]) -> Result<Acc> {
    let path = npy_path(dir, id);
    let (s, data) = read_f32(&path)?;
    if s.as_slice() != shape.as_slice() {
        return Err(Error::format(&path, format!("shape {s:?} differs from the first frame's {shape:?} (mixed 6- and 9-channel outputs?)")));
    }
    let (rows, cols, depth) = (shape[0] as usize, shape[1] as usize, shape[2] as usize);
    let inputs = input_indices(depth);
    let mut acc = Acc::new(rows, inputs.len());
    acc.frames = 1;
    for (i, cell) in data.chunks_exact(depth).enumerate() {
        if cell[4] <= 0.0 {
            continue;
        }
        let class = cell[5];
        let k = class as usize;
        if class.fract() != 0.0 || k > 3 {
            return Err(Error::format(
                &path,
                format!("cell {i} has label {class}, not a class id 0-3"),
            ));
        }
        acc.cells[k] += 1;
        acc.row_filled[i / cols] += 1;
        for (j, &c) in inputs.iter().enumerate() {
            let v = cell[c] as f64;
            acc.sum[j] += v;
            acc.sum_sq[j] += v * v;
        }
        if depth == 9 && cell[6..9].iter().any(|v| *v > 0.0) {
            acc.rgb_cells += 1;
        }
    }
    for k in 0..4 {
        acc.frames_with[k] = (acc.cells[k] > 0) as u64;
    }
    let lp = label_path(dir, id);
    match std::fs::read(&lp) {
        Ok(bytes) => {
            if bytes.len() % 4 != 0 {
                return Err(Error::format(
                    &lp,
                    format!("{} bytes, not a multiple of 4", bytes.len()),
                ));
            }
            for w in bytes.chunks_exact(4) {
                let class = (u32::from_le_bytes([w[0], w[1], w[2], w[3]]) & 0xffff) as usize;
                if class > 3 {
                    return Err(Error::format(
                        &lp,
                        format!("point label {class} is not a class id 0-3"),
                    ));
                }
                acc.points[class] += 1;
            }
        }
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => acc.points_known = false,
        Err(e) => return Err(Error::io(&lp, e)),
    }
    Ok(acc)
}

/// Frames per parallel chunk: bounds memory, fixes the order of additions.
const CHUNK: usize = 64;

fn accumulate(
    dir: &Path,
    frames: &[FrameId],
    shape: &[u64; 3],
    progress: &(dyn Fn(u64) + Sync),
) -> Result<Acc> {
    let inputs = input_indices(shape[2] as usize).len();
    let mut total = Acc::new(shape[0] as usize, inputs);
    for chunk in frames.chunks(CHUNK) {
        let parts: Vec<Result<Acc>> = chunk
            .par_iter()
            .map(|id| {
                let r = frame_acc(dir, id, shape);
                progress(1);
                r
            })
            .collect();
        for p in parts {
            total.add(&p?);
        }
    }
    Ok(total)
}

fn tracklet_stats(raw: &Path, frames: &[FrameId]) -> Result<TrackletStats> {
    let drives = discover(raw)?;
    let mut by_drive: BTreeMap<(String, u32), Vec<u32>> = BTreeMap::new();
    for id in frames {
        by_drive
            .entry((id.date.clone(), id.drive))
            .or_default()
            .push(id.frame);
    }
    let mut instances = [0u64; 4];
    let mut poses = [0u64; 4];
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
                let k = tr.object_type.class() as usize;
                poses[k] += 1;
                if seen.insert(i) {
                    instances[k] += 1;
                }
                *st.state.entry(format!("{:?}", p.state)).or_default() += 1;
                *st.occlusion
                    .entry(format!("{:?}", p.occlusion))
                    .or_default() += 1;
                *st.truncation
                    .entry(format!("{:?}", p.truncation))
                    .or_default() += 1;
                *st.object_types
                    .entry(tr.object_type.as_str().to_string())
                    .or_default() += 1;
            }
        }
    }
    st.instances = per_class(instances);
    st.poses = per_class(poses);
    Ok(st)
}

fn shares(a: [u64; 4]) -> PerClass<f64> {
    let labelled: u64 = a[1..].iter().sum();
    let mut out = per_class([0.0; 4]);
    for c in &Class::ALL[1..] {
        out.insert(
            c.name(),
            if labelled == 0 {
                0.0
            } else {
                a[*c as usize] as f64 / labelled as f64
            },
        );
    }
    out.remove("background");
    out
}

/// Computes the report. `splits` empty means one split `all` over every converted frame.
pub fn stats(
    dir: &Path,
    splits: &[SplitFrames],
    raw: Option<&Path>,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<Stats> {
    let present: BTreeSet<FrameId> = converted_frames(dir)?.into_iter().collect();
    let splits: Vec<SplitFrames> = if splits.is_empty() {
        vec![SplitFrames {
            name: "all".into(),
            source: None,
            frames: present.iter().cloned().collect(),
        }]
    } else {
        splits.to_vec()
    };
    for s in &splits {
        if let Some(missing) = s.frames.iter().find(|id| !present.contains(id)) {
            let n = s.frames.iter().filter(|id| !present.contains(id)).count();
            let path = s.source.clone().unwrap_or_else(|| dir.to_path_buf());
            return Err(Error::Input {
                path,
                message: format!(
                    "names {n} frame(s) not converted in {}, first {missing}",
                    dir.join("lidar_2d").display()
                ),
            });
        }
    }
    let first = splits
        .iter()
        .flat_map(|s| s.frames.first())
        .next()
        .ok_or_else(|| Error::Input {
            path: dir.into(),
            message: "the split lists are empty".into(),
        })?;
    let (shape0, _) = read_f32(&npy_path(dir, first))?;
    let shape: [u64; 3] = match shape0.as_slice() {
        [h, w, c] if *c == 6 || *c == 9 => [*h, *w, *c],
        other => {
            return Err(Error::format(
                npy_path(dir, first),
                format!("shape {other:?}, expected H x W x 6 or 9"),
            ))
        }
    };
    let channels: Vec<&'static str> = if shape[2] == 9 {
        RGB_CHANNELS.to_vec()
    } else {
        LIDAR_CHANNELS.to_vec()
    };
    let inputs: Vec<&'static str> = input_indices(shape[2] as usize)
        .into_iter()
        .map(|i| channels[i])
        .collect();
    let mut accs = Vec::new();
    let mut out_splits = BTreeMap::new();
    for s in &splits {
        let acc = accumulate(dir, &s.frames, &shape, progress)?;
        let filled: u64 = acc.cells.iter().sum();
        let per_row = (acc.frames * shape[1]).max(1) as f64;
        let mut mean = BTreeMap::new();
        let mut std = BTreeMap::new();
        for (j, name) in inputs.iter().enumerate() {
            let n = filled.max(1) as f64;
            let m = acc.sum[j] / n;
            mean.insert(*name, m);
            std.insert(*name, (acc.sum_sq[j] / n - m * m).max(0.0).sqrt());
        }
        let tracklets = match raw {
            Some(r) => Some(tracklet_stats(r, &s.frames)?),
            None => None,
        };
        out_splits.insert(
            s.name.clone(),
            SplitStats {
                frames: acc.frames,
                cells: per_class(acc.cells),
                points: acc.points_known.then(|| per_class(acc.points)),
                frames_with: per_class(acc.frames_with),
                share_of_labelled_cells: shares(acc.cells),
                share_of_labelled_points: acc.points_known.then(|| shares(acc.points)),
                fill_ratio: filled as f64 / (acc.frames * shape[0] * shape[1]).max(1) as f64,
                row_fill: acc.row_filled.iter().map(|&r| r as f64 / per_row).collect(),
                rgb_coverage: (shape[2] == 9).then(|| acc.rgb_cells as f64 / filled.max(1) as f64),
                channel_mean: mean,
                channel_std: std,
                tracklets,
            },
        );
        accs.push((s.name.clone(), acc));
    }
    let split_share = |get: &dyn Fn(&Acc) -> [u64; 4]| -> PerClass<BTreeMap<String, f64>> {
        let mut out = BTreeMap::new();
        for c in Class::ALL {
            let total: u64 = accs.iter().map(|(_, a)| get(a)[c as usize]).sum();
            let m = accs
                .iter()
                .map(|(n, a)| {
                    (
                        n.clone(),
                        if total == 0 {
                            0.0
                        } else {
                            get(a)[c as usize] as f64 / total as f64
                        },
                    )
                })
                .collect();
            out.insert(c.name(), m);
        }
        out
    };
    let class_split_share = split_share(&|a| a.cells);
    let class_split_share_points = accs
        .iter()
        .all(|(_, a)| a.points_known)
        .then(|| split_share(&|a| a.points));
    // Constants come from `train` when there is one, else from the first split.
    let (base_name, base) = accs.iter().find(|(n, _)| n == "train").unwrap_or(&accs[0]);
    let bs = &out_splits[base_name];
    let normalisation = Normalisation {
        from_split: base_name.clone(),
        channels: inputs.clone(),
        mean: inputs.iter().map(|c| bs.channel_mean[c]).collect(),
        std: inputs.iter().map(|c| bs.channel_std[c]).collect(),
    };
    let total: u64 = base.cells.iter().sum();
    let freq: [f64; 4] = std::array::from_fn(|k| base.cells[k] as f64 / total.max(1) as f64);
    let inv: [f64; 4] = std::array::from_fn(|k| if freq[k] > 0.0 { 1.0 / freq[k] } else { 0.0 });
    let car = if inv[1] > 0.0 { inv[1] } else { 1.0 };
    let class_weights = ClassWeights {
        from_split: base_name.clone(),
        inverse_frequency: inv.map(|w| w / car),
        sqrt_inverse_frequency: inv.map(|w| (w / car).sqrt()),
        squeezeseg_default: SQUEEZESEG_WEIGHTS,
    };
    let summary_path = dir.join(crate::pipeline::SUMMARY_FILE);
    let convert_summary = match std::fs::read_to_string(&summary_path) {
        Ok(t) => Some(
            serde_json::from_str(&t)
                .map_err(|e| Error::format(&summary_path, format!("not JSON: {e}")))?,
        ),
        Err(_) => None,
    };
    Ok(Stats {
        version: STATS_VERSION,
        rows: shape[0] as usize,
        cols: shape[1] as usize,
        channels,
        split_order: splits.iter().map(|s| s.name.clone()).collect(),
        splits: out_splits,
        class_split_share,
        class_split_share_points,
        normalisation,
        class_weights,
        convert_summary,
    })
}

/// A bar chart of the class balance: one group of bars per split (car, pedestrian, cyclist:
/// share of the labelled cells, linear 0-100%, value on top), class colours as in the previews,
/// a light line every 10%, the split name and frame count under each group, a legend on top.
pub fn balance_chart(s: &Stats) -> image::RgbImage {
    use crate::preview::{draw_text, text_width};
    let (bar, gap, group_gap, h, left, top, bottom) =
        (56u32, 8u32, 48u32, 300u32, 48u32, 56u32, 40u32);
    let n = s.split_order.len().max(1) as u32;
    let group = 3 * bar + 2 * gap;
    let w = left + n * group + (n - 1) * group_gap + 24;
    let w = w.max(420);
    let mut img = image::RgbImage::from_pixel(w, top + h + bottom, image::Rgb([255, 255, 255]));
    let black = [0, 0, 0];
    draw_text(
        &mut img,
        left,
        6,
        "share of labelled cells per split",
        black,
        1,
    );
    let mut lx = left;
    for class in [Class::Car, Class::Pedestrian, Class::Cyclist] {
        for x in lx..lx + 12 {
            for y in 22..34 {
                img.put_pixel(x, y, image::Rgb(class.colour()));
            }
        }
        draw_text(&mut img, lx + 16, 24, class.name(), black, 1);
        lx += 16 + text_width(class.name(), 1) + 20;
    }
    for t in 0..=10 {
        let y = top + h - t * h / 10;
        for x in left..w - 8 {
            img.put_pixel(
                x,
                y,
                image::Rgb(if t == 0 { black } else { [225, 225, 225] }),
            );
        }
        if t % 2 == 0 {
            let label = format!("{}%", t * 10);
            draw_text(
                &mut img,
                left.saturating_sub(text_width(&label, 1) + 4),
                y.saturating_sub(4),
                &label,
                black,
                1,
            );
        }
    }
    for (g, name) in s.split_order.iter().enumerate() {
        let split = &s.splits[name];
        let x_group = left + g as u32 * (group + group_gap);
        for (b, class) in [Class::Car, Class::Pedestrian, Class::Cyclist]
            .iter()
            .enumerate()
        {
            let v = split
                .share_of_labelled_cells
                .get(class.name())
                .copied()
                .unwrap_or(0.0);
            let bh = (v * h as f64).round() as u32;
            let x0 = x_group + b as u32 * (bar + gap);
            for x in x0..x0 + bar {
                for y in (top + h - bh)..(top + h) {
                    img.put_pixel(x, y, image::Rgb(class.colour()));
                }
            }
            let label = format!("{:.1}%", v * 100.0);
            let lx = x0 + bar.saturating_sub(text_width(&label, 1)) / 2;
            draw_text(
                &mut img,
                lx,
                (top + h - bh).saturating_sub(12),
                &label,
                black,
                1,
            );
        }
        let caption = format!("{name} ({} frames)", split.frames);
        let cx = x_group + group.saturating_sub(text_width(&caption, 1)) / 2;
        draw_text(&mut img, cx, top + h + 12, &caption, black, 1);
    }
    img
}
