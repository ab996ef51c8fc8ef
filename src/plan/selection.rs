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
