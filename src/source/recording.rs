//! Recordings that are read through a sequence folder: what a path is, when `convert` cannot
//! read it as it is ([`Recording::of`]), each format deciding by its own test ([`bag::is_bag`],
//! [`nuscenes::is_root`]). The binary turns the answer into the command that unpacks it.

use std::fmt;
use std::path::Path;

use super::{bag, nuscenes, pointcloud2};

/// A recording to unpack into a sequence folder before `convert` reads it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Recording {
    /// A ROS 2 bag (MCAP storage), with its `PointCloud2` topics (empty when they could not be
    /// read).
    Ros2Bag {
        /// Its point cloud topics.
        clouds: Vec<String>,
    },
    /// A ROS 1 bag (`.bag`): to convert to an MCAP ROS 2 bag first.
    Ros1Bag,
    /// A rosbag2 sqlite3 file (`.db3`): to convert to MCAP storage first.
    Sqlite3Bag,
    /// A nuScenes root (`DATAROOT` with its `v1.0-*` tables).
    NuScenes,
}

impl Recording {
    /// What `path` is, when it is a recording to unpack; `None` otherwise.
    pub fn of(path: &Path) -> Option<Recording> {
        if bag::is_bag(path) {
            // Its point cloud topics, when they can be read.
            let clouds = (bag::Bag::open(path).and_then(|b| b.topics()))
                .unwrap_or_default()
                .into_iter()
                .filter(|t| t.type_name == pointcloud2::TYPE_NAME)
                .map(|t| t.name)
                .collect();
            return Some(Recording::Ros2Bag { clouds });
        }
        match bag::foreign_storage(path) {
            Some(bag::Foreign::Ros1) => return Some(Recording::Ros1Bag),
            Some(bag::Foreign::Sqlite3) => return Some(Recording::Sqlite3Bag),
            None => {}
        }
        nuscenes::is_root(path).then_some(Recording::NuScenes)
    }
}

impl fmt::Display for Recording {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Recording::Ros2Bag { clouds } if clouds.is_empty() => {
                f.write_str("a ROS 2 bag (no point cloud topic found)")
            }
            Recording::Ros2Bag { clouds } => {
                write!(f, "a ROS 2 bag (point cloud topics: {})", clouds.join(", "))
            }
            Recording::Ros1Bag => f.write_str("a ROS 1 bag, which kitti2pgm reads as an MCAP bag"),
            Recording::Sqlite3Bag => {
                f.write_str("a rosbag2 sqlite3 bag, which kitti2pgm reads in MCAP storage")
            }
            Recording::NuScenes => f.write_str("a nuScenes root"),
        }?;
        f.write_str(": a recording to unpack into a sequence folder first")
    }
}
