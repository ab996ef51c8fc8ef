//! `kitti2pgm unproject`: the CLI over [`kitti2pgm::report::unproject`].

use std::path::PathBuf;

use clap::Args as ClapArgs;
use kitti2pgm::format::imageset;
use kitti2pgm::project::unproject::{KnnParams, Method, MethodKind};
use kitti2pgm::report::score::Predictions;
use kitti2pgm::report::truth::GroundTruth;
use kitti2pgm::report::unproject::{
    refuse_output_over_inputs, unproject_all, write_viz, UnprojectOptions, UnprojectSummary,
    NOT_PREDICTED,
};

use super::{completeness, durability, progress, Global};
use crate::Outcome;

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

/// Refuses a `--viz` file over an input (or the output folder).
fn refuse_viz_over_inputs(a: &UnprojectArgs) -> anyhow::Result<()> {
    use kitti2pgm::fs::Role;
    if let Some(viz) = &a.viz {
        let inputs = [
            (Role::GroundTruth, a.gt.as_path()),
            (Role::Predictions, a.pred.as_path()),
            (Role::Dataset, a.raw.as_path()),
            (Role::Predictions, a.out.as_path()),
        ];
        kitti2pgm::fs::refuse_overlap(viz, &inputs)?;
    }
    Ok(())
}

pub fn run(a: UnprojectArgs, g: &Global) -> anyhow::Result<Outcome> {
    // Parameters first: a usage error before anything is read.
    let method = a.knn.method(a.method);
    method.validate()?;
    let gt = GroundTruth::open_with(&a.gt, completeness(a.partial))?;
    if let Some(p) = &gt.partial {
        eprintln!("kitti2pgm: PARTIAL: {p}");
    }
    let preds = Predictions::index(&a.pred)?;
    let only = match &a.imageset {
        Some(l) => {
            let list = if l.is_dir() {
                l.join("val.txt")
            } else {
                l.clone()
            };
            Some(imageset::read(&list)?.into_iter().collect())
        }
        None => None,
    };
    let opts = UnprojectOptions {
        method,
        raw: a.raw.clone(),
        out: a.out.clone(),
        only,
        durability: durability(a.sync),
    };
    refuse_output_over_inputs(&opts.out, &gt, &preds, &opts)?;
    refuse_viz_over_inputs(&a)?;
    let total = opts.only.as_ref().map_or(gt.frames.len(), |o| o.len());
    let pb = progress::bar(total as u64, g.progress, "unprojecting");
    let pool = g.pool()?;
    let s = pool.install(|| unproject_all(&gt, &preds, &opts, &|n| pb.inc(n)))?;
    pb.finish_and_clear();
    if a.json {
        println!("{}", serde_json::to_string_pretty(&s)?);
    } else {
        print!("{}", table(&s, &gt));
    }
    for f in &s.failures {
        eprintln!("kitti2pgm: {}: {}", f.frame, f.error);
    }
    if let Some(viz) = &a.viz {
        let frames = &s.written;
        write_viz(&gt, &opts, frames, viz)?;
        if !a.json {
            println!("viz              {:>10}  ({})", frames.len(), viz.display());
        }
    }
    Ok(match (s.failures.is_empty(), s.frames) {
        (true, _) => Outcome::Ok,
        (false, 0) => anyhow::bail!("no frame could be carried back"),
        (false, _) => Outcome::Partial,
    })
}

/// The summary as a table.
fn table(s: &UnprojectSummary, gt: &GroundTruth) -> String {
    use std::fmt::Write;
    let mut t = String::new();
    let _ = writeln!(t, "method           {:>10}", s.method);
    let _ = writeln!(
        t,
        "frames written   {:>10}  (into {})",
        s.frames,
        s.written_to.display()
    );
    if s.not_carried > 0 {
        let _ = writeln!(
            t,
            "not carried      {:>10}  (ground-truth frames not listed, or of drives without any prediction)",
            s.not_carried
        );
    }
    let _ = writeln!(t, "points           {:>10}", s.points);
    let _ = writeln!(
        t,
        "not predicted    {:>10}  (outside the map's field of view: {})",
        s.not_predicted,
        if gt
            .frames
            .iter()
            .any(|f| f.layout == kitti2pgm::kitti::Layout::Sequence)
        {
            "raw id 0, unlabeled".to_string()
        } else {
            format!("class {NOT_PREDICTED:#06x}")
        }
    );
    t
}
