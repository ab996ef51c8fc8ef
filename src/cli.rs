//! Command-line arguments (clap derive): raw input, validated into library types by
//! `commands::*`.

use std::path::PathBuf;

use clap::{Args as ClapArgs, Parser, Subcommand, ValueEnum};
use kitti2pgm::kitti::Layout;
use kitti2pgm::params::ShardCompression;
use kitti2pgm::project::camera::Sampling;
use kitti2pgm::project::{MapPreset, RowMode};

/// KITTI raw -> labelled Polar Grid Maps for LiDAR(+camera) semantic segmentation
/// (SqueezeSeg / PointSeg training data).
#[derive(Debug, Parser)]
#[command(name = "kitti2pgm", version, about, long_about = None, propagate_version = true)]
pub struct Args {
    /// Worker threads (0 = one per core; 1 = sequential, for debugging; at most 1024).
    #[arg(long, global = true, default_value_t = 0,
          value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(0..=1024))]
    pub threads: usize,
    /// Never draw a progress bar (it is only drawn on a terminal anyway).
    #[arg(long, global = true)]
    pub no_progress: bool,
    /// The task.
    #[command(subcommand)]
    pub command: Command,
}

/// Subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Convert KITTI raw, SemanticKITTI or KITTI object scans to labelled Polar Grid Maps (.npy),
    /// per-point .label files and MCAP shards.
    ///
    /// ROOT is a KITTI raw root (<date>/calib_*.txt and <date>/<date>_drive_NNNN_sync/), date or
    /// drive folder; a SemanticKITTI root (sequences/<NN>/) or sequence; a KITTI object root
    /// (training/) or split folder. Writes DIR/lidar_2d/<frame id>.npy (float32 64x512x6: x, y,
    /// z, intensity, range, label; with --rgb x9 adding r, g, b) and
    /// DIR/labels/<drive>/<frame>.label (u32 per point: class | instance << 16). A re-run with the
    /// same parameters keeps finished frames (--overwrite converts all). Exit status: 0 all
    /// converted, 1 fatal error or every frame failed, 3 some frames failed (reported, others
    /// written).
    Convert(ConvertArgs),
    /// Draw converted frames (.npy files, or every frame of a convert folder, lidar_2d folder or
    /// shards) as PNG: range, intensity, colour and labels stacked.
    Preview(PreviewArgs),
    /// Write the train/val split lists (DIR/ImageSet/{all,train,val}.txt, and test.txt for frames
    /// without labels) from the annotations and the list of velodyne files alone (no point data).
    ///
    /// Default for KITTI raw: SqueezeSeg's split. all = frames with a velodyne scan and at least
    /// one tracklet pose; val = drives 0064 0070 0079 0084 0086 0087 0091 0093 of 2011_09_26;
    /// train = the rest. SemanticKITTI: the dataset's own (sequence 08 is val). KITTI object: a
    /// seeded half-and-half frame split.
    Split(SplitArgs),
    /// Class balance, normalisation constants and class weights of converted data (a convert
    /// folder, its lidar_2d, a folder of maps, or shards), per split.
    ///
    /// Per class: labelled cells and points, shares, frames, instances and poses (with --raw);
    /// per split: each class's train/val share; per channel: mean and standard deviation over
    /// valid cells (SqueezeSeg's INPUT_MEAN / INPUT_STD); suggested loss weights; tracklet
    /// state / occlusion / truncation histograms; per-row fill and colour coverage.
    Stats(StatsArgs),
    /// Score a model's predictions against converted ground truth: per-class IoU, mIoU.
    ///
    /// Cell protocol (SqueezeSeg's, default): cells with ground-truth range > 0, TP/FP/FN summed
    /// over all frames, IoU = TP / (TP + FP + FN); mIoU over the class map's classes (car,
    /// pedestrian, cyclist). --points: the same per scan point in the field of view (needs
    /// --raw). With a SemanticKITTI root as --gt: the benchmark's own protocol on
    /// sequences/<NN>/predictions/*.label. Predictions, matched by frame id, may be HxW label
    /// maps, HxWxK scores (argmax), SqueezeSeg-layout HxWx6/9 .npy, per-point .label files or
    /// prediction shards. Exit status 1 on bad or missing predictions, naming the frame.
    Score(ScoreArgs),
    /// Carry map predictions back to every point of their scans, in the source's per-point
    /// layout: SemanticKITTI OUT/sequences/<NN>/predictions/<frame6>.label (raw ids, as the
    /// benchmark takes them), KITTI raw and object OUT/labels/<drive>/<frame>.label (class ids).
    ///
    /// Each scan is projected again with the map the ground truth records (--gt: a convert
    /// folder or shards), by convert's own code. --method knn (default) is RangeNet++'s kNN
    /// post-processing, its result point for point (--knn-k 5, --knn-window 5, --knn-sigma 1,
    /// --knn-cutoff 1); --method cell gives each point its cell's class. Points outside the map
    /// (a 90-degree map's back) are "not predicted": raw id 0 (unlabeled) for SemanticKITTI,
    /// class 0xffff for the others; counted. Exit status 3 when some frames fail.
    Unproject(crate::commands::unproject::UnprojectArgs),
    /// Check a SemanticKITTI prediction folder before submitting it, as the benchmark's
    /// validate_submission.py does: every scan of the sequences has
    /// sequences/<NN>/predictions/<frame6>.label with one raw id of the dataset's learning_map
    /// per point; nothing missing or extra; every problem named (exit status 1). --zip packs a
    /// valid folder in the benchmark's layout, with description.txt.
    Submission(crate::commands::submission::SubmissionArgs),
    /// Lint a dataset before training on it: inventory and annotation coverage, calibration
    /// (rotations, projections, the camera's view of the points, camera/LiDAR alignment),
    /// boxes (sizes, pose jumps, heading flips, overlaps, boxes off the ground, empty boxes,
    /// annotations that end while the object is still there, frames whose annotation thins
    /// out), per-point labels (unknown ids, instances with several classes, moving classes that
    /// do not move) and the split (class balance, drives in both splits).
    ///
    /// Each finding has a severity (error: the data is wrong or unusable; warning: likely wrong;
    /// note), the check, the file, the frame and the object. --list names every check and
    /// threshold (docs/check.md explains them). Exit status: 0 clean, 3 when a finding reaches
    /// --fail-on (default error), 1 when the root cannot be read at all.
    Check(crate::commands::check::CheckArgs),
    /// Describe MCAP shards: frames, channels, sizes, compression ratio, class counts, and the
    /// conversion parameters stored in them. Fails, naming the shard and frame, on a corrupted one.
    Inspect(InspectArgs),
}

/// `kitti2pgm inspect`.
#[derive(Debug, ClapArgs)]
pub struct InspectArgs {
    /// Shards (.mcap).
    #[arg(required = true, value_name = "SHARD")]
    pub shards: Vec<PathBuf>,
    /// Print JSON instead of a table.
    #[arg(long)]
    pub json: bool,
}

/// `kitti2pgm score`.
#[derive(Debug, ClapArgs)]
pub struct ScoreArgs {
    /// Ground truth: a `kitti2pgm convert` output folder (lidar_2d/), or its shards (a .mcap
    /// file, a folder of them, or a convert folder holding only shards/; cell protocol only).
    #[arg(long, value_name = "PATH")]
    pub gt: PathBuf,
    /// Read the output of an unfinished (running or killed) or inconsistent conversion anyway;
    /// the report says it is partial. Without it such ground truth is refused.
    #[arg(long)]
    pub partial: bool,
    /// Predictions: a folder (searched recursively) or one file.
    #[arg(long, value_name = "PATH")]
    pub pred: PathBuf,
    /// Only the frames of this ImageSet list (e.g. OUT/ImageSet/val.txt), or of an ImageSet
    /// folder's val.txt; default: every ground-truth frame.
    #[arg(long, value_name = "LIST|DIR")]
    pub imageset: Option<PathBuf>,
    /// Point protocol: score every scan point in the field of view (needs --raw).
    #[arg(long, requires = "raw")]
    pub points: bool,
    /// Score map predictions per point as well, carried back to the points by this method
    /// (cell: each point its cell's class; knn: RangeNet++'s post-processing, --knn-*); the
    /// table shows the cell (2D) and point (3D) figures side by side. Needs --raw.
    #[arg(long, value_enum, requires = "raw", value_name = "METHOD")]
    pub unproject: Option<kitti2pgm::project::unproject::MethodKind>,
    /// The kNN's parameters for --unproject knn.
    #[command(flatten)]
    pub knn: crate::commands::unproject::KnnArgs,
    /// KITTI raw root (for --points, and for .label predictions under the cell protocol).
    #[arg(long, value_name = "RAW_ROOT")]
    pub raw: Option<PathBuf>,
    /// Score a ground-truth frame without a prediction as all background instead of failing.
    #[arg(long)]
    pub missing_as_background: bool,
    /// Print the report as JSON (layout in docs/evaluation.md).
    #[arg(long)]
    pub json: bool,
    /// Include per-frame IoUs (table and JSON).
    #[arg(long)]
    pub per_frame: bool,
    /// Draw the confusion matrix to this PNG.
    #[arg(long, value_name = "PNG")]
    pub confusion: Option<PathBuf>,
    /// Draw the N worst frames (lowest mIoU of the classes present) as prediction-over-truth PNGs.
    #[arg(long, value_name = "N")]
    pub worst: Option<usize>,
    /// Folder for --worst pictures.
    #[arg(long, value_name = "DIR", default_value = "worst")]
    pub worst_dir: PathBuf,
}

/// `kitti2pgm split`.
#[derive(Debug, ClapArgs)]
pub struct SplitArgs {
    /// The input, as for convert: a KITTI raw, SemanticKITTI or KITTI object root (or one
    /// drive, sequence or split folder).
    #[arg(value_name = "ROOT")]
    pub raw_root: PathBuf,
    /// Force the input layout instead of detecting it.
    #[arg(long, value_enum)]
    pub source: Option<Layout>,
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

/// `kitti2pgm stats`.
#[derive(Debug, ClapArgs)]
pub struct StatsArgs {
    /// A `kitti2pgm convert` output folder (with lidar_2d/).
    #[arg(value_name = "DIR")]
    pub dir: PathBuf,
    /// Read the output of an unfinished (running or killed) or inconsistent conversion anyway;
    /// the report says it is partial. Without it such ground truth is refused.
    #[arg(long)]
    pub partial: bool,
    /// Split lists: list files (train.txt, val.txt; named by their stem) or an ImageSet folder
    /// (its train.txt and val.txt). Without it, one split `all` over every converted frame.
    #[arg(long, value_name = "PATH")]
    pub imageset: Vec<PathBuf>,
    /// KITTI raw root, for tracklet figures (instances, poses, state, occlusion, truncation).
    #[arg(long, value_name = "RAW_ROOT")]
    pub raw: Option<PathBuf>,
    /// Print the report as JSON (stable keys, see docs/stats.md) instead of a table.
    #[arg(long)]
    pub json: bool,
    /// Also draw the class balance per split as a PNG bar chart.
    #[arg(long, value_name = "PNG")]
    pub chart: Option<PathBuf>,
}

/// `kitti2pgm convert`.
#[derive(Debug, ClapArgs)]
pub struct ConvertArgs {
    /// The input: a KITTI raw root, date or drive folder; a SemanticKITTI / odometry root
    /// (sequences/<NN>/) or one sequence folder; a KITTI object root (training/, testing/) or
    /// one split folder. The layout is detected (see --source).
    #[arg(value_name = "ROOT")]
    pub raw_root: PathBuf,
    /// Force the input layout instead of detecting it.
    #[arg(long, value_enum)]
    pub source: Option<Layout>,
    /// Class map: a built-in one by the name outputs record (kitti-paper-4: background, car,
    /// pedestrian, cyclist; semantic-kitti: SemanticKITTI's 20 classes), or a
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

/// `kitti2pgm preview`.
#[derive(Debug, ClapArgs)]
pub struct PreviewArgs {
    /// Converted frames: .npy files (H x W x 6 or 9), or every frame of a convert output
    /// folder, a lidar_2d folder (SqueezeSeg's too) or shards.
    #[arg(required = true, value_name = "NPY|DIR|SHARD")]
    pub inputs: Vec<PathBuf>,
    /// Read the output of an unfinished (running or killed) or inconsistent conversion anyway;
    /// the report says it is partial. Without it such ground truth is refused.
    #[arg(long)]
    pub partial: bool,
    /// Output: a .png file for one .npy input, else a folder (one <frame>.png per frame).
    #[arg(long, short, value_name = "PATH")]
    pub out: PathBuf,
    /// Per-point predictions (unproject's output, per-point .label files) are drawn against the
    /// scans of this dataset root: bird's-eye and range views of truth, prediction and errors.
    #[arg(long, value_name = "ROOT")]
    pub raw: Option<PathBuf>,
    /// With --raw: the convert folder whose .label files are the truth (KITTI raw and object;
    /// SemanticKITTI's own labels are used where present).
    #[arg(long, value_name = "DIR", requires = "raw")]
    pub gt: Option<PathBuf>,
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;

    #[test]
    fn cli_is_consistent() {
        Args::command().debug_assert();
    }

    #[test]
    fn parses_convert() {
        let a = Args::try_parse_from([
            "kitti2pgm",
            "convert",
            "raw",
            "--out",
            "o",
            "--rgb",
            "--camera",
            "3",
            "--fov-down-deg",
            "-20",
        ])
        .unwrap();
        let Command::Convert(c) = a.command else {
            panic!()
        };
        assert!(c.rgb);
        assert_eq!(c.camera, 3);
        assert_eq!(c.fov_down_deg, Some(-20.0));
        assert!(Args::try_parse_from([
            "kitti2pgm",
            "convert",
            "raw",
            "--out",
            "o",
            "--camera",
            "1"
        ])
        .is_err());
    }
}
