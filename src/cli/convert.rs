//! The arguments of `convert` and `split`.

use std::path::PathBuf;

use clap::{Args as ClapArgs, ValueEnum};
use kitti2pgm::project::camera::Sampling;
use kitti2pgm::project::{MapPreset, RowMode};
use kitti2pgm::provenance::ShardCompression;
use kitti2pgm::sensor::presets::Sensor;
use kitti2pgm::sensor::{RingOrder, SensorParams, SensorPose};
use kitti2pgm::source::kitti::DatasetKind;

/// `kitti2pgm split`.
#[derive(Debug, ClapArgs)]
pub struct SplitArgs {
    /// The input, as for convert: a KITTI raw, SemanticKITTI or KITTI object root (or one
    /// drive, sequence or split folder).
    #[arg(value_name = "ROOT")]
    pub raw_root: PathBuf,
    /// Force the kind of dataset instead of detecting it (`--source`, its older name, is
    /// still taken).
    #[arg(long, value_enum, alias = "source")]
    pub dataset: Option<DatasetKind>,
    /// Output folder: the lists go to DIR/ImageSet/.
    #[arg(long, short, value_name = "DIR")]
    pub out: PathBuf,
    /// Which drives go to val.
    #[command(flatten)]
    pub split: SplitRuleArgs,
    /// List every scan, not only those with a tracklet pose.
    #[arg(long)]
    pub all_frames: bool,
    /// Print the counts as JSON.
    #[arg(long)]
    pub json: bool,
}

/// `kitti2pgm convert`.
#[derive(Debug, ClapArgs)]
pub struct ConvertArgs {
    /// The input: a KITTI raw root, date or drive folder; a SemanticKITTI / odometry root
    /// (sequences/<NN>/) or one sequence folder; a KITTI object root (training/, testing/) or
    /// one split folder; another LiDAR's sequence folders (.pcd, .pcd.bin, .bin with
    /// --fields; a ROS 2 bag or a nuScenes root after `kitti2pgm unpack`). The layout is
    /// detected (see --dataset).
    #[arg(value_name = "ROOT")]
    pub raw_root: PathBuf,
    /// Force the kind of dataset instead of detecting it (`--source`, its older name, is
    /// still taken).
    #[arg(long, value_enum, alias = "source")]
    pub dataset: Option<DatasetKind>,
    /// Class map: a built-in one by the name outputs record (kitti-paper-4: background, car,
    /// pedestrian, cyclist; semantic-kitti: SemanticKITTI's 20 classes; nuscenes: the
    /// nuScenes-lidarseg benchmark's 16 classes and ignore), or a
    /// semantic-kitti.yaml-style file (labels, color_map, learning_map, learning_map_inv,
    /// learning_ignore). Default: semantic-kitti for sequences, kitti-paper-4 for boxes.
    #[arg(long, value_name = "NAME|FILE")]
    pub class_map: Option<PathBuf>,
    /// Output folder (created if needed).
    #[arg(long, short, value_name = "DIR")]
    pub out: PathBuf,
    /// Add r, g, b channels sampled from the camera image (64x512x9 output).
    #[arg(long)]
    pub rgb: bool,
    /// Colour camera for --rgb: 2 (left) or 3 (right).
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u8).range(2..=3))]
    pub camera: u8,
    /// Colour sampling for --rgb.
    #[arg(long, value_enum, default_value_t = Sampling::Nearest)]
    pub rgb_sampling: Sampling,
    /// Convert every scan, not only SqueezeSeg's (scans with at least one tracklet pose).
    #[arg(long)]
    pub all_frames: bool,
    /// Map layout. Default: full for SemanticKITTI, squeezeseg for KITTI raw and the object
    /// set. The options below override single values of it; the summary says which map was made.
    #[arg(long, value_name = "NAME", value_enum)]
    pub preset: Option<MapPreset>,
    /// Rows of the map (preset: 64).
    #[arg(long)]
    pub rows: Option<usize>,
    /// Columns of the map (preset: 512 for squeezeseg, 2048 for rangenet and full).
    #[arg(long)]
    pub cols: Option<usize>,
    /// Horizontal field of view in degrees, centred on the x axis (360 for a full map; preset:
    /// 90 for squeezeseg, 360 for rangenet and full).
    #[arg(long)]
    pub fov_deg: Option<f64>,
    /// Top of the elevation range for elevation binning, degrees (preset: 2.0; 3.0 for rangenet).
    #[arg(long, allow_negative_numbers = true)]
    pub fov_up_deg: Option<f64>,
    /// Bottom of the elevation range for elevation binning, degrees (preset: -24.9; -25.0 for
    /// rangenet).
    #[arg(long, allow_negative_numbers = true)]
    pub fov_down_deg: Option<f64>,
    /// How rows are assigned (preset: rings; elevation for rangenet).
    #[arg(long, value_enum)]
    pub row_mode: Option<RowMode>,
    /// The sensor (another LiDAR than KITTI's).
    #[command(flatten)]
    pub sensor: SensorArgs,
    /// Ouster's own columns (measurement id, destaggered) instead of azimuth bins: the map is
    /// the image Ouster's tools show (the SDK's destaggered fields), pixel for pixel. Needs
    /// --sensor-calibration with the unit's metadata .json; the map is then its columns per
    /// frame over 360 degrees.
    #[arg(long)]
    pub ouster_columns: bool,
    /// Do not write the per-point .label files.
    #[arg(long)]
    pub no_point_labels: bool,
    /// Flush each output file to the device before renaming it into place. Files are always
    /// written atomically (never half-written); this also makes them survive a power cut.
    #[arg(long)]
    pub sync: bool,
    /// Convert every frame again. Without it, a re-run into the same folder with the same
    /// parameters keeps the frames (and shards) an earlier run finished and converts the rest.
    #[arg(long)]
    pub overwrite: bool,
    /// Outputs: npy (lidar_2d/*.npy and the per-point labels/), mcap
    /// (shards/<split>-<NNNNN>.mcap), points (points/<split>-<NNNNN>.mcap), labels (labels/
    /// alone); several comma separated (`--format npy,mcap`).
    #[arg(long, value_enum, value_delimiter = ',', default_value = "npy")]
    pub format: Vec<FormatArg>,
    /// Frames per shard (default: about 256 MB of uncompressed data per shard).
    #[arg(long, value_name = "N")]
    pub shard_frames: Option<usize>,
    /// Chunk compression of the shards.
    #[arg(long, value_enum, default_value_t = ShardCompression::Lz4)]
    pub compression: ShardCompression,
    /// Add Foxglove topics to the shards: the labelled point cloud, the tracklet boxes, the image.
    #[arg(long)]
    pub viz: bool,
    /// How shards are split into train and val (the same rule as `kitti2pgm split`).
    #[command(flatten)]
    pub split: SplitRuleArgs,
    /// Print the summary as JSON on stdout instead of a table.
    #[arg(long)]
    pub json: bool,
}

/// Output formats of `convert`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum FormatArg {
    /// SqueezeSeg .npy maps and per-point .label files.
    Npy,
    /// MCAP training shards of the maps (OUT/shards).
    Mcap,
    /// Per-point .label files alone (OUT/labels/; written with npy anyway): for point-wise
    /// scoring and statistics beside shards (`--format mcap,labels`).
    Labels,
    /// MCAP point shards: each scan's points with ring, label, instance (and r, g, b with
    /// --rgb), unprojected, for projection with 3D augmentation while training (OUT/points).
    Points,
}

/// The val rule, shared by `split` and `convert --format mcap`. Default: SqueezeSeg's val drives
/// (KITTI raw), the dataset's own split (SemanticKITTI: sequence 08 is val), a seeded
/// half-and-half frame split (KITTI object).
#[derive(Debug, ClapArgs)]
pub struct SplitRuleArgs {
    /// Val drives instead of SqueezeSeg's: NNNN (of 2011_09_26), <date>_NNNN or
    /// <date>_drive_NNNN_sync, comma separated or repeated.
    #[arg(long, value_name = "DRIVES", conflicts_with_all = ["random_val", "val_sequences", "val_list"])]
    pub val_drives: Vec<String>,
    /// Val sequences (SemanticKITTI / odometry), comma separated or repeated.
    #[arg(long, value_name = "NN", value_delimiter = ',', conflicts_with_all = ["random_val", "val_list"])]
    pub val_sequences: Vec<u32>,
    /// An ImageSet list of the val frames (one frame id a line), e.g. the KITTI object set's
    /// usual val.txt.
    #[arg(long, value_name = "FILE", conflicts_with = "random_val")]
    pub val_list: Option<PathBuf>,
    /// A seeded random split, disjoint by drive (by frame for the object set), with about this
    /// share of the frames in val.
    #[arg(long, value_name = "FRACTION")]
    pub random_val: Option<f64>,
    /// Seed of --random-val.
    #[arg(long, default_value_t = 0, requires = "random_val")]
    pub seed: u64,
}

impl SplitRuleArgs {
    /// The library's rule; `None` when none is given (the layout's default applies).
    pub fn rule(&self) -> kitti2pgm::Result<Option<kitti2pgm::plan::split::SplitRule>> {
        use kitti2pgm::plan::split::SplitRule;
        if let Some(fraction) = self.random_val {
            return Ok(Some(SplitRule::Random {
                fraction,
                seed: self.seed,
            }));
        }
        if !self.val_drives.is_empty() {
            return SplitRule::parse_drives(&self.val_drives).map(Some);
        }
        if !self.val_sequences.is_empty() {
            return Ok(Some(SplitRule::Sequences(
                self.val_sequences.iter().copied().collect(),
            )));
        }
        if let Some(list) = &self.val_list {
            let ids = kitti2pgm::format::imageset::read(list)?;
            return Ok(Some(SplitRule::Frames(ids.into_iter().collect())));
        }
        Ok(None)
    }
}

/// The sensor options of `convert` and `check`: another sensor's scans get one row per beam.
#[derive(Debug, Clone, ClapArgs)]
pub struct SensorArgs {
    /// Another sensor's scans (a sequence of .pcd files, or of KITTI-layout .bin): the rows are
    /// this sensor's beams, by its built-in nominal beam table. The map gets one row per beam
    /// unless --rows says otherwise; a ring / channel field in the scans decides first.
    #[arg(
        long,
        value_name = "NAME",
        value_enum,
        conflicts_with = "sensor_calibration"
    )]
    pub sensor: Option<Sensor>,
    /// Like --sensor, with a unit's own calibration file: velodyne_pointcloud .yaml, Hesai
    /// angle-correction .csv, or Ouster metadata .json (beam origin and sensor frame included).
    #[arg(long, value_name = "FILE")]
    pub sensor_calibration: Option<std::path::PathBuf>,
    /// How a ring / channel field counts the beams (with --sensor or --sensor-calibration).
    #[arg(long, value_enum, default_value_t = RingOrder::BottomUp)]
    pub ring_order: RingOrder,
    /// Where the sensor sits in the frame the points are written in, X,Y,Z[,ROLL,PITCH,YAW]
    /// (metres, degrees; ROS's roll-pitch-yaw): for clouds moved to a vehicle frame (a ROS
    /// bag's base_link). The points are moved into the sensor's frame when read, so rows,
    /// columns and the x, y, z channels are the sensor's; points then beyond 500 m are dropped.
    /// A mounting is at most 100 m from the points' origin.
    #[arg(long, value_name = "X,Y,Z[,R,P,Y]", allow_hyphen_values = true)]
    pub sensor_pose: Option<String>,
    /// The point layout of the scans' flat .bin files (with --sensor or --sensor-calibration):
    /// comma-separated names, each with an optional :type (i8 u8 i16 u16 i32 u32 i64 u64 f32
    /// f64; a field without one takes the next given type, the last ones f32; `_` is padding),
    /// e.g. x,y,z,intensity,ring:f32 or x,y,z:f32,intensity:u8,_:u8,ring:u16. x, y, z are
    /// required; the intensity and ring fields are found by name. Default: KITTI's x, y, z,
    /// reflectance (nuScenes' five floats for .pcd.bin).
    #[arg(long, value_name = "FIELDS")]
    pub fields: Option<String>,
}

impl SensorArgs {
    /// The sensor parameters asked for (a calibration file is read now), if any.
    pub fn params(&self) -> kitti2pgm::Result<Option<SensorParams>> {
        let mut p = match (&self.sensor, &self.sensor_calibration) {
            (Some(s), _) => SensorParams::preset(*s, self.ring_order),
            (None, Some(path)) => SensorParams::file(path, self.ring_order)?,
            (None, None) if self.sensor_pose.is_some() || self.fields.is_some() => {
                let what = if self.fields.is_some() {
                    "--fields"
                } else {
                    "--sensor-pose"
                };
                return Err(kitti2pgm::Error::Config(format!(
                    "{what} needs the sensor: --sensor or --sensor-calibration"
                )));
            }
            (None, None) => return Ok(None),
        };
        p.pose = self
            .sensor_pose
            .as_deref()
            .map(SensorPose::parse)
            .transpose()?;
        if let Some(spec) = &self.fields {
            p = p.with_fields(spec)?;
        }
        Ok(Some(p))
    }
}
