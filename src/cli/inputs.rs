//! The arguments of the commands over a dataset's inputs: `check`, `submission` and `unpack`.

use std::path::PathBuf;

use clap::Args as ClapArgs;
use kitti2pgm::check::{CheckName, Severity};

/// `kitti2pgm check`.
#[derive(Debug, ClapArgs)]
pub struct CheckArgs {
    /// The dataset root (what `convert` reads), or a folder of raw drive folders holding only
    /// their tracklet_labels.xml.
    #[arg(value_name = "ROOT", required_unless_present = "list")]
    pub root: Option<PathBuf>,
    /// The kind of dataset, when not the one the root shows (`--source`, its older name, is
    /// still taken).
    #[arg(long, value_enum, alias = "source")]
    pub dataset: Option<kitti2pgm::source::kitti::DatasetKind>,
    /// Switch these checks off (comma separated; `--list` names them).
    #[arg(long, value_delimiter = ',', value_name = "CHECK")]
    pub skip: Vec<CheckName>,
    /// Run only these checks (comma separated).
    #[arg(
        long,
        value_delimiter = ',',
        value_name = "CHECK",
        conflicts_with = "skip"
    )]
    pub only: Vec<CheckName>,
    /// Set a threshold, NAME=VALUE (repeatable; `--list` names them with their defaults).
    #[arg(long = "set", value_name = "NAME=VALUE")]
    pub set: Vec<String>,
    /// Annotations, calibration and file lists only: skip the checks that read the scans.
    #[arg(long)]
    pub no_scans: bool,
    /// Another sensor's scans: check their points against its beam model (`beam-model`: points
    /// that fit no beam), and their ring field against its beams.
    #[command(flatten)]
    pub sensor: super::convert::SensorArgs,
    /// Check this ImageSet folder's train.txt and val.txt (leaks, balance) instead of the
    /// layout's default split.
    #[arg(long, value_name = "DIR")]
    pub imageset: Option<PathBuf>,
    /// The class map (a built-in name or a semantic-kitti.yaml-style file) whose ids per-point
    /// labels are checked against (default: the one `kitti2pgm label` recorded beside the
    /// labels, else SemanticKITTI's).
    #[arg(long, value_name = "NAME|YAML")]
    pub class_map: Option<PathBuf>,
    /// Draw a picture of each flagged frame into DIR: a bird's-eye view with the boxes (the
    /// flagged object in red), or the points over the image for the camera checks.
    #[arg(long, value_name = "DIR")]
    pub pictures: Option<PathBuf>,
    /// At most this many pictures per check.
    #[arg(long, default_value_t = 20, value_name = "N")]
    pub max_pictures: usize,
    /// Exit with status 3 when a finding of this severity or worse is found.
    #[arg(long, default_value = "error", value_name = "SEVERITY")]
    pub fail_on: Severity,
    /// List the checks and the thresholds with their values, and exit.
    #[arg(long)]
    pub list: bool,
    /// Print the report as JSON.
    #[arg(long)]
    pub json: bool,
}

/// `kitti2pgm submission`.
#[derive(Debug, ClapArgs)]
pub struct SubmissionArgs {
    /// The prediction folder: PRED/sequences/<NN>/predictions/<frame6>.label.
    #[arg(value_name = "PRED")]
    pub pred: PathBuf,
    /// The SemanticKITTI root whose scans the predictions are of (sequences/<NN>/velodyne/).
    #[arg(long, value_name = "ROOT")]
    pub gt: PathBuf,
    /// The sequences to check (comma separated; the benchmark's test set is 11-21). Default:
    /// every sequence of ROOT.
    #[arg(long, value_name = "NN", value_delimiter = ',')]
    pub sequences: Vec<u32>,
    /// The class map whose learning_map lists the valid raw ids (a name or a
    /// semantic-kitti.yaml-style file).
    #[arg(long, value_name = "NAME|FILE", default_value = "semantic-kitti")]
    pub class_map: PathBuf,
    /// Pack a valid folder into this zip archive, in the benchmark's layout.
    #[arg(long, value_name = "ZIP")]
    pub zip: Option<PathBuf>,
    /// The archive's description.txt: this text, or the contents of this file.
    #[arg(long, value_name = "TEXT|FILE", requires = "zip")]
    pub description: Option<String>,
    /// Print the check as JSON.
    #[arg(long)]
    pub json: bool,
}

/// `kitti2pgm unpack`.
#[derive(Debug, ClapArgs)]
pub struct UnpackArgs {
    /// A ROS 2 bag: its directory (with metadata.yaml; MCAP storage) or one .mcap file. Or a
    /// nuScenes root (DATAROOT with v1.0-*/ tables and samples/LIDAR_TOP): one scene becomes one
    /// sequence (scene-0061 -> sequences/61), each LIDAR_TOP keyframe a frame, with its
    /// nuScenes-lidarseg labels (convert with --class-map nuscenes --sensor hdl32e).
    #[arg(value_name = "BAG|NUSCENES_ROOT")]
    pub bag: PathBuf,
    /// The dataset root to write: ROOT/sequences/<NN>/velodyne/<frame6>.pcd (.pcd.bin for
    /// nuScenes), times.txt and unpack.json (nuscenes.json).
    #[arg(long, value_name = "ROOT", required_unless_present = "list")]
    pub out: Option<PathBuf>,
    /// Replace the scans of an earlier unpack into the same sequence (scans past the new last
    /// frame are removed).
    #[arg(long)]
    pub overwrite: bool,
    /// List the bag's topics (type, serialisation, messages), or a nuScenes root's scenes
    /// (keyframes, labelled keyframes), and stop.
    #[arg(long)]
    pub list: bool,
    /// Flush every file to the device before it is renamed into place.
    #[arg(long)]
    pub sync: bool,
    /// Print JSON instead of a table.
    #[arg(long)]
    pub json: bool,
    /// Options for a ROS 2 bag.
    #[command(flatten)]
    pub from_bag: BagUnpackArgs,
    /// Options for a nuScenes root.
    #[command(flatten)]
    pub from_nuscenes: NuScenesUnpackArgs,
}

/// `kitti2pgm unpack BAG`: what only a bag takes.
#[derive(Debug, ClapArgs)]
#[command(next_help_heading = "ROS 2 bags")]
pub struct BagUnpackArgs {
    /// The sensor_msgs/msg/PointCloud2 topic to unpack (without it, or with a wrong one, the
    /// error lists the bag's point cloud topics).
    #[arg(long, value_name = "TOPIC")]
    pub topic: Option<String>,
    /// The sequence number NN (one bag is one sequence; 00 without it).
    #[arg(long, value_name = "NN", value_parser = clap::value_parser!(u32).range(0..=99))]
    pub sequence: Option<u32>,
    /// The sensor's frame (velodyne, os_sensor...): its pose in the clouds' frame (a base_link)
    /// is found through the bag's /tf_static, recorded in unpack.json and printed as the
    /// --sensor-pose that convert takes.
    #[arg(long, value_name = "FRAME")]
    pub sensor_frame: Option<String>,
}

impl BagUnpackArgs {
    /// The flags given, by name.
    pub fn given(&self) -> Vec<&'static str> {
        let mut out = Vec::new();
        out.extend(self.topic.as_ref().map(|_| "--topic"));
        out.extend(self.sequence.map(|_| "--sequence"));
        out.extend(self.sensor_frame.as_ref().map(|_| "--sensor-frame"));
        out
    }
}

/// `kitti2pgm unpack NUSCENES_ROOT`: what only a nuScenes root takes.
#[derive(Debug, ClapArgs)]
#[command(next_help_heading = "nuScenes roots")]
pub struct NuScenesUnpackArgs {
    /// The version to read (the folder of its tables: v1.0-mini, v1.0-trainval...); without
    /// it, the one the root holds.
    #[arg(long, value_name = "VERSION")]
    pub nuscenes_version: Option<String>,
    /// Only these scenes (scene-0061,scene-0103,...); all without it.
    #[arg(long, value_name = "SCENES", value_delimiter = ',')]
    pub scenes: Vec<String>,
}

impl NuScenesUnpackArgs {
    /// The flags given, by name.
    pub fn given(&self) -> Vec<&'static str> {
        let mut out = Vec::new();
        out.extend(self.nuscenes_version.as_ref().map(|_| "--nuscenes-version"));
        out.extend((!self.scenes.is_empty()).then_some("--scenes"));
        out
    }
}
