//! `kitti2pgm infer`'s arguments.

use std::path::PathBuf;

use clap::Args as ClapArgs;
use kitti2pgm::project::unproject::MethodKind;
use kitti2pgm::source::kitti::DatasetKind;

use super::reports::KnnArgs;

/// `kitti2pgm infer`.
#[derive(Debug, ClapArgs)]
pub struct InferArgs {
    /// The model: an ONNX file exported by `python -m kitti2pgm_train export` (it records its
    /// map), or any ONNX segmentation model with --map-from.
    #[arg(long, value_name = "MODEL.onnx")]
    pub model: PathBuf,
    /// What to run it on: a dataset root (KITTI raw, SemanticKITTI, KITTI object, a sequence
    /// folder of your own sensor's .pcd/.bin scans, an unpacked bag or nuScenes root), a ROS 2
    /// bag (a .mcap file or a bag folder, with --topic; streamed) or one scan file.
    #[arg(value_name = "INPUT")]
    pub input: PathBuf,
    /// Output folder: OUT/sequences/<NN>/predictions/<frame6>.label (sequence roots and bags,
    /// raw ids; a bag is sequence 00, message i frame i) or OUT/labels/<drive>/<frame>.label
    /// (KITTI raw and object, class ids); a lone scan file gives OUT/<stem>.label.
    #[arg(long, short, value_name = "DIR", required_unless_present = "as_labels")]
    pub out: Option<PathBuf>,
    /// A bag's sensor_msgs/msg/PointCloud2 topic (the error lists them when missing).
    #[arg(long, value_name = "TOPIC")]
    pub topic: Option<String>,
    /// Also write the predictions as label files of a sequence root, to correct by hand:
    /// ROOT/sequences/<NN>/labels/<frame6>.label (raw ids of the model's class map), with
    /// model_labels.json naming the model and each file as written (check reports the unedited
    /// ones). ROOT may be INPUT; labels already there are never replaced (--overwrite: an
    /// earlier --as-labels run's, when none was edited).
    #[arg(long, value_name = "ROOT")]
    pub as_labels: Option<PathBuf>,
    /// Replace the label files of an earlier --as-labels run (never edited ones).
    #[arg(long, requires = "as_labels")]
    pub overwrite: bool,
    /// Write a Foxglove replay file: each scan's labelled points coloured by class, at the scan's
    /// own time (a bag's header stamps).
    #[arg(long, value_name = "OUT.mcap")]
    pub viz: Option<PathBuf>,
    /// The map a model without kitti2pgm's record was trained on: a conversion's output folder
    /// (convert_summary.json) or shards; its class map too.
    #[arg(long, value_name = "DIR")]
    pub map_from: Option<PathBuf>,
    /// Also write each map prediction: OUT/maps/<frame id>.npy (rows x cols class ids), which
    /// `score --pred` reads.
    #[arg(long)]
    pub maps: bool,
    /// How a point gets its class from the map (the kNN's parameters: --knn-*).
    #[arg(long, value_enum, default_value_t = MethodKind::Knn)]
    pub method: MethodKind,
    /// The kNN's parameters.
    #[command(flatten)]
    pub knn: KnnArgs,
    /// The dataset layout of INPUT, when it is not the one found.
    #[arg(long, value_enum, value_name = "LAYOUT")]
    pub dataset: Option<DatasetKind>,
    /// ONNX Runtime's library (libonnxruntime.so*) or its folder; default: $KITTI2PGM_ONNXRUNTIME,
    /// $ORT_DYLIB_PATH, else the onnxruntime Python package's (tools/install.sh installs it).
    #[arg(long, value_name = "PATH")]
    pub onnxruntime: Option<PathBuf>,
    /// Threads ONNX Runtime runs one map on (0: one per core).
    #[arg(long, default_value_t = 0, value_name = "N")]
    pub model_threads: usize,
    /// Flush each file before renaming it into place.
    #[arg(long)]
    pub sync: bool,
    /// Print the summary as JSON.
    #[arg(long)]
    pub json: bool,
}
