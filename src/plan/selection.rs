//! PLAN: which frames of a drive are converted.

use serde::{Deserialize, Serialize};

use crate::kitti::tracklets::Tracklets;

/// Which frames of a drive are converted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum FrameSelection {
    /// SqueezeSeg's selection: frames with a scan and at least one tracklet pose (any type).
    #[default]
    Annotated,
    /// Every frame with a scan.
    All,
}

impl FrameSelection {
    /// Whether a frame that has a velodyne scan is selected, given its drive's tracklets (empty
    /// when the drive has no `tracklet_labels.xml`).
    pub fn keeps(self, tracklets: &Tracklets, frame: u32) -> bool {
        self == FrameSelection::All || tracklets.count_at(frame) > 0
    }
}

/// Why frames were not converted by a run (the summary's `frames_skipped` keys: the serde
/// names, in their alphabetical order, so that the JSON reads as before the enum).
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, serde::Serialize, serde::Deserialize,
)]
pub enum SkipReason {
    /// The journal proves the frame was written with the same parameters (a re-run).
    #[serde(rename = "already converted by an earlier run with the same parameters")]
    Kept,
    /// The frame's shard is complete and intact (a re-run).
    #[serde(rename = "already in a complete, intact shard")]
    InIntactShard,
    /// A tracklet pose names a frame whose scan is missing.
    #[serde(rename = "annotated frame without a velodyne scan")]
    AnnotatedWithoutScan,
    /// The drive has no tracklets (annotated frames only).
    #[serde(rename = "drive has no tracklet_labels.xml")]
    NoTrackletFile,
    /// No tracklet pose at the frame (annotated frames only).
    #[serde(rename = "no tracklet pose at the frame")]
    NoPose,
}

impl SkipReason {
    /// The reason in words (its JSON key).
    pub fn as_str(self) -> &'static str {
        match self {
            SkipReason::Kept => "already converted by an earlier run with the same parameters",
            SkipReason::InIntactShard => "already in a complete, intact shard",
            SkipReason::AnnotatedWithoutScan => "annotated frame without a velodyne scan",
            SkipReason::NoTrackletFile => "drive has no tracklet_labels.xml",
            SkipReason::NoPose => "no tracklet pose at the frame",
        }
    }
}

impl std::fmt::Display for SkipReason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// Why a frame an earlier run with the same parameters finished was converted again (the
/// summary's `reconverted` keys).
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, serde::Serialize, serde::Deserialize,
)]
pub enum Reconverted {
    /// A file it was made from changed, appeared or went (scan, labels, tracklets,
    /// calibration, image): the summary's `changed_inputs` names them.
    #[serde(rename = "input changed")]
    InputChanged,
    /// One of its output files is missing or of the wrong size.
    #[serde(rename = "output missing or damaged")]
    OutputMissing,
}

/// Why a run removed every converted output of its folder before converting (the summary's
/// `restarted`), instead of continuing the earlier run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Restart {
    /// The earlier run had other parameters.
    #[serde(rename = "parameters changed")]
    Parameters,
    /// The earlier run converted another dataset root.
    #[serde(rename = "dataset root changed")]
    Root,
    /// The earlier run's journal records no inputs (an older version): nothing can be proved.
    #[serde(rename = "journal without inputs (older version)")]
    OldJournal,
    /// Asked for (`--overwrite`).
    #[serde(rename = "overwrite asked")]
    Overwrite,
}

impl std::fmt::Display for Reconverted {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Reconverted::InputChanged => "input changed",
            Reconverted::OutputMissing => "output missing or damaged",
        })
    }
}

impl std::fmt::Display for Restart {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Restart::Parameters => "parameters changed",
            Restart::Root => "dataset root changed",
            Restart::OldJournal => "journal without inputs (older version)",
            Restart::Overwrite => "overwrite asked",
        })
    }
}
