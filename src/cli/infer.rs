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
    /// folder of your own sensor's .pcd/.bin scans, an unpacked bag or nuScenes root) or one
    /// scan file.
    #[arg(value_name = "INPUT")]
    pub input: PathBuf,
    /// Output folder: OUT/sequences/<NN>/predictions/<frame6>.label (sequence roots, raw ids)
    /// or OUT/labels/<drive>/<frame>.label (KITTI raw and object, class ids); a lone scan file
    /// gives OUT/<stem>.label.
    #[arg(long, short, value_name = "DIR")]
    pub out: PathBuf,
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
