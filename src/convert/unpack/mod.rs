//! UNPACK: recordings that `convert` does not read as they are -> sequence folders that every
//! command reads (`ROOT/sequences/NN/`: the scans under `velodyne/`, `times.txt`, and the mark
//! of the unpack: [`crate::source::unpacked`]). [`bag`]: a ROS 2 bag's point cloud topic, one
//! sequence; [`nuscenes`]: a nuScenes root, one sequence a scene.
//!
//! Both follow one path, written here once: the root's lock, an earlier unpack refused unless
//! `overwrite`, the mark written `complete: false` before the first scan and `true` after the
//! last file, a frame that fails named in [`UnpackFailure`] while the rest goes on, the files of
//! an earlier unpack that no frame wrote again removed, and one [`UnpackOutcome`].

pub mod bag;
pub mod nuscenes;

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::format::{atomic_write, create_dir, Durability};

pub use bag::{unpack, UnpackOptions, UnpackSummary};
pub use nuscenes::{unpack_nuscenes, NuScenesOptions, NuScenesSummary};

/// A frame that did not unpack.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct UnpackFailure {
    /// The scene it belongs to (a nuScenes root's; a bag is one sequence).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scene: Option<String>,
    /// The frame (the message's place on the topic; the keyframe's in its scene).
    pub frame: u64,
    /// What was wrong.
    pub error: String,
}

/// How an unpack ended, for every kind of recording.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum UnpackOutcome {
    /// Every frame unpacked.
    Done,
    /// Some frames unpacked, others failed (or a damaged part was passed over).
    Partial,
    /// Frames failed and none unpacked.
    NoneUnpacked,
    /// The recording held no frame to unpack.
    Empty,
}

/// What every unpack summary tells: frames written and what failed.
pub trait UnpackReport {
    /// Frames written.
    fn frames_written(&self) -> u64;
    /// Frames that failed.
    fn failures(&self) -> &[UnpackFailure];
    /// Damaged parts passed over that held no frame (a bag's chunks).
    fn damaged(&self) -> &[String] {
        &[]
    }

    /// How the unpack ended.
    fn outcome(&self) -> UnpackOutcome {
        let clean = self.failures().is_empty() && self.damaged().is_empty();
        match (clean, self.frames_written()) {
            (true, 0) => UnpackOutcome::Empty,
            (true, _) => UnpackOutcome::Done,
            (false, 0) => UnpackOutcome::NoneUnpacked,
            (false, _) => UnpackOutcome::Partial,
        }
    }
}

/// Creates the root `out` and takes its lock (another run writing into it stops), held until
/// the guard drops.
fn begin(out: &Path) -> Result<std::fs::File> {
    create_dir(out)?;
    crate::convert::resume::lock_dir(out)
}

/// Refuses a sequence folder `dir` holding `found` files of an earlier unpack, unless
/// `overwrite`; `instead` says what else the user can do.
fn refuse_earlier(dir: &Path, found: usize, overwrite: bool, instead: &str) -> Result<()> {
    if found == 0 || overwrite {
        return Ok(());
    }
    Err(Error::Input {
        path: dir.into(),
        message: format!("already holds {found} {instead}"),
    })
}

/// Writes a sequence's mark (`unpack.json`, `nuscenes.json`) as `name`.
fn write_mark<T: Serialize>(mark: &T, seq: &Path, name: &str, d: Durability) -> Result<()> {
    let json = serde_json::to_vec_pretty(mark).expect("a mark serialises");
    atomic_write(&seq.join(name), &json, d)
}

/// Writes a sequence's `times.txt`: `stamps_ns` (nanoseconds) after the first.
fn write_times(seq: &Path, stamps_ns: &[i64], d: Durability) -> Result<()> {
    let zero = stamps_ns.first().copied().unwrap_or(0);
    let times = crate::source::kitti::poses::times_text(stamps_ns.iter().map(|t| t - zero));
    atomic_write(
        &seq.join(crate::source::kitti::sequence::TIMES),
        times.as_bytes(),
        d,
    )
}

/// Removes the files of an earlier unpack (`old`) that `keep` does not hold (a file already
/// gone is fine); how many went.
fn remove_stale(old: &[PathBuf], keep: impl Fn(&Path) -> bool) -> Result<u64> {
    let mut removed = 0;
    for f in old.iter().filter(|p| !keep(p)) {
        removed += crate::fs::remove_if_there(f)? as u64;
    }
    Ok(removed)
}
