//! The sequence-folder layout (SemanticKITTI's, KITTI odometry's, point_labeler's), with one
//! owner: discovery reads it, both unpackers write it, and every other sensor's scans live in
//! it: `ROOT/sequences/<NN>/` holding `velodyne/<frame6>.<ext>` (the scans), `labels/<frame6>.label`
//! (per-point labels), `times.txt` (seconds after the first scan) and `calib.txt`.

use std::path::{Path, PathBuf};

/// The folder of the sequences under a root.
pub const SEQUENCES: &str = "sequences";
/// The folder of a sequence's scans.
pub const SCANS: &str = "velodyne";
/// The folder of a sequence's per-point labels.
pub const LABELS: &str = "labels";
/// A sequence's scan times, one line a frame.
pub const TIMES: &str = "times.txt";

/// The folder of sequence `number` under `root` (`ROOT/sequences/07`).
pub fn sequence_dir(root: &Path, number: u32) -> PathBuf {
    root.join(SEQUENCES).join(format!("{number:02}"))
}

/// A frame's file name in a sequence: `<frame6>.<ext>` (`000042.pcd`).
pub fn frame_file(frame: u64, ext: &str) -> String {
    format!("{frame:06}.{ext}")
}
