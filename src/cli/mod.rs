//! Command-line arguments (clap derive), every subcommand's here: raw input, validated into
//! library types by `commands::*`. One file per family: [`convert`] (convert, split and the
//! split rule), [`reports`] (preview, stats, score, unproject, inspect), [`inputs`] (check,
//! submission).

mod convert;
mod infer;
mod inputs;
mod label;
mod reports;

pub use convert::{ConvertArgs, FormatArg, SplitArgs};
pub use infer::InferArgs;
pub use inputs::{CheckArgs, SubmissionArgs, UnpackArgs};
pub use label::LabelArgs;
pub use reports::{InspectArgs, PreviewArgs, ScoreArgs, StatsArgs, UnprojectArgs};

use clap::{Parser, Subcommand};

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

impl Args {
    /// Whether the command prints JSON (`--json`): its errors then go to standard output as a
    /// JSON record too.
    pub fn json(&self) -> bool {
        match &self.command {
            Command::Convert(a) => a.json,
            Command::Split(a) => a.json,
            Command::Stats(a) => a.json,
            Command::Score(a) => a.json,
            Command::Unproject(a) => a.json,
            Command::Infer(a) => a.json,
            Command::Submission(a) => a.json,
            Command::Check(a) => a.json,
            Command::Inspect(a) => a.json,
            Command::Unpack(a) => a.json,
            Command::Label(a) => a.json,
            Command::Preview(_) => false,
        }
    }
}

/// Subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Convert KITTI raw, SemanticKITTI or KITTI object scans to labelled Polar Grid Maps (.npy),
    /// per-point .label files and MCAP shards.
    ///
    /// ROOT is a KITTI raw root (<date>/calib_*.txt and <date>/<date>_drive_NNNN_sync/), date or
    /// drive folder; a SemanticKITTI root (sequences/<NN>/) or sequence; a KITTI object root
    /// (training/) or split folder. Any other LiDAR's scans come in the sequence layout
    /// (sequences/<NN>/velodyne/ of .pcd, nuScenes .pcd.bin, or .bin with --fields; rows from
    /// --sensor or --sensor-calibration); `kitti2pgm unpack` makes one of a ROS 2 bag or a
    /// nuScenes root. Writes DIR/lidar_2d/<frame id>.npy (float32 64x512x6: x, y,
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
    Unproject(UnprojectArgs),
    /// Run a trained model (ONNX) on scans: each scan projected exactly as the model's training
    /// data was, the model run, its classes carried back to every point.
    ///
    /// The model exported by `python -m kitti2pgm_train export` records its map (rows, columns,
    /// field of view, row source, sensor model and pose, colour, class map) and its input's
    /// channels; a scan of a sensor whose beam model does not fit that map is refused, with the
    /// numbers. INPUT is a dataset root, a scan file or a ROS 2 bag (--topic; streamed).
    /// Outputs per-point predictions in the layout `score` and `submission` read
    /// (SemanticKITTI's predictions/ for sequence roots and bags), --maps the map predictions,
    /// --viz a Foxglove replay, --as-labels label files to correct by hand (`check` reports the
    /// unedited ones, `score` compares the corrections with the model). ONNX Runtime is loaded
    /// from the onnxruntime Python package (tools/install.sh). Exit status: 0 all predicted, 1
    /// fatal error or every scan failed, 2 usage error, 3 some scans failed.
    Infer(InferArgs),
    /// Check a SemanticKITTI prediction folder before submitting it, as the benchmark's
    /// validate_submission.py does: every scan of the sequences has
    /// sequences/<NN>/predictions/<frame6>.label with one raw id of the dataset's learning_map
    /// per point; nothing missing or extra; every problem named (exit status 1). --zip packs a
    /// valid folder in the benchmark's layout, with description.txt.
    Submission(SubmissionArgs),
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
    Check(CheckArgs),
    /// Describe MCAP shards: frames, channels, sizes, compression ratio, class counts, and the
    /// conversion parameters stored in them. Fails, naming the shard and frame, on a corrupted one.
    Inspect(InspectArgs),
    /// Unpack a ROS 2 bag's point clouds (sensor_msgs/msg/PointCloud2, CDR, MCAP storage) into
    /// a sequence folder that every other command reads: one bag is one sequence, one message
    /// one frame, ROOT/sequences/<NN>/velodyne/<frame6>.pcd with every field of the message,
    /// times.txt (header stamps, seconds after the first) and unpack.json (the first stamp, the
    /// frame ids, failures).
    ///
    /// The bag is streamed: memory stays flat whatever its size. Then `kitti2pgm convert ROOT
    /// --sensor NAME` (rows from the ring field, or the beam table). A message that does not
    /// decode fails its frame only. Exit status: 0 all unpacked, 3 some frames failed, 1 the bag
    /// or topic cannot be read (the error lists the point cloud topics).
    ///
    /// A nuScenes root (its devkit's layout) unpacks the same way: one scene is one sequence
    /// (scene-0061 -> sequences/61), one LIDAR_TOP keyframe one frame (time order), the scan
    /// hard-linked (else copied) as <frame6>.pcd.bin, its nuScenes-lidarseg labels as
    /// labels/<frame6>.label (the 32 general classes as raw ids), times.txt and nuscenes.json
    /// (the scene, each frame's sample_data token). Then `kitti2pgm convert ROOT --sensor hdl32e
    /// --class-map nuscenes` (the benchmark's 16 classes). The tables are streamed.
    Unpack(UnpackArgs),
    /// Label a sequence's scans point by point from the 3D boxes an annotation tool exported
    /// (CVAT's Kitti Raw Format, Supervisely point clouds, SUSTechPOINTS, labelCloud,
    /// Segments.ai, Xtreme1 / BasicAI, ASAM OpenLABEL):
    /// ROOT/sequences/<NN>/labels/<frame6>.label (u32 per point: class | instance << 16), which
    /// every other command then reads like SemanticKITTI's.
    ///
    /// Each annotated frame's scan is found by name (its file, a scan link's target, or its
    /// frame number); every point in a box takes the box's class, by parry's containment test,
    /// the smallest box winning where boxes overlap (KITTI's tracklet rule). --class-map says
    /// which object type is which class (a type it does not know is an error unless --alias or
    /// --unknown-class says); instance ids are stable per track across the sequence and across
    /// runs. box_labels.json beside the labels records the class map, the box files' digests
    /// and every label file written: `convert ROOT` uses that class map, and a re-run rewrites
    /// exactly the frames whose labels change. A label file `label` did not write is refused
    /// unless --overwrite (a dataset's own labels always). Exit status: 0 all labelled, 3 some
    /// frames failed (a scan missing or unreadable; the rest written), 1 none could be.
    Label(LabelArgs),
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
