//! INFER: a trained model run on scans (`kitti2pgm infer`), between PROJECT and UNPROJECT.
//!
//! The model's ONNX file records the map its training data was made with ([`spec`]); every scan
//! is read and projected with exactly that map by the code `convert` projects with (the sensor
//! model, its pose, rows and columns, colour from the camera), the model is run by ONNX Runtime
//! ([`engine`], [`model`]), and the map's classes are carried back to every point by
//! [`unproject`](crate::project::unproject) (RangeNet++'s kNN by default). Written, per frame:
//!
//! - the per-point predictions in the layout `score` and `submission` read: SemanticKITTI's
//!   `OUT/sequences/<NN>/predictions/<frame6>.label` (raw ids) for sequence roots, else
//!   `OUT/labels/<drive>/<frame>.label` (class ids); a lone scan file gives `OUT/<stem>.label`;
//! - with `maps`, the map prediction `OUT/maps/<frame id>.npy` (rows x cols class ids);
//! - with `as_labels`, a sequence root's label files ([`labels`]), with `viz` a replay file
//!   ([`viz`]).
//!
//! INPUT is a dataset root, one scan file or a ROS 2 bag's point cloud topic ([`input`]), read
//! a batch of scans at a time (a bag in flat memory) and recorded in their order. When ONNX
//! Runtime runs a map on every core (the default), the scans run one at a time; with fewer model
//! threads than workers, the scans of a batch run in parallel (the model's runs one at a time).
//! A scan that fails is recorded and the others go on; files are written atomically.

pub mod engine;
pub mod frame;
pub mod input;
pub mod labels;
pub mod model;
pub mod spec;
pub mod viz;

use std::path::{Path, PathBuf};
use std::time::Instant;

use rayon::prelude::*;
use serde::Serialize;

use crate::error::{Error, Result, Role};
use crate::format::model_labels::{ModelLabelRecord, RecordedMethod};
use crate::format::Durability;
use crate::fs::Fingerprint;
use crate::geom::Point3;
use crate::label::{ClassCounts, ClassId};
use crate::project::unproject::{Method, MethodKind};
use crate::source::kitti::DatasetKind;

pub use frame::StageTimes;
pub use input::{Input, BAG_SEQUENCE};
pub use model::{Model, ModelOptions};
pub use spec::{ModelSpec, Normalisation, METADATA_KEY, SPEC_VERSION};

use input::{Target, Unit};
use labels::AsLabels;
use viz::VizWriter;

/// The folder of the map predictions under the output (`--maps`).
pub const MAPS_DIR: &str = "maps";

/// Where and how to infer.
#[derive(Debug, Clone)]
pub struct InferOptions {
    /// The output folder of the predictions (`score`'s layouts), if any.
    pub out: Option<PathBuf>,
    /// How the points get their classes from the map.
    pub method: Method,
    /// Also write each map prediction (`OUT/maps`).
    pub maps: bool,
    /// The layout of a dataset root, when it is not the one found.
    pub dataset: Option<DatasetKind>,
    /// A bag's point cloud topic.
    pub topic: Option<String>,
    /// A replay file to write (Foxglove MCAP).
    pub viz: Option<PathBuf>,
    /// A sequence root to write the predictions into as label files.
    pub as_labels: Option<PathBuf>,
    /// Replace the label files an earlier `as_labels` run wrote (unedited ones only).
    pub overwrite: bool,
    /// Whether each file is flushed to the device before it is renamed into place.
    pub durability: Durability,
}

/// One scan that could not be run.
#[derive(Debug, Clone, Serialize)]
pub struct InferFailure {
    /// The frame (or file).
    pub frame: String,
    /// What went wrong, naming the file.
    pub error: String,
}

/// Seconds spent in each stage, summed over the frames (they overlap on several threads).
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct StageSeconds {
    /// Reading and projecting.
    pub read_project: f64,
    /// Running the model.
    pub model: f64,
    /// Carrying the classes back to the points.
    pub unproject: f64,
    /// Writing.
    pub write: f64,
}

impl From<StageTimes> for StageSeconds {
    fn from(t: StageTimes) -> StageSeconds {
        StageSeconds {
            read_project: t.read_project.as_secs_f64(),
            model: t.model.as_secs_f64(),
            unproject: t.unproject.as_secs_f64(),
            write: t.write.as_secs_f64(),
        }
    }
}

/// What `infer` did.
#[derive(Debug, Clone, Serialize)]
pub struct InferSummary {
    /// The model file.
    pub model: PathBuf,
    /// Its content hash.
    pub digest: String,
    /// The method (`cell` or `knn`).
    pub method: MethodKind,
    /// Frames predicted.
    pub frames: u64,
    /// Points written (every point of their scans).
    pub points: u64,
    /// Points outside the map (or dropped when read): no prediction.
    pub not_predicted: u64,
    /// Predicted points per class name, in the class map's order.
    pub classes: Vec<(String, u64)>,
    /// Frames that failed.
    pub failures: Vec<InferFailure>,
    /// Where the per-point files are (`None`: only label files were written).
    pub written_to: Option<PathBuf>,
    /// The sequence root the label files went into (`--as-labels`).
    pub labels_in: Option<PathBuf>,
    /// The replay file (`--viz`).
    pub viz: Option<PathBuf>,
    /// Time per stage.
    pub seconds: StageSeconds,
    /// Wall time, seconds.
    pub wall_seconds: f64,
}

/// The totals of the frames run so far.
struct Totals {
    frames: u64,
    points: u64,
    missing: u64,
    counts: ClassCounts,
    times: StageTimes,
}

impl Totals {
    fn new(classes: usize) -> Totals {
        Totals {
            frames: 0,
            points: 0,
            missing: 0,
            counts: ClassCounts::zeros(classes),
            times: StageTimes::default(),
        }
    }

    fn add(&mut self, r: &frame::ScanResult) {
        self.frames += 1;
        self.points += r.per_point.len() as u64;
        self.missing += r.per_point.iter().filter(|c| c.is_none()).count() as u64;
        self.counts += &r.counts;
        self.times += r.times;
    }
}

/// Refuses outputs that are, lie in or hold the input or the model (the label root may be the
/// input: that is where pre-labels go), and an output folder over the label root.
fn refuse_over_inputs(model: &Model, input: &Path, opts: &InferOptions) -> Result<()> {
    let inputs = [(Role::Dataset, input), (Role::Model, model.path.as_path())];
    if let Some(out) = &opts.out {
        crate::fs::refuse_overlap(out, &inputs)?;
        if let Some(root) = &opts.as_labels {
            crate::fs::refuse_overlap(out, &[(Role::Dataset, root.as_path())])?;
        }
    }
    if let Some(v) = &opts.viz {
        crate::fs::refuse_overlap(v, &inputs)?;
    }
    if let Some(root) = &opts.as_labels {
        crate::fs::refuse_overlap(root, &[(Role::Model, model.path.as_path())])?;
    }
    Ok(())
}

/// Runs `model` on `input` (a dataset root, one scan file or a bag) as `opts` say; `progress`
/// is called with the number of scans once known, then as they finish.
pub fn infer(
    model: &Model,
    input: &Path,
    opts: &InferOptions,
    progress: &(dyn Fn(Progress) + Sync),
) -> Result<InferSummary> {
    let start = Instant::now();
    if opts.out.is_none() && opts.as_labels.is_none() {
        return Err(Error::Config(
            "nothing to write: give --out, --as-labels or both".into(),
        ));
    }
    refuse_over_inputs(model, input, opts)?;
    opts.method.validate()?;
    let source = open_input(input, opts)?;
    let mut labels = match &opts.as_labels {
        Some(root) => Some(begin_labels(model, &source, input, root, opts)?),
        None => None,
    };
    let mut viz = (opts.viz.as_ref())
        .map(|p| VizWriter::create(p, &model.spec.map.class_map))
        .transpose()?;
    progress(Progress::Frames(source.len()));
    let mut totals = Totals::new(model.spec.map.class_map.len());
    let mut failures = Vec::new();
    let batch_len = 8 * rayon::current_num_threads().max(1);
    let one_at_a_time = model_takes_every_core(model);
    let mut units = input::units(&source);
    let is_bag = matches!(source, Input::Bag(..));
    loop {
        let batch = next_batch(&mut units, batch_len, is_bag, &mut failures, progress);
        if batch.is_empty() {
            break;
        }
        let run = Run {
            model,
            input: &source,
            opts,
            labels: labels.as_ref(),
            viz: viz.is_some(),
        };
        let one = |u: Unit| {
            let r = run.unit(&u);
            progress(Progress::Done(1));
            (u, r)
        };
        let done: Vec<(Unit, Result<Done>)> = if one_at_a_time {
            batch.into_iter().map(one).collect()
        } else {
            batch.into_par_iter().map(one).collect()
        };
        for (u, r) in done {
            match r {
                Ok(d) => {
                    totals.add(&d.result);
                    if let (Some(l), Some(written)) = (labels.as_mut(), d.label) {
                        l.record(written);
                    }
                    if let (Some(v), Some(points)) = (viz.as_mut(), d.viz) {
                        v.add(points, d.stamp.or(u.stamp_ns))?;
                    }
                }
                Err(e) => failures.push(InferFailure {
                    frame: u.name,
                    error: e.to_string(),
                }),
            }
        }
    }
    if let Some(l) = labels {
        l.finish()?;
    }
    if let Some(v) = viz {
        v.finish()?;
    }
    Ok(summary(model, &source, opts, totals, failures, start))
}

/// Opens the input; with `--as-labels ROOT --overwrite`, first clears what an interrupted run
/// left in ROOT (which the readers would refuse).
fn open_input(input: &Path, opts: &InferOptions) -> Result<Input> {
    if let (Some(root), true) = (&opts.as_labels, opts.overwrite) {
        labels::clear_unfinished(root)?;
    }
    Input::open(input, opts.topic.as_deref(), opts.dataset)
}

/// The next (up to) `len` units; those that cannot run are added to `failures` (a bag's count
/// towards the progress: its message count includes them).
fn next_batch(
    units: &mut dyn Iterator<Item = std::result::Result<Unit, input::Skipped>>,
    len: usize,
    is_bag: bool,
    failures: &mut Vec<InferFailure>,
    progress: &(dyn Fn(Progress) + Sync),
) -> Vec<Unit> {
    let mut batch = Vec::with_capacity(len);
    for u in units {
        match u {
            Ok(u) => batch.push(u),
            Err(s) => {
                if is_bag {
                    progress(Progress::Done(1));
                }
                failures.push(InferFailure {
                    frame: s.name,
                    error: s.error,
                });
            }
        }
        if batch.len() == len {
            break;
        }
    }
    batch
}

/// The summary of a run.
fn summary(
    model: &Model,
    source: &Input,
    opts: &InferOptions,
    t: Totals,
    failures: Vec<InferFailure>,
    start: Instant,
) -> InferSummary {
    let map = &model.spec.map.class_map;
    let written_to = (opts.out.as_ref()).map(|out| match source {
        Input::File(_) => out.clone(),
        Input::Root(plan) => written_dir(out, plan.layout()),
        Input::Bag(..) => written_dir(out, DatasetKind::Sequence),
    });
    InferSummary {
        model: model.path.clone(),
        digest: model.digest.clone(),
        method: opts.method.kind(),
        frames: t.frames,
        points: t.points,
        not_predicted: t.missing,
        classes: map
            .classes
            .iter()
            .zip(&t.counts.0)
            .map(|(c, &n)| (c.name.clone(), n))
            .collect(),
        failures,
        written_to,
        labels_in: opts.as_labels.clone(),
        viz: opts.viz.clone(),
        seconds: t.times.into(),
        wall_seconds: start.elapsed().as_secs_f64(),
    }
}

/// Starts the label files of `--as-labels root`: the sequences of a sequence root, or a bag's
/// ([`BAG_SEQUENCE`]); other inputs are refused.
fn begin_labels(
    model: &Model,
    source: &Input,
    input: &Path,
    root: &Path,
    opts: &InferOptions,
) -> Result<AsLabels> {
    let numbers: Vec<u32> = match source {
        Input::Root(plan) if plan.layout() == DatasetKind::Sequence => {
            plan.drives.iter().map(|d| d.drive.number).collect()
        }
        Input::Bag(..) => vec![BAG_SEQUENCE],
        _ => {
            return Err(Error::Config(format!(
                "--as-labels: {} is not a sequence root or a bag; label files go beside a \
                 sequence's scans (sequences/<NN>/labels/)",
                input.display()
            )))
        }
    };
    let template = ModelLabelRecord {
        version: crate::format::model_labels::VERSION,
        kitti2pgm: env!("CARGO_PKG_VERSION").into(),
        complete: false,
        model: model.path.clone(),
        digest: model.digest.clone(),
        producer: model.spec.producer.clone(),
        class_map: model.spec.map.class_map.clone(),
        method: RecordedMethod::from(&opts.method),
        input: input.into(),
        predictions: opts.out.clone(),
        frames: Default::default(),
    };
    AsLabels::begin(root, &numbers, &template, opts.overwrite, opts.durability)
}

/// Whether ONNX Runtime runs a map on as many threads as there are workers: then the scans run
/// one at a time (each scan's stages on one worker, the model on every core). Its threads wait
/// for their slowest, and scans read, projected and carried back beside them slowed the model
/// more than the overlap won: 30 raw scans took 1.32-1.67 s one at a time against 1.38-2.14 s
/// two at a time (lidar-only model; 2.42-3.60 against 2.45-3.63 s with colour), and a gate
/// that kept the model alone while the other stages ran in parallel, 1.52-1.88 s
/// (docs/performance.md).
fn model_takes_every_core(model: &Model) -> bool {
    let workers = rayon::current_num_threads();
    model.threads == 0 || model.threads >= workers
}

/// What one scan gave.
struct Done {
    result: frame::ScanResult,
    label: Option<(u32, String, Fingerprint)>,
    viz: Option<Vec<(Point3, f32, ClassId)>>,
    stamp: Option<i64>,
}

/// What every scan of a run shares.
struct Run<'a> {
    model: &'a Model,
    input: &'a Input,
    opts: &'a InferOptions,
    labels: Option<&'a AsLabels>,
    viz: bool,
}

impl Run<'_> {
    /// One scan: read, projected, predicted, written.
    fn unit(&self, u: &Unit) -> Result<Done> {
        let (model, opts) = (self.model, self.opts);
        let t = Instant::now();
        let (p, stamp) = input::project(model, self.input, &u.read)?;
        let read_project = t.elapsed();
        let mut r = frame::predict(model, &p, &opts.method)?;
        r.times.read_project = read_project;
        let t = Instant::now();
        match (&opts.out, &u.target) {
            (Some(out), Target::Frame(id)) => frame::write(out, id, &r, model, opts)?,
            (Some(out), Target::Stem(stem)) => frame::write_file(out, stem, &r, model, opts)?,
            (None, _) => {}
        }
        let label = match (self.labels, &u.target) {
            (Some(l), Target::Frame(id)) => {
                Some(l.write(id, &r.per_point, &model.spec.map.class_map)?)
            }
            _ => None,
        };
        r.times.write = t.elapsed();
        let viz = self.viz.then(|| frame::viz_points(&p.scan, &r.per_point));
        Ok(Done {
            result: r,
            label,
            viz,
            stamp,
        })
    }
}

/// How far a run is.
#[derive(Debug, Clone, Copy)]
pub enum Progress {
    /// The scans it will run.
    Frames(u64),
    /// Scans finished since the last call.
    Done(u64),
}

/// Where the per-point predictions of a root of `layout` go under `out`.
fn written_dir(out: &Path, layout: DatasetKind) -> PathBuf {
    match layout {
        DatasetKind::Sequence => out.join("sequences"),
        _ => out.join("labels"),
    }
}
