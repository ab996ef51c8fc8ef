//! CONVERT: frame -> read -> label -> project -> write, parallel over frames.
//!
//! [`convert`] runs a [`Plan`] on a rayon pool; each frame's outcome goes to a callback (the
//! CLI's progress bar) and into running totals, so memory does not grow with the number of
//! frames. A bad frame, or a drive whose calibration or tracklets are broken, is reported and
//! the rest of the batch goes on. Every output is written atomically and depends only on its own
//! frame, so the files are byte-identical whatever the thread count. The summary, with the typed
//! parameters, is written last ([`crate::format::summary`]).
//!
//! - [`frame`]: one frame, read to written;
//! - [`shards`]: the shard output (frames in order, written while the next batch converts);
//! - [`unpack`]: recordings -> sequence folders: a ROS 2 bag's point clouds (PCD scans), a
//!   nuScenes root's scenes;
//! - [`box_labels`]: a sequence labelled point by point from an annotation tool's 3D boxes
//!   (`kitti2pgm label`).

pub mod box_labels;
pub mod frame;
pub mod labels;
pub mod resume;
pub mod shards;
pub mod unpack;

use std::sync::Mutex;

use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::format::layout::OutputDir;
use crate::format::summary::{self, ConvertSummary};
use crate::format::{create_dir, Durability};
use crate::label::ClassCounts;
use crate::plan::{Failed, SkipReason};
use crate::plan::{FrameFailure, Plan};
use crate::provenance::ConvertParams;
pub use frame::{convert_frame, load, process, write_frame_files, Converted, FrameReport, Viz};

/// What to convert and where to.
#[derive(Debug, Clone)]
pub struct ConvertOptions {
    /// Output folder.
    pub out: OutputDir,
    /// What to make (recorded in the summary and the shards).
    pub params: ConvertParams,
    /// Worker threads; 0 = one per core, 1 = sequential.
    pub threads: usize,
    /// Whether every file is flushed to the device before it is renamed into place (to survive
    /// power cuts).
    pub durability: Durability,
    /// Convert every frame again, even those an earlier run with the same parameters finished.
    pub overwrite: bool,
    /// How the map was chosen, for the summary; `None` when the caller gave the map directly.
    pub map_origin: Option<crate::project::MapOrigin>,
}

impl ConvertOptions {
    /// SqueezeSeg's conversion into `out_dir`.
    pub fn new(out_dir: impl Into<std::path::PathBuf>) -> Self {
        ConvertOptions {
            out: OutputDir::new(out_dir),
            params: ConvertParams::squeezeseg(),
            threads: 0,
            durability: Durability::Renamed,
            overwrite: false,
            map_origin: None,
        }
    }
}

/// The outcome of one frame, as handed to the progress callback.
#[derive(Debug)]
pub enum FrameOutcome<'a> {
    /// Converted and written.
    Done(&'a FrameReport),
    /// Failed; the rest of the batch goes on.
    Failed(&'a FrameFailure),
    /// This many frames were skipped: their shard is already complete and intact.
    Skipped(u64),
}

/// The running totals of a conversion: the summary, and per-class counts by id.
struct Totals {
    summary: ConvertSummary,
    points: ClassCounts,
    cells: ClassCounts,
    /// The inputs found changed, with what changed.
    changed_inputs: std::collections::BTreeSet<String>,
}

impl Totals {
    fn add(&mut self, r: &FrameReport) {
        let s = &mut self.summary;
        s.frames_converted += 1;
        s.points += r.points;
        s.dropped_nonfinite += r.dropped_nonfinite;
        s.dropped_out_of_range += r.dropped_out_of_range;
        s.projection += &r.projection;
        if r.fallback() {
            s.fallback_frames.push(r.id.clone());
        }
        if r.projection.beam_table_frames > 0 {
            s.beam_table_frame_ids.push(r.id.clone());
        }
        s.rgb_cells += r.rgb_cells;
        s.frames_without_labels += !r.annotated as u64;
        for t in &r.unknown_object_types {
            *s.unknown_object_types.entry(t.clone()).or_default() += 1;
        }
        self.points += &r.labelled_points;
        self.cells += &r.labelled_cells;
    }

    fn fail(&mut self, f: FrameFailure) {
        self.summary.frames_failed += f.frames;
        self.summary.failures.push(f);
    }

    fn finish(self) -> ConvertSummary {
        let mut s = self.summary;
        let map = &s.params.map.class_map;
        s.labelled_points = map.keyed(&self.points.0);
        s.labelled_cells = map.keyed(&self.cells.0);
        s.failures.sort_by_cached_key(|f| f.what.to_string());
        s.fallback_frames.sort();
        s.beam_table_frame_ids.sort();
        s.changed_inputs = self.changed_inputs.into_iter().collect();
        s
    }
}

/// The shared state of a running conversion, handed to the shard writer.
pub(crate) struct Run<'a> {
    totals: Mutex<Totals>,
    /// The folder's journal of finished frames.
    pub(crate) journal: resume::Journal,
    /// Shards this run wrote or kept.
    shards: Mutex<std::collections::BTreeSet<std::path::PathBuf>>,
    progress: &'a (dyn Fn(FrameOutcome<'_>) + Sync),
}

impl Run<'_> {
    fn totals(&self) -> std::sync::MutexGuard<'_, Totals> {
        self.totals.lock().expect("no panic while holding the lock")
    }

    /// What `verdict` says of a planned frame, counted: whether to keep it.
    pub(crate) fn keeps(&self, verdict: resume::Verdict) -> bool {
        match verdict {
            resume::Verdict::Keep => true,
            resume::Verdict::Convert(None) => false,
            resume::Verdict::Convert(Some((why, change))) => {
                let mut t = self.totals();
                *t.summary.reconverted.entry(why).or_default() += 1;
                if let Some(c) = change {
                    t.changed_inputs.insert(c.to_string());
                }
                false
            }
        }
    }

    /// Frames left as an earlier run wrote them.
    pub(crate) fn kept(&self, n: u64, why: SkipReason) {
        (self.progress)(FrameOutcome::Skipped(n));
        let mut t = self.totals();
        t.summary.resumed_frames += n;
        *t.summary.frames_skipped.entry(why).or_default() += n;
    }

    /// A shard written, or kept as it was, by this run.
    pub(crate) fn produced(&self, path: &std::path::Path) {
        self.shards
            .lock()
            .expect("no panic while holding the lock")
            .insert(path.to_path_buf());
    }

    /// A frame converted and written.
    pub(crate) fn done(&self, r: &FrameReport) {
        (self.progress)(FrameOutcome::Done(r));
        self.totals().add(r);
    }

    /// `frames` frames lost to `e`.
    pub(crate) fn failed(&self, what: Failed, frames: u64, e: Error) {
        let f = FrameFailure {
            what,
            frames,
            error: e.to_string(),
        };
        (self.progress)(FrameOutcome::Failed(&f));
        self.totals().fail(f);
    }
}

/// The summary a run starts from: its parameters and what the plan found.
fn started_summary(plan: &Plan, opts: &ConvertOptions) -> ConvertSummary {
    let names = |v: &[std::path::PathBuf]| -> Vec<String> {
        v.iter().map(|p| p.to_string_lossy().into_owned()).collect()
    };
    ConvertSummary {
        version: env!("CARGO_PKG_VERSION").to_string(),
        params: opts.params.clone(),
        source: plan.layout(),
        map_origin: opts.map_origin.clone(),
        drives: (plan.drives.len() + plan.failed.len()) as u64,
        frames_planned: plan.jobs.len() as u64,
        frames_skipped: plan.skipped.clone(),
        not_frames: names(&plan.not_frames),
        labels_without_scan: names(&plan.labels_without_scan),
        unknown_object_types: plan.unknown_object_types.clone(),
        ..Default::default()
    }
}

/// The shard outputs: maps first (the primary pass, which counts the frames), then points.
fn write_shards(
    plan: &Plan,
    opts: &ConvertOptions,
    run: &Run,
    pool: &rayon::ThreadPool,
) -> Result<()> {
    use crate::format::shard::ShardKind;
    let params = &opts.params;
    let passes = [
        (ShardKind::Maps, &params.shards, true),
        (
            ShardKind::Points,
            &params.point_shards,
            params.shards.is_none(),
        ),
    ];
    for (kind, sh, primary) in passes {
        if let Some(sh) = sh {
            let pass = shards::Pass { kind, primary };
            pool.install(|| shards::convert_to_shards(plan, opts, sh, pass, run))?;
        }
    }
    Ok(())
}

/// The per-frame outputs (`.npy`, `.label`), frames in parallel; a frame the journal proves
/// finished with these parameters is kept.
fn write_frames(plan: &Plan, opts: &ConvertOptions, run: &Run, pool: &rayon::ThreadPool) {
    let one = |&(d, frame): &(usize, u32)| {
        let dp = &plan.drives[d];
        if run.keeps(run.journal.verdict(dp, frame, opts)) {
            return run.kept(1, SkipReason::Kept);
        }
        let id = dp.drive.frame_id(frame);
        let written = convert_frame(dp, frame, opts)
            .and_then(|(r, inputs)| run.journal.record(&id, &inputs).map(|_| r));
        match written {
            Ok(r) => run.done(&r),
            Err(e) => {
                // Whatever is left under the frame's names was not made by this run. (A
                // failure to remove them leaves files the journal does not list, which the
                // readers refuse.)
                let _ = resume::remove_frame_files(&id, opts);
                run.failed(Failed::Frame(id), 1, e)
            }
        }
    };
    if opts.threads == 1 {
        plan.jobs.iter().for_each(one);
    } else {
        pool.install(|| plan.jobs.par_iter().for_each(one));
    }
}

/// Removes the `.npy` / `.label` files of the frames an earlier run finished that this run did
/// not plan (their scan went, or their annotation changed so that the selection drops them):
/// they no longer match the inputs.
fn remove_unplanned_frames(plan: &Plan, opts: &ConvertOptions, run: &Run) -> Result<()> {
    let planned: std::collections::BTreeSet<_> = plan.frame_ids().collect();
    for id in run.journal.unplanned(&planned) {
        let removed = resume::remove_frame_files(&id, opts)?;
        run.totals().summary.stale_removed += removed;
    }
    Ok(())
}

/// Removes the shards this run did not write or keep (another cut of the frames, frames that
/// now fail): they would be read as part of the data.
fn remove_unproduced_shards(opts: &ConvertOptions, run: &Run) -> Result<()> {
    let produced =
        std::mem::take(&mut *run.shards.lock().expect("no panic while holding the lock"));
    for dir in [opts.out.shards_dir(), opts.out.points_dir()] {
        if !dir.is_dir() {
            continue;
        }
        for p in crate::format::layout::list_shards(&dir)? {
            if !produced.contains(&p) {
                std::fs::remove_file(&p).map_err(|source| Error::Write { path: p, source })?;
                run.totals().summary.stale_removed += 1;
            }
        }
    }
    Ok(())
}

/// Refuses an output folder over any input: the dataset (by path, and through the hard links of
/// its scans: an unpacked nuScenes root's) and the sensor's calibration table.
fn refuse_over_inputs(plan: &Plan, opts: &ConvertOptions) -> Result<()> {
    use crate::fs::Role;
    let mut inputs = vec![(Role::Dataset, plan.root.as_path())];
    if let Some(crate::sensor::params::SensorSource::File { path, .. }) =
        opts.params.map.sensor.as_ref().map(|s| &s.source)
    {
        inputs.push((Role::Calibration, path.as_path()));
    }
    crate::fs::refuse_overlap(&opts.out.root, &inputs)?;
    let scans: Vec<std::path::PathBuf> = (plan.jobs.iter())
        .map(|&(d, f)| plan.drives[d].drive.scan_path(f))
        .collect();
    crate::fs::refuse_linked(
        &opts.out.root,
        Role::Dataset,
        scans.iter().map(|p| p.as_path()),
    )
}

/// Converts every frame of `plan`, calling `progress` after each one (from worker threads).
/// A frame that fails is recorded in the summary and the others go on; the whole run fails only
/// over its folder: parameters or a class map that do not fit, an output folder over the
/// dataset, a folder that cannot be created, locked, cleaned or journalled.
pub fn convert(
    plan: &Plan,
    opts: &ConvertOptions,
    progress: &(dyn Fn(FrameOutcome<'_>) + Sync),
) -> Result<ConvertSummary> {
    let params = &opts.params;
    params.validate()?;
    plan.check_class_map(&params.map.class_map)?;
    refuse_over_inputs(plan, opts)?;
    create_dir(&opts.out.root)?;
    let _lock = resume::lock(&opts.out)?;
    let leftovers_removed = resume::remove_leftovers(&opts.out)?;
    let journal = resume::Journal::start(opts, &plan.root)?;
    if params.npy {
        create_dir(&opts.out.lidar_dir())?;
    }
    if params.labels {
        for dp in &plan.drives {
            create_dir(&opts.out.label_dir(&dp.drive.frame_id(0)))?;
        }
    }
    let n = params.map.class_map.len();
    let run = Run {
        totals: Mutex::new(Totals {
            summary: ConvertSummary {
                leftovers_removed,
                stale_removed: journal.stale_removed,
                restarted: journal.restarted,
                ..started_summary(plan, opts)
            },
            points: ClassCounts::zeros(n),
            cells: ClassCounts::zeros(n),
            changed_inputs: Default::default(),
        }),
        journal,
        shards: Mutex::default(),
        progress,
    };
    for f in &plan.failed {
        progress(FrameOutcome::Failed(f));
        run.totals().fail(f.clone());
    }
    // Recorded before any frame is written, so that an interrupted run can be resumed.
    let started = run.totals().summary.clone();
    summary::write(&opts.out.summary_path(), &started, opts.durability)?;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(opts.threads)
        .build()
        .map_err(|e| Error::Config(format!("cannot start {} threads: {e}", opts.threads)))?;
    if params.shards.is_some() || params.point_shards.is_some() {
        write_shards(plan, opts, &run, &pool)?;
    } else {
        write_frames(plan, opts, &run, &pool);
    }
    remove_unproduced_shards(opts, &run)?;
    remove_unplanned_frames(plan, opts, &run)?;
    run.journal.finish()?;
    let s = run
        .totals
        .into_inner()
        .expect("no panic while holding the lock")
        .finish();
    let s = ConvertSummary {
        complete: true,
        ..s
    };
    summary::write(&opts.out.summary_path(), &s, opts.durability)?;
    Ok(s)
}
