//! PLAN: which frames of a drive are converted.

use serde::{Deserialize, Serialize};

use crate::source::boxes::BoxSource;

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
    /// Whether a frame that has a scan is selected, given its drive's boxes (none when the
    /// drive has no `tracklet_labels.xml`).
    pub fn keeps(self, boxes: &dyn BoxSource, frame: u32) -> bool {
        self == FrameSelection::All || boxes.count_at(frame) > 0
    }
}

/// Why frames were not converted by a run (the summary's `frames_skipped` keys: the names, in
/// their alphabetical order, so that the JSON reads as before the enum).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum SkipReason {
    /// The journal proves the frame was written with the same parameters (a re-run).
    Kept,
    /// The frame's shard is complete and intact (a re-run).
    InIntactShard,
    /// A tracklet pose names a frame whose scan is missing.
    AnnotatedWithoutScan,
    /// The drive has no tracklets (annotated frames only).
    NoTrackletFile,
    /// No tracklet pose at the frame (annotated frames only).
    NoPose,
}

crate::named_enum!(SkipReason, "skip reason", [
    Kept => "already converted by an earlier run with the same parameters" []
        "the journal proves the frame was written with the same parameters",
    InIntactShard => "already in a complete, intact shard" []
        "the frame's shard is complete and intact",
    AnnotatedWithoutScan => "annotated frame without a velodyne scan" []
        "a tracklet pose names a frame whose scan is missing",
    NoTrackletFile => "drive has no tracklet_labels.xml" []
        "the drive has no tracklets (annotated frames only)",
    NoPose => "no tracklet pose at the frame" []
        "no tracklet pose at the frame (annotated frames only)",
]);

/// Why a frame an earlier run with the same parameters finished was converted again (the
/// summary's `reconverted` keys).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Reconverted {
    /// A file it was made from changed, appeared or went (scan, labels, tracklets,
    /// calibration, image): the summary's `changed_inputs` names them.
    InputChanged,
    /// One of its output files is missing or of the wrong size.
    OutputMissing,
}

crate::named_enum!(Reconverted, "reason to convert again", [
    InputChanged => "input changed" [] "a file the frame was made from changed, appeared or went",
    OutputMissing => "output missing or damaged" [] "an output file is missing or of the wrong size",
]);

/// Why a run removed every converted output of its folder before converting (the summary's
/// `restarted`), instead of continuing the earlier run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Restart {
    /// The earlier run had other parameters.
    Parameters,
    /// The earlier run converted another dataset root.
    Root,
    /// The earlier run's journal records no inputs (an older version): nothing can be proved.
    OldJournal,
    /// Asked for (`--overwrite`).
    Overwrite,
}

crate::named_enum!(Restart, "reason to start afresh", [
    Parameters => "parameters changed" [] "the earlier run had other parameters",
    Root => "dataset root changed" [] "the earlier run converted another dataset root",
    OldJournal => "journal without inputs (older version)" []
        "the earlier run's journal records no inputs: nothing can be proved",
    Overwrite => "overwrite asked" [] "asked for (--overwrite)",
]);
