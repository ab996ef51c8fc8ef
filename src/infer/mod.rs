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
//! - with `maps`, the map prediction `OUT/maps/<frame id>.npy` (rows x cols class ids).
//!
//! Frames run in parallel (the model's runs one at a time, each on ONNX Runtime's threads); a
//! frame that fails is recorded and the others go on; files are written atomically.

pub mod engine;
pub mod frame;
pub mod model;
pub mod spec;

use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::Instant;

use rayon::prelude::*;
use serde::Serialize;

use crate::error::{Error, Result, Role};
use crate::format::Durability;
use crate::label::ClassCounts;
use crate::plan::{FrameSelection, Plan};
use crate::project::unproject::{Method, MethodKind};
use crate::source::kitti::DatasetKind;

pub use frame::StageTimes;
pub use model::{Model, ModelOptions};
pub use spec::{ModelSpec, Normalisation, METADATA_KEY, SPEC_VERSION};

/// The folder of the map predictions under the output (`--maps`).
pub const MAPS_DIR: &str = "maps";

/// Where and how to infer.
#[derive(Debug, Clone)]
pub struct InferOptions {
    /// The output folder.
    pub out: PathBuf,
    /// How the points get their classes from the map.
    pub method: Method,
    /// Also write each map prediction (`OUT/maps`).
    pub maps: bool,
    /// The layout of a dataset root, when it is not the one found.
    pub dataset: Option<DatasetKind>,
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
    /// Where the per-point files are.
    pub written_to: PathBuf,
    /// Time per stage.
    pub seconds: StageSeconds,
    /// Wall time, seconds.
    pub wall_seconds: f64,
}

/// The totals of the frames run so far.
#[derive(Default)]
struct Totals {
    frames: u64,
    points: u64,
    missing: u64,
    counts: Option<ClassCounts>,
    times: StageTimes,
}

impl Totals {
    fn add(&mut self, r: &frame::ScanResult, missing: u64) {
        self.frames += 1;
        self.points += r.per_point.len() as u64;
        self.missing += missing;
        match &mut self.counts {
            Some(c) => *c += &r.counts,
            None => self.counts = Some(r.counts.clone()),
        }
        self.times += r.times;
    }
}

/// Refuses an output folder that is, lies in or holds the input or the model.
fn refuse_over_inputs(model: &Model, input: &Path, out: &Path) -> Result<()> {
    crate::fs::refuse_overlap(out, &[(Role::Dataset, input), (Role::Model, &model.path)])
}

/// Runs `model` on `input` (a dataset root, or one scan file) into `opts.out`; `progress` is
/// called with the number of frames once they are known, then after each frame.
pub fn infer(
    model: &Model,
    input: &Path,
    opts: &InferOptions,
    progress: &(dyn Fn(Progress) + Sync),
) -> Result<InferSummary> {
    let start = Instant::now();
    refuse_over_inputs(model, input, &opts.out)?;
    opts.method.validate()?;
    let totals = Mutex::new(Totals::default());
    let mut failures = Vec::new();
    let written_to;
    if std::fs::metadata(input)
        .map_err(|e| Error::io(input, e))?
        .is_file()
    {
        written_to = opts.out.clone();
        progress(Progress::Frames(1));
        match one_file(model, input, opts) {
            Ok((r, missing)) => totals.lock().expect("not poisoned").add(&r, missing),
            Err(e) => failures.push(InferFailure {
                frame: input.display().to_string(),
                error: e.to_string(),
            }),
        }
        progress(Progress::Done(1));
    } else {
        written_to = run_root(model, input, opts, &totals, &mut failures, progress)?;
    }
    let t = totals.into_inner().expect("not poisoned");
    let map = &model.spec.map.class_map;
    let counts = t.counts.unwrap_or_else(|| ClassCounts::zeros(map.len()));
    Ok(InferSummary {
        model: model.path.clone(),
        digest: model.digest.clone(),
        method: opts.method.kind(),
        frames: t.frames,
        points: t.points,
        not_predicted: t.missing,
        classes: map
            .classes
            .iter()
            .zip(&counts.0)
            .map(|(c, &n)| (c.name.clone(), n))
            .collect(),
        failures,
        written_to,
        seconds: t.times.into(),
        wall_seconds: start.elapsed().as_secs_f64(),
    })
}

/// Every frame of the dataset root `input`: its failures added to `failures`; returns where
/// the per-point files went.
fn run_root(
    model: &Model,
    input: &Path,
    opts: &InferOptions,
    totals: &Mutex<Totals>,
    failures: &mut Vec<InferFailure>,
    progress: &(dyn Fn(Progress) + Sync),
) -> Result<PathBuf> {
    let plan = Plan::build_as(input, FrameSelection::All, opts.dataset)?;
    for f in &plan.failed {
        failures.push(InferFailure {
            frame: f.what.to_string(),
            error: f.error.clone(),
        });
    }
    progress(Progress::Frames(plan.jobs.len() as u64));
    let mut failed: Vec<(usize, InferFailure)> = plan
        .jobs
        .par_iter()
        .enumerate()
        .filter_map(|(i, &(d, f))| {
            let r = one_frame(model, &plan, (d, f), opts);
            progress(Progress::Done(1));
            match r {
                Ok((r, missing)) => {
                    totals.lock().expect("not poisoned").add(&r, missing);
                    None
                }
                Err(e) => Some((
                    i,
                    InferFailure {
                        frame: plan.drives[d].drive.frame_id(f).to_string(),
                        error: e.to_string(),
                    },
                )),
            }
        })
        .collect();
    failed.sort_by_key(|(i, _)| *i);
    failures.extend(failed.into_iter().map(|(_, f)| f));
    Ok(written_dir(&opts.out, plan.layout()))
}

/// How far a run is.
#[derive(Debug, Clone, Copy)]
pub enum Progress {
    /// The frames it will run.
    Frames(u64),
    /// Frames finished since the last call.
    Done(u64),
}

/// Where the per-point predictions of a root of `layout` go under `out`.
fn written_dir(out: &Path, layout: DatasetKind) -> PathBuf {
    match layout {
        DatasetKind::Sequence => out.join("sequences"),
        _ => out.join("labels"),
    }
}

/// One frame of a root: projected, predicted, written.
fn one_frame(
    model: &Model,
    plan: &Plan,
    (d, f): (usize, u32),
    opts: &InferOptions,
) -> Result<(frame::ScanResult, u64)> {
    let dp = &plan.drives[d];
    let t = Instant::now();
    let p = frame::project(model, &dp.drive.scan_path(f), Some((dp, f)))?;
    let read_project = t.elapsed();
    let mut r = frame::predict(model, &p, &opts.method)?;
    r.times.read_project = read_project;
    let t = Instant::now();
    let missing = frame::write(&dp.drive.frame_id(f), &r, model, opts)?;
    r.times.write = t.elapsed();
    Ok((r, missing))
}

/// A lone scan file: `OUT/<stem>.label` (class ids; [`NOT_PREDICTED`] outside the map) and,
/// with maps, `OUT/maps/<stem>.npy`.
///
/// [`NOT_PREDICTED`]: crate::format::label_file::NOT_PREDICTED
fn one_file(model: &Model, path: &Path, opts: &InferOptions) -> Result<(frame::ScanResult, u64)> {
    let mut r = frame::predict_file(model, path, &opts.method)?;
    let t = Instant::now();
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "scan".into());
    let missing = frame::write_file(&opts.out, &stem, &r, model, opts)?;
    r.times.write = t.elapsed();
    Ok((r, missing))
}
