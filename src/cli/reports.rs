//! The arguments of the reports: `preview`, `stats`, `score`, `unproject`, `inspect`.

use std::path::PathBuf;

use clap::Args as ClapArgs;
use kitti2pgm::project::unproject::{KnnParams, Method, MethodKind};

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
    pub knn: KnnArgs,
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

/// RangeNet++'s kNN parameters (defaults: the reference's).
#[derive(Debug, Clone, ClapArgs)]
pub struct KnnArgs {
    /// kNN: neighbours that vote.
    #[arg(long, default_value_t = 5, value_name = "K")]
    pub knn_k: usize,
    /// kNN: side of the search window around the point's cell (odd).
    #[arg(long, default_value_t = 5, value_name = "CELLS")]
    pub knn_window: usize,
    /// kNN: standard deviation of the Gaussian over the window, cells.
    #[arg(long, default_value_t = 1.0, value_name = "CELLS")]
    pub knn_sigma: f32,
    /// kNN: neighbours whose weighted range difference is above this vote for nobody (0: none
    /// is cut off).
    #[arg(long, default_value_t = 1.0, value_name = "METRES")]
    pub knn_cutoff: f32,
    /// kNN: take the window across the 360-degree seam (the reference pads with zeros there).
    #[arg(long)]
    pub knn_wrap: bool,
}

impl KnnArgs {
    /// The method, with these parameters for the kNN.
    pub fn method(&self, m: MethodKind) -> Method {
        m.with(KnnParams {
            k: self.knn_k,
            window: self.knn_window,
            sigma: self.knn_sigma,
            cutoff: self.knn_cutoff,
            wrap_columns: self.knn_wrap,
        })
    }
}

/// `kitti2pgm unproject`.
#[derive(Debug, ClapArgs)]
pub struct UnprojectArgs {
    /// The converted ground truth the predictions were made on (a convert folder or shards): it
    /// records the map whose cells are recomputed.
    #[arg(long, value_name = "PATH")]
    pub gt: PathBuf,
    /// Map predictions: a folder (searched recursively) or one file (H x W label maps, H x W x K
    /// scores, SqueezeSeg-layout .npy or prediction shards).
    #[arg(long, value_name = "PATH")]
    pub pred: PathBuf,
    /// The dataset root holding the scans (KITTI raw, SemanticKITTI or KITTI object).
    #[arg(long, value_name = "ROOT")]
    pub raw: PathBuf,
    /// Output folder: OUT/sequences/<NN>/predictions/<frame6>.label (SemanticKITTI, raw ids) or
    /// OUT/labels/<drive>/<frame>.label (KITTI raw and object, class ids).
    #[arg(long, short, value_name = "DIR")]
    pub out: PathBuf,
    /// How a point gets its class (the kNN's parameters: --knn-*).
    #[arg(long, value_enum, default_value_t = MethodKind::Knn)]
    pub method: MethodKind,
    /// The kNN's parameters.
    #[command(flatten)]
    pub knn: KnnArgs,
    /// Only the frames of this ImageSet list (or an ImageSet folder's val.txt).
    #[arg(long, value_name = "LIST|DIR")]
    pub imageset: Option<PathBuf>,
    /// Read the output of an unfinished or inconsistent conversion anyway.
    #[arg(long)]
    pub partial: bool,
    /// Flush each file before renaming it into place.
    #[arg(long)]
    pub sync: bool,
    /// Also write the per-point predictions to this MCAP file for Foxglove: each scan's points
    /// coloured by their predicted class, wrong ones (against the truth, where there is one) in
    /// red.
    #[arg(long, value_name = "MCAP")]
    pub viz: Option<PathBuf>,
    /// Print the summary as JSON.
    #[arg(long)]
    pub json: bool,
}
