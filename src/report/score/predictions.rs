//! SCORE: predictions, found and read.
//!
//! Predictions are matched to ground-truth frames by frame id (the file stem; for `.label` files
//! the drive folder and the frame number). Formats, detected per file: H x W label maps (`.npy`,
//! integer or integral float), H x W x K class scores (`.npy`, argmax), SqueezeSeg-layout
//! H x W x 6 or 9 `.npy` (its label channel), per-point `.label` files (low 16 bits), and
//! prediction shards. Every label read is checked to be a class of the ground truth's map.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::Serialize;

use crate::error::{Error, NotAFrameId, Result};
use crate::format::npy::{read_any, NpyArray};
use crate::format::shard::Shard;
use crate::label::{ClassId, ClassMap};
use crate::project::{Channel, Channels};
use crate::source::kitti::{parse_drive_name, FrameId};

/// The kind of a prediction file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum PredFormat {
    /// H x W class ids (`.npy`).
    LabelMap,
    /// H x W x K class scores (`.npy`, argmax; K = classes of the map).
    ScoreMap,
    /// SqueezeSeg layout H x W x 6 or 9 (`.npy`, channel 5).
    SqueezeSeg,
    /// One u32 per point of the scan (`.label`, low 16 bits).
    PointLabels,
}

/// The format family of a set of predictions.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PredictionKind {
    /// Map predictions, one `.npy` per frame (H x W labels, H x W x K scores, SqueezeSeg's layout).
    Maps,
    /// Per-point predictions, one `.label` per frame.
    Points,
    /// Map predictions in prediction shards.
    Shards,
}

/// Predictions by frame id, all of one format family ([`PredictionKind`]).
pub struct Predictions {
    /// The folder or file given.
    pub root: PathBuf,
    /// Files by frame (`.npy` or `.label`).
    pub files: BTreeMap<FrameId, PathBuf>,
    /// Their format family.
    pub kind: PredictionKind,
    /// Prediction shards, and where each frame's message is: (shard, chunk).
    shards: Vec<(Shard, mcap::read::Summary)>,
    /// Where each frame of prediction shards is: (shard, chunk).
    pub(super) in_shard: BTreeMap<FrameId, (usize, usize)>,
}

fn frame_id_of(path: &Path) -> Option<FrameId> {
    let stem = path.file_stem()?.to_str()?;
    match path.extension()?.to_str()? {
        "npy" => stem.parse().ok(),
        "label" => {
            let digits = |t: &str, n| t.len() == n && t.bytes().all(|c| c.is_ascii_digit());
            let parent = path.parent()?;
            let drive = parent.file_name()?.to_str()?;
            if let Some((date, number)) = parse_drive_name(drive) {
                // convert's raw layout: labels/<date>_drive_<NNNN>_sync/<frame10>.label
                digits(stem, 10).then_some(())?;
                return Some(FrameId::raw(&date, number, stem.parse().ok()?));
            }
            digits(stem, 6).then_some(())?;
            // SemanticKITTI's sequences/<NN>/predictions/<frame6>.label, convert's
            // labels/<NN>/<frame6>.label, or labels/object/<frame6>.label.
            let seq = if drive == "predictions" {
                parent.parent()?.file_name()?.to_str()?
            } else {
                drive
            };
            if drive == "object" {
                return stem.parse().ok();
            }
            digits(seq, 2).then_some(())?;
            format!("{seq}_{stem}").parse().ok()
        }
        _ => None,
    }
}

fn walk(dir: &Path, out: &mut Vec<PathBuf>) -> Result<()> {
    for p in crate::fs::sorted_dir(dir)? {
        if p.is_dir() {
            walk(&p, out)?;
        } else {
            out.push(p);
        }
    }
    Ok(())
}

impl Predictions {
    /// The frames that have a prediction, sorted.
    pub fn frame_ids(&self) -> Vec<&FrameId> {
        let mut v: Vec<&FrameId> = self.files.keys().chain(self.in_shard.keys()).collect();
        v.sort();
        v
    }

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
        let mcaps: Vec<PathBuf> = paths
            .iter()
            .filter(|p| p.extension().is_some_and(|e| e == "mcap"))
            .cloned()
            .collect();
        let found = FileIndex::of(paths)?;
        let mixed = |message: String| Error::Input {
            path: root.into(),
            message: format!("mixed formats: {message}"),
        };
        if let (Some(a), Some(b)) = (&found.npy, &found.label) {
            let (a, b) = (a.display(), b.display());
            return Err(mixed(format!(".npy maps ({a}) and .label files ({b})")));
        }
        if let (Some(a), Some(b)) = (found.npy.as_ref().or(found.label.as_ref()), mcaps.first()) {
            let (a, b) = (a.display(), b.display());
            return Err(mixed(format!("prediction files ({a}) and shards ({b})")));
        }
        let (shards, in_shard) = index_shards(&mcaps)?;
        if found.files.is_empty() && in_shard.is_empty() {
            let named = found
                .unrecognised
                .map(|p| format!("; {} is not named as one", p.display()))
                .unwrap_or_default();
            return Err(Error::Input {
                path: root.into(),
                message: format!(
                    "no prediction found{named}. Expected: map predictions <frame id>.npy \
                     (2011_09_26_0001_0000000000.npy, 00_000000.npy), per-point \
                     <drive>/<frame>.label (2011_09_26_drive_0001_sync/0000000000.label), \
                     SemanticKITTI's sequences/<NN>/predictions/<frame6>.label, or prediction \
                     shards (.mcap)"
                ),
            });
        }
        Ok(Predictions {
            root: root.into(),
            files: found.files,
            kind: if found.label.is_some() {
                PredictionKind::Points
            } else if found.npy.is_some() {
                PredictionKind::Maps
            } else {
                PredictionKind::Shards
            },
            shards,
            in_shard,
        })
    }
}

/// The prediction files found, by frame id, with the first of each kind (to name them).
struct FileIndex {
    files: BTreeMap<FrameId, PathBuf>,
    npy: Option<PathBuf>,
    label: Option<PathBuf>,
    /// A `.npy` or `.label` file whose name is no frame id.
    unrecognised: Option<PathBuf>,
}

impl FileIndex {
    /// Indexes `paths` (sorted) by frame id; a frame twice is an error naming both files.
    fn of(paths: Vec<PathBuf>) -> Result<FileIndex> {
        let mut out = FileIndex {
            files: BTreeMap::new(),
            npy: None,
            label: None,
            unrecognised: None,
        };
        for p in paths {
            let Some(id) = frame_id_of(&p) else {
                if p.extension().is_some_and(|e| e == "npy" || e == "label") {
                    out.unrecognised.get_or_insert(p);
                }
                continue;
            };
            if p.extension().is_some_and(|e| e == "npy") {
                out.npy.get_or_insert(p.clone());
            } else {
                out.label.get_or_insert(p.clone());
            }
            if let Some(prev) = out.files.insert(id.clone(), p.clone()) {
                return Err(Error::DuplicatePrediction {
                    path: p,
                    frame: id.to_string(),
                    first: prev,
                });
            }
        }
        Ok(out)
    }
}

/// The prediction shards, verified, and the (shard, chunk) of each frame; a frame twice is an
/// error.
type ShardIndex = (
    Vec<(Shard, mcap::read::Summary)>,
    BTreeMap<FrameId, (usize, usize)>,
);

fn index_shards(mcaps: &[PathBuf]) -> Result<ShardIndex> {
    let mut shards = Vec::new();
    let mut in_shard = BTreeMap::new();
    for p in mcaps {
        let shard = Shard::open_verified(p)?;
        let summary = shard.summary()?;
        for chunk in 0..summary.chunk_indexes.len() {
            for f in shard.chunk_frames(&summary, chunk)? {
                let f = f?;
                let id: FrameId = f.id.parse().map_err(|e: NotAFrameId| e.in_file(p))?;
                if let Some((k, _)) = in_shard.insert(id.clone(), (shards.len(), chunk)) {
                    return Err(Error::DuplicatePrediction {
                        path: p.clone(),
                        frame: id.to_string(),
                        first: mcaps[k].clone(),
                    });
                }
            }
        }
        shards.push((shard, summary));
    }
    Ok((shards, in_shard))
}

impl Predictions {
    /// The file (or shard) holding frame `id`'s prediction; the folder when there is none.
    pub fn path_of(&self, id: &FrameId) -> &Path {
        match (self.files.get(id), self.in_shard.get(id)) {
            (Some(p), _) => p,
            (None, Some(&(k, _))) => &self.shards[k].0.path,
            (None, None) => &self.root,
        }
    }

    /// Whether frame `id` has a prediction.
    pub fn has(&self, id: &FrameId) -> bool {
        self.files.contains_key(id) || self.in_shard.contains_key(id)
    }

    /// The predicted class of each cell of frame `id` (a map file or a prediction shard),
    /// checked against the `rows x cols` map of `map`'s classes; `None` without a prediction.
    /// An error for per-point (`.label`) predictions.
    pub fn cell_labels(
        &self,
        id: &FrameId,
        shape: (usize, usize),
        map: &ClassMap,
    ) -> Result<Option<Vec<ClassId>>> {
        if self.kind == PredictionKind::Points {
            return Err(Error::Input {
                path: self.root.clone(),
                message: "these predictions are per point already (.label files), not maps".into(),
            });
        }
        match (self.files.get(id), self.in_shard.get(id)) {
            (Some(p), _) => Ok(Some(read_cell_prediction(p, shape, map)?.labels)),
            (None, Some(&(k, chunk))) => self.shard_prediction(k, chunk, id, shape, map).map(Some),
            (None, None) => Ok(None),
        }
    }

    /// The label map of frame `id` from prediction shard `k`, chunk `chunk`, checked.
    pub(super) fn shard_prediction(
        &self,
        k: usize,
        chunk: usize,
        id: &FrameId,
        (rows, cols): (usize, usize),
        map: &ClassMap,
    ) -> Result<Vec<u8>> {
        let (shard, summary) = &self.shards[k];
        let want = id.to_string();
        for f in shard.chunk_frames(summary, chunk)? {
            let f = f?;
            if f.id != want {
                continue;
            }
            if (f.height as usize, f.width as usize) != (rows, cols) || f.label.len() != rows * cols
            {
                return Err(Error::Shape {
                    path: shard.path.clone(),
                    what: format!("the prediction for {id} ({} labels)", f.label.len()),
                    found: vec![f.height as usize, f.width as usize],
                    expected: format!("{rows}x{cols}, as the ground truth"),
                });
            }
            for (i, v) in f.label.iter().enumerate() {
                map.check(*v as u64, &shard.path, || {
                    format!("prediction for {id}: cell ({}, {})", i / cols, i % cols)
                })?;
            }
            return Ok(f.label);
        }
        Err(Error::Corrupt {
            path: shard.path.clone(),
            what: format!("the prediction for {id} vanished from its chunk"),
        })
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
fn class_of(v: f64, map: &ClassMap, path: &Path, what: impl Fn() -> String) -> Result<u8> {
    if v.is_nan() {
        return Err(Error::NotFinite {
            path: path.into(),
            what: what(),
            value: v,
        });
    }
    // Range first, then integrality by a round trip (`fract` is a libm call).
    if !(0.0..map.len() as f64).contains(&v) || (v as u8) as f64 != v {
        return Err(Error::NotAClass {
            path: path.into(),
            what: what(),
            value: v,
            map: map.name.clone(),
            max: map.len() - 1,
            hint: None,
        });
    }
    Ok(v as u8)
}

/// Reads a `.npy` prediction for an `rows x cols` map of the classes of `map`.
pub fn read_cell_prediction(
    path: &Path,
    (rows, cols): (usize, usize),
    map: &ClassMap,
) -> Result<CellPrediction> {
    const K_NPY: [usize; 2] = [6, 9];
    let k = map.len();
    let NpyArray { shape, data, dtype } = read_any(path)?;
    let cells = rows * cols;
    let dims: Vec<usize> = shape.iter().map(|&d| d as usize).collect();
    let (format, depth) = match dims.as_slice() {
        [h, w] if *h == rows && *w == cols => (PredFormat::LabelMap, 1),
        [h, w, 1] if *h == rows && *w == cols => (PredFormat::LabelMap, 1),
        [h, w, c] if *h == rows && *w == cols && *c == k => (PredFormat::ScoreMap, k),
        [h, w, c] if *h == rows && *w == cols && K_NPY.contains(c) => (PredFormat::SqueezeSeg, *c),
        other => {
            return Err(Error::Shape {
                path: path.into(),
                what: format!("the prediction ({dtype})"),
                found: other.to_vec(),
                expected: format!("{rows}x{cols} labels, {rows}x{cols}x{k} scores or {rows}x{cols}x6/9 SqueezeSeg maps, as the ground truth"),
            })
        }
    };
    let mut labels = Vec::with_capacity(cells);
    for i in 0..cells {
        let cell = &data[i * depth..(i + 1) * depth];
        let what = || format!("cell ({}, {})", i / cols, i % cols);
        let l = match format {
            PredFormat::LabelMap => class_of(cell[0], map, path, what)?,
            PredFormat::SqueezeSeg => {
                let label = Channels::npy_of_depth(depth)
                    .and_then(|c| c.index(Channel::Label))
                    .expect("an .npy layout");
                class_of(cell[label], map, path, what)?
            }
            PredFormat::ScoreMap => {
                if let Some(k) = cell.iter().position(|v| v.is_nan()) {
                    return Err(Error::NotFinite {
                        path: path.into(),
                        what: format!("{}: the score of class {k}", what()),
                        value: cell[k],
                    });
                }
                // First maximum: ties go to the lower class id.
                let mut best = 0;
                for c in 1..k {
                    if cell[c] > cell[best] {
                        best = c;
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
