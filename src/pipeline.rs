//! The conversion pipeline: frame -> read -> label -> project -> write, parallel over frames.
//!
//! [`Plan::build`] finds the drives, reads each day's calibration and each drive's tracklets
//! once, and lists the frames to convert. [`convert`] runs them on a rayon pool; each frame's
//! outcome goes to a callback (the CLI's progress bar) and into a [`ConvertSummary`] that holds
//! totals only, so memory does not grow with the number of frames. A bad frame, or a drive whose
//! calibration or tracklets are broken, is reported and the rest of the batch goes on. Every
//! output is written atomically and depends only on its own frame, so the files are
//! byte-identical whatever the thread count.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

use rayon::prelude::*;
use serde::Serialize;

use crate::error::{Error, Result};
use crate::kitti::calib::Calibration;
use crate::kitti::camera::decode_image;
use crate::kitti::timestamps::{self, Timestamp};
use crate::kitti::tracklets::Tracklets;
use crate::kitti::velodyne::Scan;
use crate::kitti::{discover, Drive, FrameId};
use crate::label::{Class, LabelBox, Labeller, PointLabels};
use crate::project::camera::{CameraProjector, Sampling};
use crate::project::frame::{assemble, PgmFrame};
use crate::project::{project, PgmSpec, Projection};
use crate::report::split::{val_drives, SplitRule};
use crate::write::shard::{
    shard_is_intact, shard_name, FrameMsg, ShardCompression, ShardMetadata, ShardWriter,
};
use crate::write::viz::VizFrame;
use crate::write::{atomic_write, create_dir, label_file_bytes, npy};

/// Name of the summary that [`convert`] leaves in the output folder (read by `stats`).
pub const SUMMARY_FILE: &str = "convert_summary.json";

/// Which frames of a drive are converted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, serde::Deserialize, Default)]
pub enum FrameSelection {
    /// SqueezeSeg's selection: frames with a scan and at least one tracklet pose (any type).
    #[default]
    Annotated,
    /// Every frame with a scan.
    All,
}

impl FrameSelection {
    /// Whether a frame that has a velodyne scan is selected, given its drive's tracklets (empty
    /// when the drive has no `tracklet_labels.xml`).
    pub fn keeps(self, tracklets: &Tracklets, frame: u32) -> bool {
        self == FrameSelection::All || tracklets.count_at(frame) > 0
    }
}

/// Colour channels.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, serde::Deserialize)]
pub struct RgbOptions {
    /// Camera 2 (left colour, default) or 3 (right colour).
    pub camera: u8,
    /// Sampling rule.
    pub sampling: Sampling,
}

/// What to convert and where to.
#[derive(Debug, Clone, Serialize)]
pub struct ConvertOptions {
    /// Output folder.
    pub out_dir: PathBuf,
    /// Map shape and row rule.
    pub spec: PgmSpec,
    /// Colour channels, when wanted.
    pub rgb: Option<RgbOptions>,
    /// Frame selection.
    pub selection: FrameSelection,
    /// Write `lidar_2d/<id>.npy`.
    pub write_npy: bool,
    /// Write `labels/<drive>/<frame>.label`.
    pub write_labels: bool,
    /// Worker threads; 0 = one per core, 1 = sequential.
    pub threads: usize,
    /// Flush every file to the device before it is renamed into place (survives power cuts).
    pub sync: bool,
    /// Also write MCAP training shards.
    pub shards: Option<ShardOptions>,
}

/// MCAP shard output (`--format mcap`).
#[derive(Debug, Clone, Serialize)]
pub struct ShardOptions {
    /// Chunk compression.
    pub compression: ShardCompression,
    /// Frames per shard; `None` sizes shards to about [`SHARD_TARGET_BYTES`] of uncompressed data.
    pub frames_per_shard: Option<usize>,
    /// Add Foxglove visualisation topics.
    pub viz: bool,
    /// Which drives go to val (the same rule as `kitti2pgm split`).
    pub split: SplitRule,
}

/// Uncompressed bytes a shard is sized to when `--shard-frames` is not given.
pub const SHARD_TARGET_BYTES: usize = 256 << 20;

impl ShardOptions {
    /// Frames per shard for a map of `spec`, with or without colour.
    pub fn frames_per_shard(&self, spec: &PgmSpec, rgb: bool) -> usize {
        self.frames_per_shard.unwrap_or_else(|| {
            // tensor (5 or 8 float32) + label + instance (2) + mask (+ rgb_valid), per cell.
            let per_cell = if rgb { 8 * 4 + 5 } else { 5 * 4 + 4 };
            (SHARD_TARGET_BYTES / (spec.cells() * per_cell)).max(1)
        })
    }
}

impl ConvertOptions {
    /// Defaults: 64x512 front map, no colour, SqueezeSeg's frames, both outputs.
    pub fn new(out_dir: impl Into<PathBuf>) -> Self {
        ConvertOptions {
            out_dir: out_dir.into(),
            spec: PgmSpec::default(),
            rgb: None,
            selection: FrameSelection::Annotated,
            write_npy: true,
            write_labels: true,
            threads: 0,
            sync: false,
            shards: None,
        }
    }

    /// Checks the options.
    pub fn validate(&self) -> Result<()> {
        self.spec.validate()?;
        if !self.write_npy && !self.write_labels && self.shards.is_none() {
            return Err(Error::Config(
                "nothing to write: enable .npy, .label or shard output".into(),
            ));
        }
        if self
            .shards
            .as_ref()
            .is_some_and(|s| s.frames_per_shard == Some(0))
        {
            return Err(Error::Config("--shard-frames must be at least 1".into()));
        }
        if let Some(rgb) = &self.rgb {
            if !(rgb.camera == 2 || rgb.camera == 3) {
                return Err(Error::Config(format!(
                    "camera {} has no colour; use 2 or 3",
                    rgb.camera
                )));
            }
        }
        Ok(())
    }

    /// Path of a frame's `.npy`.
    pub fn npy_path(&self, id: &FrameId) -> PathBuf {
        crate::write::npy_path(&self.out_dir, id)
    }

    /// Path of a frame's `.label`.
    pub fn label_path(&self, drive: &Drive, frame: u32) -> PathBuf {
        crate::write::label_path(&self.out_dir, &drive.frame_id(frame))
    }
}

/// One drive, read and ready.
#[derive(Debug, Clone)]
pub struct DrivePlan {
    /// The drive.
    pub drive: Drive,
    /// Its day's calibration.
    pub calib: Arc<Calibration>,
    /// Its tracklets (empty without a `tracklet_labels.xml`).
    pub tracklets: Arc<Tracklets>,
    /// Velodyne timestamps, when the file exists.
    pub timestamps: Option<Arc<Vec<Option<Timestamp>>>>,
}

impl DrivePlan {
    /// Reads a drive's tracklets and timestamps; `calib` is its day's calibration.
    pub fn load(drive: Drive, calib: Arc<Calibration>) -> Result<DrivePlan> {
        let tpath = drive.tracklets_path();
        let tracklets = if tpath.exists() {
            Tracklets::read(&tpath)?
        } else {
            Tracklets::default()
        };
        let ts_path = drive.scan_timestamps_path();
        let timestamps = if ts_path.exists() {
            Some(Arc::new(timestamps::read(&ts_path)?))
        } else {
            None
        };
        if let Some(ts) = &timestamps {
            let len = ts.len() as u32;
            if let Some((i, t)) = tracklets
                .tracklets
                .iter()
                .enumerate()
                .find(|(_, t)| t.end_frame() > len)
            {
                return Err(Error::format(
                    &tpath,
                    format!(
                        "tracklet {i} ({}) has poses up to frame {}, past the drive's last frame {} ({} has {len} lines)",
                        t.object_type.as_str(),
                        t.end_frame() - 1,
                        len.saturating_sub(1),
                        ts_path.display()
                    ),
                ));
            }
        }
        Ok(DrivePlan {
            drive,
            calib,
            tracklets: Arc::new(tracklets),
            timestamps,
        })
    }

    /// The velodyne timestamp of a frame, when known.
    pub fn timestamp(&self, frame: u32) -> Option<Timestamp> {
        self.timestamps
            .as_ref()
            .and_then(|t| t.get(frame as usize).copied().flatten())
    }

    /// The boxes present at a frame.
    pub fn boxes(&self, frame: u32) -> Vec<LabelBox> {
        self.tracklets
            .at(frame)
            .map(|(i, t, p)| LabelBox::new(i, t, p))
            .collect()
    }
}

/// A frame that could not be converted.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FrameFailure {
    /// The frame id, or the drive name when the whole drive failed.
    pub what: String,
    /// Frames lost.
    pub frames: u64,
    /// The error, naming the file.
    pub error: String,
}

/// The work: drives and frames.
#[derive(Debug, Clone)]
pub struct Plan {
    /// Drives that could be read.
    pub drives: Vec<DrivePlan>,
    /// (index into `drives`, frame) to convert, in frame-id order.
    pub jobs: Vec<(usize, u32)>,
    /// Frames not converted by the selection, by reason.
    pub skipped: BTreeMap<String, u64>,
    /// Drives that could not be read, with their frames.
    pub failed: Vec<FrameFailure>,
}

impl Plan {
    /// Finds the drives under `root` and lists the frames `selection` picks.
    pub fn build(root: &Path, selection: FrameSelection) -> Result<Plan> {
        let mut plan = Plan {
            drives: Vec::new(),
            jobs: Vec::new(),
            skipped: BTreeMap::new(),
            failed: Vec::new(),
        };
        let mut calibs: BTreeMap<PathBuf, std::result::Result<Arc<Calibration>, String>> =
            BTreeMap::new();
        for drive in discover(root)? {
            let frames = match drive.scan_frames() {
                Ok(f) => f,
                Err(e) => {
                    plan.failed.push(FrameFailure {
                        what: drive.name(),
                        frames: 0,
                        error: e.to_string(),
                    });
                    continue;
                }
            };
            let date_dir = drive.date_dir();
            let calib = calibs
                .entry(date_dir.clone())
                .or_insert_with(|| {
                    Calibration::read_dir(&date_dir)
                        .map(Arc::new)
                        .map_err(|e| e.to_string())
                })
                .clone();
            let loaded =
                calib.and_then(|c| DrivePlan::load(drive.clone(), c).map_err(|e| e.to_string()));
            let dp = match loaded {
                Ok(dp) => dp,
                Err(error) => {
                    plan.failed.push(FrameFailure {
                        what: drive.name(),
                        frames: frames.len() as u64,
                        error,
                    });
                    continue;
                }
            };
            let index = plan.drives.len();
            let has_file = dp.drive.tracklets_path().exists();
            for &f in &frames {
                if selection.keeps(&dp.tracklets, f) {
                    plan.jobs.push((index, f));
                } else {
                    let why = if has_file {
                        "no tracklet pose at the frame"
                    } else {
                        "drive has no tracklet_labels.xml"
                    };
                    *plan.skipped.entry(why.into()).or_default() += 1;
                }
            }
            let with_scan: std::collections::BTreeSet<u32> = frames.iter().copied().collect();
            let missing = (0..dp.tracklets.end_frame())
                .filter(|f| dp.tracklets.count_at(*f) > 0 && !with_scan.contains(f))
                .count() as u64;
            if missing > 0 {
                *plan
                    .skipped
                    .entry("annotated frame without a velodyne scan".into())
                    .or_default() += missing;
            }
            plan.drives.push(dp);
        }
        Ok(plan)
    }

    /// The frame ids the plan converts, in order.
    pub fn frame_ids(&self) -> impl Iterator<Item = FrameId> + '_ {
        self.jobs
            .iter()
            .map(|&(d, f)| self.drives[d].drive.frame_id(f))
    }
}

/// Per-class counts, indexed by class id.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct ClassCounts {
    /// Background.
    pub background: u64,
    /// Car.
    pub car: u64,
    /// Pedestrian.
    pub pedestrian: u64,
    /// Cyclist.
    pub cyclist: u64,
}

impl ClassCounts {
    /// From an array indexed by class id.
    pub fn from_array(a: [u64; Class::COUNT]) -> Self {
        ClassCounts {
            background: a[0],
            car: a[1],
            pedestrian: a[2],
            cyclist: a[3],
        }
    }

    /// As an array indexed by class id.
    pub fn to_array(self) -> [u64; Class::COUNT] {
        [self.background, self.car, self.pedestrian, self.cyclist]
    }

    fn add(&mut self, o: &ClassCounts) {
        let (a, b) = (self.to_array(), o.to_array());
        *self = ClassCounts::from_array(std::array::from_fn(|k| a[k] + b[k]));
    }
}

/// What converting one frame found.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FrameReport {
    /// The frame.
    pub id: String,
    /// Finite points in the scan.
    pub points: u64,
    /// Non-finite points dropped.
    pub dropped_nonfinite: u64,
    /// Boxes of a labelled class at the frame.
    pub boxes: u64,
    /// Points per class.
    pub labelled_points: ClassCounts,
    /// Valid cells per class.
    pub labelled_cells: ClassCounts,
    /// Points in the field of view.
    pub in_fov: u64,
    /// Cells holding a point.
    pub filled_cells: u64,
    /// Points that lost their cell to a nearer one.
    pub collisions: u64,
    /// Rings found in the scan order.
    pub rings_found: u64,
    /// Rows came from elevation binning.
    pub fallback: bool,
    /// Cells with a colour.
    pub rgb_cells: u64,
}

/// The products of one frame, before writing.
#[derive(Debug, Clone)]
pub struct Converted {
    /// The map.
    pub pgm: PgmFrame,
    /// Per-point labels in file order (class ids).
    pub point_class: Vec<u8>,
    /// Per-point instance ids in file order.
    pub point_instance: Vec<u16>,
    /// What was found.
    pub report: FrameReport,
}

/// Labels and projects one scan (no file access but the image, already decoded, if any).
pub fn process(
    id: &FrameId,
    scan: &Scan,
    boxes: &[LabelBox],
    spec: &PgmSpec,
    camera: Option<(&CameraProjector, &image::RgbImage)>,
) -> Converted {
    let labeller = Labeller::new(boxes);
    let labels: PointLabels = labeller.label(&scan.points);
    let proj: Projection = project(&scan.points, spec);
    let colour_fn = camera.map(|(cam, img)| move |i: usize| cam.colour(img, &scan.points[i]));
    let pgm = assemble(
        scan,
        &labels,
        &proj,
        colour_fn
            .as_ref()
            .map(|f| f as &dyn Fn(usize) -> Option<[f32; 3]>),
    );
    let class_ids: Vec<u8> = labels.class.iter().map(|c| c.id()).collect();
    let report = FrameReport {
        id: id.to_string(),
        points: scan.len() as u64,
        dropped_nonfinite: scan.dropped.len() as u64,
        boxes: labeller.len() as u64,
        labelled_points: ClassCounts::from_array(labels.class_counts()),
        labelled_cells: ClassCounts::from_array(pgm.class_cells()),
        in_fov: proj.in_fov,
        filled_cells: proj.filled,
        collisions: proj.collisions,
        rings_found: proj.rings_found as u64,
        fallback: proj.fallback,
        rgb_cells: pgm
            .rgb_valid
            .as_ref()
            .map_or(0, |v| v.iter().map(|&b| b as u64).sum()),
    };
    Converted {
        point_class: scan.to_file_order(&class_ids, 0),
        point_instance: scan.to_file_order(&labels.instance, 0),
        pgm,
        report,
    }
}

/// A converted frame with what the shard writer needs beside it.
#[derive(Debug, Clone)]
pub struct Produced {
    /// The products.
    pub out: Converted,
    /// Visualisation payload, when asked for.
    pub viz: Option<VizFrame>,
}

/// Reads and converts one frame (no output written). `want_viz` keeps the scan points, boxes
/// and camera PNG for the visualisation topics.
pub fn produce(
    dp: &DrivePlan,
    frame: u32,
    opts: &ConvertOptions,
    want_viz: bool,
) -> Result<Produced> {
    let id = dp.drive.frame_id(frame);
    let scan = Scan::read(&dp.drive.scan_path(frame))?;
    let boxes = dp.boxes(frame);
    let mut png_bytes = None;
    let camera = match &opts.rgb {
        Some(rgb) => {
            let path = dp.drive.image_path(rgb.camera, frame);
            let bytes = std::fs::read(&path).map_err(|e| Error::io(&path, e))?;
            let img = decode_image(&bytes, &path)?;
            if want_viz {
                png_bytes = Some(bytes);
            }
            let proj = CameraProjector {
                velo_to_image: dp.calib.velo_to_image(rgb.camera as usize),
                sampling: rgb.sampling,
            };
            Some((proj, img))
        }
        None => None,
    };
    let out = process(
        &id,
        &scan,
        &boxes,
        &opts.spec,
        camera.as_ref().map(|(p, i)| (p, i)),
    );
    let viz = want_viz.then(|| {
        let class_of = |i: usize| Class::from_id(out.point_class[i]).unwrap_or_default();
        let file_idx = scan.file_indices();
        VizFrame {
            points: scan
                .points
                .iter()
                .enumerate()
                .map(|(k, p)| (*p, scan.reflectance[k], class_of(file_idx[k] as usize)))
                .collect(),
            boxes: boxes
                .into_iter()
                .filter(|b| b.class != Class::Background)
                .collect(),
            png: png_bytes,
            camera: opts.rgb.map_or(2, |r| r.camera),
        }
    });
    Ok(Produced { out, viz })
}

/// Writes a converted frame's `.npy` and `.label` files, as the options ask.
pub fn write_frame_files(
    dp: &DrivePlan,
    frame: u32,
    out: &Converted,
    opts: &ConvertOptions,
) -> Result<()> {
    if opts.write_npy {
        let p = &out.pgm;
        let bytes = npy::encode_f32(&[p.rows as u64, p.cols as u64, p.depth() as u64], &p.data);
        atomic_write(&opts.npy_path(&dp.drive.frame_id(frame)), &bytes, opts.sync)?;
    }
    if opts.write_labels {
        let path = opts.label_path(&dp.drive, frame);
        atomic_write(
            &path,
            &label_file_bytes(&out.point_class, &out.point_instance),
            opts.sync,
        )?;
    }
    Ok(())
}

/// Reads, converts and writes one frame (`.npy` and `.label` outputs).
pub fn convert_frame(dp: &DrivePlan, frame: u32, opts: &ConvertOptions) -> Result<FrameReport> {
    let p = produce(dp, frame, opts, false)?;
    write_frame_files(dp, frame, &p.out, opts)?;
    Ok(p.out.report)
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

/// Totals of a conversion.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct ConvertSummary {
    /// kitti2pgm version that wrote the files.
    pub version: String,
    /// Map shape and row rule used.
    pub spec: Option<PgmSpec>,
    /// Colour options used.
    pub rgb: Option<RgbOptions>,
    /// Frame selection used.
    pub selection: FrameSelection,
    /// Drives found.
    pub drives: u64,
    /// Frames converted and written.
    pub frames_converted: u64,
    /// Frames that failed (a failed drive counts all its scans).
    pub frames_failed: u64,
    /// Frames left out by the selection, by reason.
    pub frames_skipped: BTreeMap<String, u64>,
    /// Each failure, sorted by frame id.
    pub failures: Vec<FrameFailure>,
    /// Finite points read.
    pub points: u64,
    /// Non-finite points dropped.
    pub dropped_nonfinite: u64,
    /// Points per class.
    pub labelled_points: ClassCounts,
    /// Valid cells per class.
    pub labelled_cells: ClassCounts,
    /// Points in the field of view.
    pub in_fov: u64,
    /// Cells holding a point.
    pub filled_cells: u64,
    /// Cells in all converted maps.
    pub total_cells: u64,
    /// Points that lost their cell to a nearer one.
    pub collisions: u64,
    /// Frames whose rows came from elevation binning.
    pub ring_fallbacks: u64,
    /// Those frames' ids (sorted).
    pub fallback_frames: Vec<String>,
    /// Cells with a colour.
    pub rgb_cells: u64,
    /// Shards written.
    pub shards_written: u64,
    /// Shards left as they were (complete, intact, same frames and parameters).
    pub shards_skipped: u64,
}

impl ConvertSummary {
    fn add(&mut self, r: &FrameReport) {
        self.frames_converted += 1;
        self.points += r.points;
        self.dropped_nonfinite += r.dropped_nonfinite;
        self.labelled_points.add(&r.labelled_points);
        self.labelled_cells.add(&r.labelled_cells);
        self.in_fov += r.in_fov;
        self.filled_cells += r.filled_cells;
        self.collisions += r.collisions;
        if r.fallback {
            self.ring_fallbacks += 1;
            self.fallback_frames.push(r.id.clone());
        }
        self.rgb_cells += r.rgb_cells;
    }

    /// Filled cells over all cells.
    pub fn fill_ratio(&self) -> f64 {
        if self.total_cells == 0 {
            0.0
        } else {
            self.filled_cells as f64 / self.total_cells as f64
        }
    }
}

/// Converts every frame of `plan`, calling `progress` after each one (from worker threads).
/// Fails as a whole only when the output folder cannot be created.
pub fn convert(
    plan: &Plan,
    opts: &ConvertOptions,
    progress: &(dyn Fn(FrameOutcome<'_>) + Sync),
) -> Result<ConvertSummary> {
    opts.validate()?;
    create_dir(&opts.out_dir)?;
    if opts.write_npy {
        create_dir(&opts.out_dir.join("lidar_2d"))?;
    }
    if opts.write_labels {
        for dp in &plan.drives {
            create_dir(&opts.out_dir.join("labels").join(dp.drive.name()))?;
        }
    }
    let summary = Mutex::new(ConvertSummary {
        version: env!("CARGO_PKG_VERSION").to_string(),
        spec: Some(opts.spec),
        rgb: opts.rgb,
        selection: opts.selection,
        drives: (plan.drives.len() + plan.failed.len()) as u64,
        frames_skipped: plan.skipped.clone(),
        failures: plan.failed.clone(),
        frames_failed: plan.failed.iter().map(|f| f.frames).sum(),
        ..Default::default()
    });
    for f in &plan.failed {
        progress(FrameOutcome::Failed(f));
    }
    let add = |r: &FrameReport| {
        let mut s = summary.lock().expect("no panic while holding the lock");
        s.add(r);
        s.total_cells += opts.spec.cells() as u64;
    };
    let record_ok = |r: &FrameReport| {
        progress(FrameOutcome::Done(r));
        add(r);
    };
    let record_err = |what: String, frames: u64, e: Error| {
        let f = FrameFailure {
            what,
            frames,
            error: e.to_string(),
        };
        progress(FrameOutcome::Failed(&f));
        let mut s = summary.lock().expect("no panic while holding the lock");
        s.frames_failed += frames;
        s.failures.push(f);
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(opts.threads)
        .build()
        .map_err(|e| Error::Config(format!("cannot start {} threads: {e}", opts.threads)))?;
    if let Some(sh) = &opts.shards {
        let shards = plan_shards(plan, opts, sh)?;
        let dir = opts.out_dir.join("shards");
        create_dir(&dir)?;
        let params = serde_json::to_string(&serde_json::json!({
            "spec": opts.spec, "rgb": opts.rgb, "selection": opts.selection,
            "split": sh.split, "compression": sh.compression, "viz": sh.viz,
        }))
        .expect("parameters serialise");
        let drives: Vec<String> = plan.drives.iter().map(|d| d.drive.name()).collect();
        pool.install(|| {
            shards.par_iter().for_each(|sp| {
                let path = dir.join(shard_name(&sp.split, sp.index));
                let ids: Vec<String> = sp
                    .jobs
                    .iter()
                    .map(|&(d, f)| plan.drives[d].drive.frame_id(f).to_string())
                    .collect();
                let others_present = sp.jobs.iter().all(|&(d, f)| {
                    let dp = &plan.drives[d];
                    (!opts.write_npy || opts.npy_path(&dp.drive.frame_id(f)).is_file())
                        && (!opts.write_labels || opts.label_path(&dp.drive, f).is_file())
                });
                if others_present && shard_is_intact(&path, &ids, &params) {
                    progress(FrameOutcome::Skipped(ids.len() as u64));
                    let mut s = summary.lock().expect("no panic while holding the lock");
                    s.shards_skipped += 1;
                    *s.frames_skipped
                        .entry("already in a complete, intact shard".into())
                        .or_default() += ids.len() as u64;
                    return;
                }
                let meta = ShardMetadata {
                    version: env!("CARGO_PKG_VERSION").into(),
                    params: params.clone(),
                    drives: drives.clone(),
                    frames: ids,
                    failed: Vec::new(),
                    split: sp.split.clone(),
                };
                let frames = sp.jobs.len() as u64;
                match write_shard(plan, opts, sh, sp, &path, meta, progress, &record_err) {
                    Ok(reports) => {
                        reports.iter().for_each(add);
                        summary
                            .lock()
                            .expect("no panic while holding the lock")
                            .shards_written += 1;
                    }
                    // The shard is lost (its temporary file is removed), so are its frames.
                    Err(e) => record_err(format!("shard {}", path.display()), frames, e),
                }
            })
        });
    } else {
        let run = |&(d, frame): &(usize, u32)| {
            let dp = &plan.drives[d];
            match convert_frame(dp, frame, opts) {
                Ok(r) => record_ok(&r),
                Err(e) => record_err(dp.drive.frame_id(frame).to_string(), 1, e),
            }
        };
        if opts.threads == 1 {
            plan.jobs.iter().for_each(run);
        } else {
            pool.install(|| plan.jobs.par_iter().for_each(run));
        }
    }
    let mut s = summary
        .into_inner()
        .expect("no panic while holding the lock");
    s.failures.sort_by(|a, b| a.what.cmp(&b.what));
    s.fallback_frames.sort();
    let json = serde_json::to_vec_pretty(&s).expect("the summary serialises");
    atomic_write(&opts.out_dir.join(SUMMARY_FILE), &json, opts.sync)?;
    Ok(s)
}

/// The frames of one shard.
#[derive(Debug, Clone)]
struct ShardPlan {
    split: String,
    index: usize,
    jobs: Vec<(usize, u32)>,
}

/// Assigns each job to a split by its drive, then cuts each split into shards, in frame-id order.
fn plan_shards(plan: &Plan, opts: &ConvertOptions, sh: &ShardOptions) -> Result<Vec<ShardPlan>> {
    let mut counts: BTreeMap<(String, u32), usize> = BTreeMap::new();
    for &(d, _) in &plan.jobs {
        let drive = &plan.drives[d].drive;
        *counts
            .entry((drive.date.clone(), drive.number))
            .or_default() += 1;
    }
    let counts: Vec<_> = counts.into_iter().collect();
    let val = val_drives(&sh.split, &counts)?;
    let per_shard = sh.frames_per_shard(&opts.spec, opts.rgb.is_some());
    let mut out = Vec::new();
    for split in ["train", "val"] {
        let jobs: Vec<(usize, u32)> = plan
            .jobs
            .iter()
            .copied()
            .filter(|&(d, _)| {
                let drive = &plan.drives[d].drive;
                val.contains(&(drive.date.clone(), drive.number)) == (split == "val")
            })
            .collect();
        for (index, chunk) in jobs.chunks(per_shard).enumerate() {
            out.push(ShardPlan {
                split: split.into(),
                index,
                jobs: chunk.to_vec(),
            });
        }
    }
    Ok(out)
}

/// Converts a shard's frames (in parallel batches) and writes them in order; failed frames are
/// reported, left out and listed in the shard's metadata.
#[allow(clippy::too_many_arguments)]
fn write_shard(
    plan: &Plan,
    opts: &ConvertOptions,
    sh: &ShardOptions,
    sp: &ShardPlan,
    path: &Path,
    mut meta: ShardMetadata,
    progress: &(dyn Fn(FrameOutcome<'_>) + Sync),
    record_err: &(dyn Fn(String, u64, Error) + Sync),
) -> Result<Vec<FrameReport>> {
    let mut writer = ShardWriter::create(path, sh.compression, sh.viz)?;
    let mut reports = Vec::with_capacity(sp.jobs.len());
    let batch = rayon::current_num_threads().max(1) * 2;
    type Done = Vec<Result<(Produced, FrameMsg, u64)>>;
    let produce_batch = |jobs: &[(usize, u32)]| -> Done {
        jobs.par_iter()
            .map(|&(d, f)| {
                let dp = &plan.drives[d];
                let p = produce(dp, f, opts, sh.viz)?;
                write_frame_files(dp, f, &p.out, opts)?;
                let ts = dp.timestamp(f).map(|t| t.0.max(0) as u64);
                // Without a timestamp, frames are spaced at the scanner's 10 Hz.
                let log_time = ts.unwrap_or(f as u64 * 100_000_000);
                let msg = FrameMsg::from_frame(
                    &p.out.pgm,
                    &p.out.report.id,
                    &dp.drive.name(),
                    f,
                    ts.unwrap_or(0),
                    &sp.split,
                );
                Ok((p, msg, log_time))
            })
            .collect()
    };
    // Appends a finished batch in frame order (sequential: the writer compresses here).
    let mut write_batch =
        |done: Done, jobs: &[(usize, u32)], meta: &mut ShardMetadata| -> Result<()> {
            for (r, &(d, f)) in done.into_iter().zip(jobs) {
                match r {
                    Ok((p, msg, log_time)) => {
                        writer.write(&msg, log_time, p.viz.as_ref())?;
                        progress(FrameOutcome::Done(&p.out.report));
                        reports.push(p.out.report);
                    }
                    Err(e) => {
                        let id = plan.drives[d].drive.frame_id(f).to_string();
                        meta.failed.push(id.clone());
                        record_err(id, 1, e);
                    }
                }
            }
            Ok(())
        };
    // Pipeline: batch k is written (compressed) while batch k + 1 is produced.
    let mut pending: Option<(Done, &[(usize, u32)])> = None;
    for jobs in sp.jobs.chunks(batch) {
        let (written, done) = rayon::join(
            || match pending.take() {
                Some((d, j)) => write_batch(d, j, &mut meta),
                None => Ok(()),
            },
            || produce_batch(jobs),
        );
        written?;
        pending = Some((done, jobs));
    }
    if let Some((d, j)) = pending.take() {
        write_batch(d, j, &mut meta)?;
    }
    writer.finish(&meta)?;
    Ok(reports)
}
