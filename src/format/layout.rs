//! The output folder of `convert`, the one place its paths are spelled:
//!
//! ```text
//! OUT/lidar_2d/<date>_<drive4>_<frame10>.npy          one map per frame (format::pgm)
//! OUT/labels/<drive>/<frame>.label                   per-point labels (format::label_file);
//!     <drive> = <date>_drive_<NNNN>_sync (raw), <NN> (sequences) or object
//! OUT/shards/<split>-<NNNNN>.mcap                     training shards (format::shard)
//! OUT/points/<split>-<NNNNN>.mcap                     point shards (format::shard::points)
//! OUT/convert_summary.json                            what was converted, how (format::summary)
//! OUT/ImageSet/{all,train,val}.txt                    split lists (format::imageset)
//! ```
//!
//! [`OutputDir`] also finds what a folder holds: its converted frames and its shards. A bare
//! `lidar_2d` folder (SqueezeSeg's published data) is read through [`list_npy_frames`].

use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::source::kitti::FrameId;

/// Folder of the `.npy` maps.
pub const LIDAR_2D: &str = "lidar_2d";
/// Folder of the `.label` files.
pub const LABELS: &str = "labels";
/// Folder of the shards.
pub const SHARDS: &str = "shards";
/// Folder of the point shards.
pub const POINTS: &str = "points";
/// Folder of the split lists.
pub const IMAGESET: &str = "ImageSet";
/// The conversion summary.
pub const SUMMARY_FILE: &str = "convert_summary.json";

/// A `convert` output folder.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct OutputDir {
    /// The folder.
    pub root: PathBuf,
}

impl OutputDir {
    /// The output folder at `root`.
    pub fn new(root: impl Into<PathBuf>) -> OutputDir {
        OutputDir { root: root.into() }
    }

    /// `OUT/lidar_2d`.
    pub fn lidar_dir(&self) -> PathBuf {
        self.root.join(LIDAR_2D)
    }

    /// `OUT/labels/<drive>` of a frame's drive.
    pub fn label_dir(&self, id: &FrameId) -> PathBuf {
        self.root.join(LABELS).join(id.drive_name())
    }

    /// `OUT/lidar_2d/<frame id>.npy`.
    pub fn npy_path(&self, id: &FrameId) -> PathBuf {
        npy_path_in(&self.lidar_dir(), id)
    }

    /// `OUT/labels/<date>_drive_<NNNN>_sync/<frame10>.label`.
    pub fn label_path(&self, id: &FrameId) -> PathBuf {
        self.label_dir(id)
            .join(format!("{}.label", id.frame_name()))
    }

    /// `OUT/shards`.
    pub fn shards_dir(&self) -> PathBuf {
        self.root.join(SHARDS)
    }

    /// `OUT/points`.
    pub fn points_dir(&self) -> PathBuf {
        self.root.join(POINTS)
    }

    /// `OUT/points/<split>-<NNNNN>.mcap`.
    pub fn points_path(&self, split: &str, index: usize) -> PathBuf {
        self.points_dir().join(shard_name(split, index))
    }

    /// `OUT/shards/<split>-<NNNNN>.mcap`.
    pub fn shard_path(&self, split: &str, index: usize) -> PathBuf {
        self.shards_dir().join(shard_name(split, index))
    }

    /// `OUT/convert_summary.json`.
    pub fn summary_path(&self) -> PathBuf {
        self.root.join(SUMMARY_FILE)
    }

    /// `OUT/ImageSet`.
    pub fn imageset_dir(&self) -> PathBuf {
        self.root.join(IMAGESET)
    }

    /// Whether the folder holds `.npy` maps.
    pub fn has_maps(&self) -> bool {
        self.lidar_dir().is_dir()
    }

    /// Whether the folder holds `.label` files.
    pub fn has_labels(&self) -> bool {
        self.root.join(LABELS).is_dir()
    }

    /// The converted frames (`lidar_2d/*.npy` named by a frame id), sorted.
    pub fn converted_frames(&self) -> Result<Vec<FrameId>> {
        Ok(list_npy_frames(&self.lidar_dir())?
            .into_iter()
            .map(|(id, _)| id)
            .collect())
    }

    /// The shards under `OUT/shards` (or `OUT` itself when it holds `.mcap` files), sorted.
    pub fn shards(&self) -> Result<Vec<PathBuf>> {
        for dir in [self.shards_dir(), self.root.clone()] {
            if dir.is_dir() {
                let v = list_shards(&dir)?;
                if !v.is_empty() {
                    return Ok(v);
                }
            }
        }
        Ok(Vec::new())
    }
}

/// The folder of SemanticKITTI's per-point predictions of sequence `seq` (two digits), in the
/// benchmark's layout: `PRED/sequences/<NN>/predictions`.
pub fn sequence_predictions_dir(pred: &Path, seq: &str) -> PathBuf {
    pred.join("sequences").join(seq).join("predictions")
}

/// The file of a frame's per-point predictions under `out`: the benchmark's
/// `sequences/<NN>/predictions/<frame6>.label` for SemanticKITTI, else the convert folder's
/// `labels/<drive>/<frame>.label`.
pub fn point_prediction_path(out: &Path, id: &FrameId) -> PathBuf {
    match id.dataset {
        crate::source::kitti::DatasetKind::Sequence => {
            sequence_predictions_dir(out, &id.drive_name())
                .join(format!("{}.label", id.frame_name()))
        }
        _ => OutputDir::new(out).label_path(id),
    }
}

/// `<dir>/<frame id>.npy`.
pub fn npy_path_in(dir: &Path, id: &FrameId) -> PathBuf {
    dir.join(format!("{id}.npy"))
}

/// The name of shard `index` of a split: `<split>-<NNNNN>.mcap`.
pub fn shard_name(split: &str, index: usize) -> String {
    format!("{split}-{index:05}.mcap")
}

/// The `.mcap` files of a folder, sorted; hidden files (an unfinished shard's `.tmp-*.mcap`)
/// are not shards.
pub fn list_shards(dir: &Path) -> Result<Vec<PathBuf>> {
    let hidden = |p: &Path| {
        p.file_name()
            .and_then(|n| n.to_str())
            .is_none_or(|n| n.starts_with('.'))
    };
    Ok(crate::fs::sorted_dir(dir)?
        .into_iter()
        .filter(|p| p.extension().is_some_and(|e| e == "mcap") && !hidden(p) && p.is_file())
        .collect())
}

/// The `<frame id>.npy` files of a folder (other files are ignored), sorted by frame id; an
/// error when there is none.
pub fn list_npy_frames(dir: &Path) -> Result<Vec<(FrameId, PathBuf)>> {
    let mut ids: Vec<(FrameId, PathBuf)> = crate::fs::sorted_dir(dir)?
        .into_iter()
        .filter(|p| p.extension().is_some_and(|x| x == "npy"))
        .filter_map(|p| {
            let id = p.file_stem()?.to_str()?.parse::<FrameId>().ok()?;
            Some((id, p))
        })
        .collect();
    if ids.is_empty() {
        return Err(Error::Input {
            path: dir.into(),
            message: "no converted frame (<date>_<drive4>_<frame10>.npy) here".into(),
        });
    }
    ids.sort();
    Ok(ids)
}
