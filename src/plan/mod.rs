//! PLAN: what a conversion will do, before any point is read.
//!
//! [`Plan::build`] finds the drives, reads each day's calibration and each drive's tracklets
//! once, and lists the frames that the [`selection`] rule picks; [`split`] assigns drives to
//! train and val. Both rules live here, on the input side, so that `convert`, `split` and the
//! shards share them. A drive whose calibration or tracklets are broken is listed as failed with
//! its frames, and the rest of the plan goes on.

pub mod selection;
pub mod split;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::fs::Inputs;
use crate::geom::Matrix3x4;
use crate::label::{label_boxes, ClassMap, LabelBox};
use crate::source::boxes::BoxSource;
use crate::source::kitti::calib::{Calibration, FrameCalib};
use crate::source::kitti::timestamps::{self, Timestamp};
use crate::source::kitti::tracklets::Tracklets;
use crate::source::kitti::{discover_as, DatasetKind, Drive, FrameId};
pub use selection::{FrameSelection, Reconverted, Restart, SkipReason};

/// A day's calibration (or why it could not be read), and the files read for it.
type DayCalibration = (std::result::Result<Arc<Calibration>, String>, Inputs);

/// Each recording day's calibration, read once (or why it could not be).
struct DayCalibrations(BTreeMap<PathBuf, DayCalibration>);

impl DayCalibrations {
    fn new() -> Self {
        DayCalibrations(BTreeMap::new())
    }

    /// The calibration of the day folder `date_dir`.
    fn of(&mut self, date_dir: &Path) -> DayCalibration {
        self.0
            .entry(date_dir.to_path_buf())
            .or_insert_with(|| {
                let (c, inputs) = crate::fs::recording(|| Calibration::read_dir(date_dir));
                (c.map(Arc::new).map_err(|e| e.to_string()), inputs)
            })
            .clone()
    }
}

/// One drive, read and ready.
#[derive(Debug, Clone)]
pub struct DrivePlan {
    /// The drive.
    pub drive: Drive,
    /// Its day's calibration (raw drives; sequences and object frames read theirs per frame,
    /// [`DrivePlan::camera`]).
    pub calib: Option<Arc<Calibration>>,
    /// Why a raw drive's day calibration could not be read: only colour needs it (the tracklet
    /// boxes are in the velodyne frame), so the drive converts without `--rgb` and its frames
    /// fail with this error with it.
    pub calib_error: Option<String>,
    /// Its boxes: a raw drive's tracklets (none without a `tracklet_labels.xml`).
    pub boxes: Arc<dyn BoxSource>,
    /// Velodyne timestamps, when the file exists.
    pub timestamps: Option<Arc<Vec<Option<Timestamp>>>>,
    /// The drive's own files every frame depends on (tracklets, timestamps; read or found
    /// absent), fingerprinted: part of each frame's inputs.
    pub inputs: Inputs,
    /// The files of the day calibration (raw), part of the inputs of a frame that uses it.
    pub calib_inputs: Inputs,
}

impl DrivePlan {
    /// Reads a drive's tracklets and timestamps (raw; none elsewhere), recording them in
    /// [`DrivePlan::inputs`]; `calib` is its day's calibration (raw).
    pub fn load(drive: Drive, calib: Option<Arc<Calibration>>) -> Result<DrivePlan> {
        let (dp, inputs) = crate::fs::recording(|| DrivePlan::read(drive, calib));
        Ok(DrivePlan { inputs, ..dp? })
    }

    fn read(drive: Drive, calib: Option<Arc<Calibration>>) -> Result<DrivePlan> {
        let tpath = drive.tracklets_path();
        let tracklets = if crate::fs::present(&tpath) {
            Tracklets::read(&tpath)?
        } else {
            Tracklets::default()
        };
        let ts_path = drive.scan_timestamps_path();
        let timestamps = if crate::fs::present(&ts_path) {
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
            calib_error: None,
            boxes: Arc::new(tracklets),
            timestamps,
            inputs: Inputs::default(),
            calib_inputs: Inputs::default(),
        })
    }

    /// The velodyne timestamp of a frame, when known.
    pub fn timestamp(&self, frame: u32) -> Option<Timestamp> {
        self.timestamps
            .as_ref()
            .and_then(|t| t.get(frame as usize).copied().flatten())
    }

    /// The camera `camera` at `frame`: homogeneous velodyne points to homogeneous pixels, the
    /// image size it is calibrated for (raw: `S_rect`; unknown elsewhere), and the
    /// calibration file (for errors).
    pub fn camera(&self, frame: u32, camera: u8) -> Result<(Matrix3x4, Option<[f64; 2]>, PathBuf)> {
        match &self.calib {
            Some(c) => {
                crate::fs::note(&self.calib_inputs);
                let size = c.cam_to_cam.cameras[camera as usize].size_rect;
                let file = self
                    .drive
                    .date_dir()
                    .join(crate::source::kitti::calib::CAM_TO_CAM);
                Ok((
                    c.velo_to_image(camera as usize),
                    Some([size.x, size.y]),
                    file,
                ))
            }
            None if self.drive.dataset == DatasetKind::Raw => Err(Error::Input {
                path: self.drive.date_dir(),
                message: format!(
                    "colour needs the day's calibration: {}",
                    self.calib_error.as_deref().unwrap_or("not read")
                ),
            }),
            None => {
                let file = self.drive.calib_path(frame);
                let c = FrameCalib::read(&file)?;
                Ok((c.velo_to_image(camera as usize), None, file))
            }
        }
    }

    /// The boxes present at a frame, classed by `map`.
    pub fn label_boxes(&self, frame: u32, map: &ClassMap) -> Vec<LabelBox> {
        label_boxes(&self.boxes.boxes_at(frame), map)
    }
}

/// What failed. Written as one string (`convert_summary.json`'s `what`: the frame id, the
/// drive name, the folder, `shard <path>`) and read back from it.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(into = "String", from = "String")]
pub enum Failed {
    /// One frame.
    Frame(FrameId),
    /// A whole drive, sequence or split, by name.
    Drive(String),
    /// A folder that could not be read as a drive.
    Folder(PathBuf),
    /// A shard, with the frames it held.
    Shard(PathBuf),
}

impl std::fmt::Display for Failed {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Failed::Frame(id) => write!(f, "{id}"),
            Failed::Drive(name) => f.write_str(name),
            Failed::Folder(p) => write!(f, "{}", p.to_string_lossy()),
            Failed::Shard(p) => write!(f, "shard {}", p.display()),
        }
    }
}

impl From<Failed> for String {
    fn from(f: Failed) -> String {
        f.to_string()
    }
}

impl From<String> for Failed {
    fn from(s: String) -> Failed {
        if let Some(p) = s.strip_prefix("shard ") {
            return Failed::Shard(p.into());
        }
        if let Ok(id) = s.parse::<FrameId>() {
            return Failed::Frame(id);
        }
        let drive = crate::source::kitti::parse_drive_name(&s).is_some()
            || s == "object"
            || crate::source::kitti::sequence_number(&s).is_some();
        if drive {
            Failed::Drive(s)
        } else {
            Failed::Folder(s.into())
        }
    }
}

/// A frame that could not be converted.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FrameFailure {
    /// What failed: a frame, a whole drive, a folder, a shard.
    pub what: Failed,
    /// Frames lost.
    pub frames: u64,
    /// The error, naming the file.
    pub error: String,
}

/// The work: drives and frames.
#[derive(Debug, Clone)]
pub struct Plan {
    /// The dataset root it was built from, as given.
    pub root: PathBuf,
    /// Drives that could be read.
    pub drives: Vec<DrivePlan>,
    /// (index into `drives`, frame) to convert, in frame-id order.
    pub jobs: Vec<(usize, u32)>,
    /// Frames not converted by the selection, by reason.
    pub skipped: BTreeMap<SkipReason, u64>,
    /// Drives that could not be read, with their frames.
    pub failed: Vec<FrameFailure>,
    /// Files in velodyne folders that are not `<frame10>.bin` scans: skipped, and named.
    pub not_frames: Vec<PathBuf>,
    /// Label files that belong to no scan (SemanticKITTI, object set), named.
    pub labels_without_scan: Vec<PathBuf>,
    /// Tracklets whose object type KITTI does not define, by type: the class map decides what
    /// they become (background, unless it lists the type), and the summary names them.
    pub unknown_object_types: BTreeMap<String, u64>,
}

impl Plan {
    /// Checks that `map` has a rule for the annotations of every drive of the plan
    /// ([`ClassMap::can_label`](crate::label::ClassMap::can_label)): a map that cannot label the
    /// source would make every point background.
    pub fn check_class_map(&self, map: &crate::label::ClassMap) -> Result<()> {
        let Some(dp) = self
            .drives
            .iter()
            .find(|dp| !map.can_label(dp.drive.dataset))
        else {
            return Ok(());
        };
        Err(Error::Config(format!(
            "class map {:?} has no rule for the annotations of {} ({}): every point would be {:?}; use a class map made for this source",
            map.name,
            dp.drive.dir.display(),
            match dp.drive.dataset {
                crate::source::kitti::DatasetKind::Sequence => "per-point labels need a learning_map",
                _ => "boxes need object types mapped to classes",
            },
            map.name(map.background)
        )))
    }

    /// Finds the drives under `root` and lists the frames `selection` picks.
    pub fn build(root: &Path, selection: FrameSelection) -> Result<Plan> {
        Plan::build_as(root, selection, None)
    }

    /// Like [`Plan::build`], for the layout `source` when given (else the one found). Frames of
    /// sequences and of the object set are all selected (their labels are per frame; a frame
    /// without labels converts with label 0, and the summary says so).
    pub fn build_as(
        root: &Path,
        selection: FrameSelection,
        source: Option<DatasetKind>,
    ) -> Result<Plan> {
        let mut plan = Plan {
            root: root.to_path_buf(),
            drives: Vec::new(),
            jobs: Vec::new(),
            skipped: BTreeMap::new(),
            failed: Vec::new(),
            not_frames: Vec::new(),
            labels_without_scan: Vec::new(),
            unknown_object_types: BTreeMap::new(),
        };
        let mut calibs = DayCalibrations::new();
        let found = discover_as(root, source)?;
        for (path, why) in found.problems {
            plan.failed.push(FrameFailure {
                what: Failed::Folder(path.clone()),
                frames: 0,
                error: format!("{}: {why}", path.to_string_lossy()),
            });
        }
        for drive in found.drives {
            let Some(frames) = plan.list_frames(&drive) else {
                continue;
            };
            let calib = (drive.dataset == DatasetKind::Raw).then(|| calibs.of(&drive.date_dir()));
            // A raw day without a readable calibration still converts without colour.
            let (calib, calib_error, calib_inputs) = match calib {
                Some((Ok(c), inputs)) => (Some(c), None, inputs),
                Some((Err(e), inputs)) => (None, Some(e), inputs),
                None => (None, None, Inputs::default()),
            };
            let loaded = DrivePlan::load(drive.clone(), calib).map(|dp| DrivePlan {
                calib_error,
                calib_inputs,
                ..dp
            });
            match loaded {
                Ok(dp) => plan.add_drive(dp, &frames, selection),
                Err(e) => plan.failed.push(FrameFailure {
                    what: Failed::Drive(drive.name()),
                    frames: frames.len() as u64,
                    error: e.to_string(),
                }),
            }
        }
        Ok(plan)
    }

    /// A drive's scans; files that are not scans and label files without a scan are noted.
    /// `None` (and the drive failed) when its folder cannot be listed.
    fn list_frames(&mut self, drive: &Drive) -> Option<Vec<u32>> {
        let listing = match drive.scan_listing() {
            Ok(l) => l,
            Err(e) => {
                self.failed.push(FrameFailure {
                    what: Failed::Drive(drive.name()),
                    frames: 0,
                    error: e.to_string(),
                });
                return None;
            }
        };
        self.not_frames.extend(listing.not_frames);
        match drive.labels_without_scan(&listing.frames) {
            Ok(extra) => self.labels_without_scan.extend(extra),
            Err(e) => self.failed.push(FrameFailure {
                what: Failed::Drive(drive.name()),
                frames: 0,
                error: e.to_string(),
            }),
        }
        Some(listing.frames)
    }

    /// Adds a loaded drive: its frames the selection keeps become jobs, the others are
    /// counted by reason, with the annotated frames that have no scan.
    fn add_drive(&mut self, dp: DrivePlan, frames: &[u32], selection: FrameSelection) {
        for name in dp.boxes.unknown_types() {
            *self.unknown_object_types.entry(name).or_default() += 1;
        }
        let index = self.drives.len();
        let raw = dp.drive.dataset == DatasetKind::Raw;
        let why = if crate::fs::present(&dp.drive.tracklets_path()) {
            SkipReason::NoPose
        } else {
            SkipReason::NoTrackletFile
        };
        for &f in frames {
            if !raw || selection.keeps(dp.boxes.as_ref(), f) {
                self.jobs.push((index, f));
            } else {
                *self.skipped.entry(why).or_default() += 1;
            }
        }
        let with_scan: std::collections::BTreeSet<u32> = frames.iter().copied().collect();
        let missing = (0..dp.boxes.end_frame())
            .filter(|f| dp.boxes.count_at(*f) > 0 && !with_scan.contains(f))
            .count() as u64;
        if missing > 0 {
            *self
                .skipped
                .entry(SkipReason::AnnotatedWithoutScan)
                .or_default() += missing;
        }
        self.drives.push(dp);
    }

    /// The layout of the plan's drives (raw when it has none).
    pub fn layout(&self) -> DatasetKind {
        self.drives
            .first()
            .map_or(DatasetKind::Raw, |d| d.drive.dataset)
    }

    /// The frame ids the plan converts, in order.
    pub fn frame_ids(&self) -> impl Iterator<Item = FrameId> + '_ {
        self.jobs
            .iter()
            .map(|&(d, f)| self.drives[d].drive.frame_id(f))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn what_failed_round_trips_through_its_string() {
        for f in [
            Failed::Frame("2011_09_26_0001_0000000010".parse().unwrap()),
            Failed::Frame("00_000007".parse().unwrap()),
            Failed::Drive("2011_09_26_drive_0001_sync".into()),
            Failed::Drive("08".into()),
            Failed::Drive("object".into()),
            Failed::Folder("/data/kitti/2011_09_26/odd".into()),
            Failed::Shard("out/shards/train-00000.mcap".into()),
        ] {
            let json = serde_json::to_string(&f).unwrap();
            assert_eq!(serde_json::from_str::<Failed>(&json).unwrap(), f, "{json}");
        }
        assert_eq!(Failed::Shard("a.mcap".into()).to_string(), "shard a.mcap");
    }
}
