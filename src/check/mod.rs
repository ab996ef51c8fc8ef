//! CHECK: a linter for the inputs, before anyone trains on them.
//!
//! [`check`] reads a source `convert` reads (KITTI raw, SemanticKITTI, the KITTI object set; or
//! a folder of raw drive folders holding only their `tracklet_labels.xml`) and returns
//! [`Finding`]s: a [`Severity`], the [`CheckName`], the file, the frame, the object and one line
//! of explanation. Each check is one module; thresholds are typed and tunable
//! ([`Thresholds`]); `docs/check.md` states every rule. The checks that need the scans
//! ([`CheckName::needs_scans`]) read each scan once, in parallel over frames; the rest read
//! only annotations, calibration and file lists.

mod calibration;
mod imported;
mod inventory;
mod layouts;
mod model_labels;
mod names;
mod picture;
mod read;
mod scans;
mod semantic;
mod splits;
mod thresholds;
mod tracklets;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::Serialize;

pub use calibration::Alignment;
pub use names::{CheckName, Severity};
pub use picture::Pictures;
pub use thresholds::{SizeRange, Thresholds};

use crate::error::Result;
use crate::source::kitti::DatasetKind;

/// The object a finding is about: its index in the file (tracklet number, `label_2` line,
/// SemanticKITTI instance id) and its type.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord, Serialize)]
pub struct ObjectRef {
    /// Tracklet index (0-based, file order), object line (0-based) or instance id.
    pub index: u32,
    /// Object type (`Car`, `Pedestrian`, ...) or class name.
    pub kind: String,
}

/// One thing found wrong, or likely wrong.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Finding {
    /// How bad.
    pub severity: Severity,
    /// Which check found it.
    pub check: CheckName,
    /// The file that is wrong (or the folder, for a missing file).
    pub file: PathBuf,
    /// The drive or sequence (`2011_09_26_drive_0001_sync`, `00`, `object`).
    pub drive: String,
    /// The frame, when the finding is about one (the first frame of a range).
    pub frame: Option<u32>,
    /// The object, when the finding is about one.
    pub object: Option<ObjectRef>,
    /// One line: what is wrong, with the values and the threshold.
    pub message: String,
}

/// What `check` looked at in one drive, sequence or split.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct DriveInventory {
    /// Drive name.
    pub drive: String,
    /// Velodyne scans.
    pub scans: usize,
    /// Camera images per camera folder present (`image_02`: count).
    pub images: BTreeMap<String, usize>,
    /// Lines of the velodyne timestamps (raw) or `times.txt` (sequences), when present.
    pub timestamps: Option<usize>,
    /// OXTS files (raw) or `poses.txt` lines (sequences), when present.
    pub poses: Option<usize>,
    /// Label files (SemanticKITTI `.label`, object `label_2`), when the layout has them.
    pub label_files: Option<usize>,
    /// Frames with at least one annotation (tracklet pose, label file).
    pub annotated: usize,
    /// First and last annotated frame.
    pub annotated_range: Option<(u32, u32)>,
    /// Scans read by the scan checks.
    pub scans_read: usize,
    /// Share of the front points that land inside camera 2's image (scan checks).
    pub camera_overlap: Option<f64>,
    /// Camera/LiDAR alignment (scan checks, with images).
    pub alignment: Option<Alignment>,
}

/// The whole result.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct CheckReport {
    /// Version of this JSON shape.
    pub version: u32,
    /// The root checked.
    pub root: PathBuf,
    /// Its layout.
    pub layout: DatasetKind,
    /// Checks run, in order.
    pub checks: Vec<CheckName>,
    /// Per drive: what was there.
    pub drives: Vec<DriveInventory>,
    /// Everything found, sorted by check, drive, frame and object.
    pub findings: Vec<Finding>,
}

impl CheckReport {
    /// Number of findings of `severity`.
    pub fn count(&self, severity: Severity) -> usize {
        self.findings
            .iter()
            .filter(|f| f.severity == severity)
            .count()
    }

    /// The worst severity found, if any.
    pub fn worst(&self) -> Option<Severity> {
        self.findings.iter().map(|f| f.severity).max()
    }
}

/// What to check and how.
#[derive(Debug, Clone)]
pub struct CheckOptions {
    /// The layout, when not the one the root shows.
    pub layout: Option<DatasetKind>,
    /// Checks switched off.
    pub skip: Vec<CheckName>,
    /// Read the scans (the checks that need them); false: annotations, calibration and file
    /// lists only.
    pub scans: bool,
    /// The split to check balance and leaks against: ImageSet `train.txt` and `val.txt` in this
    /// folder; `None`: the layout's default split rule.
    pub imageset: Option<PathBuf>,
    /// The thresholds.
    pub thresholds: Thresholds,
    /// The class map whose yaml the per-point label ids are checked against (`None`: the one
    /// `kitti2pgm label` recorded beside the labels, else SemanticKITTI's own).
    pub class_map: Option<crate::label::ClassMap>,
    /// The sensor whose beam model the points of scans without a ring field are checked
    /// against (`beam-model`); `None`: not checked.
    pub sensor: Option<crate::sensor::SensorParams>,
}

impl Default for CheckOptions {
    fn default() -> Self {
        CheckOptions {
            layout: None,
            skip: Vec::new(),
            scans: true,
            imageset: None,
            thresholds: Thresholds::default(),
            class_map: None,
            sensor: None,
        }
    }
}

impl CheckOptions {
    /// Whether `check` runs.
    pub fn runs(&self, check: CheckName) -> bool {
        !self.skip.contains(&check) && (self.scans || !check.needs_scans())
    }
}

/// Findings of one drive, and what it held.
pub(crate) struct Collector<'a> {
    drive: String,
    pub(crate) opts: &'a CheckOptions,
    findings: Vec<Finding>,
    /// Camera/LiDAR alignment of the drive, when judged.
    pub(crate) alignment: Option<Alignment>,
    /// Share of front points in the image, when judged.
    pub(crate) overlap: Option<f64>,
}

impl<'a> Collector<'a> {
    pub(crate) fn new(drive: &str, opts: &'a CheckOptions) -> Collector<'a> {
        Collector {
            drive: drive.to_string(),
            opts,
            findings: Vec::new(),
            alignment: None,
            overlap: None,
        }
    }

    /// Adds a finding when its check runs.
    pub(crate) fn add(
        &mut self,
        check: CheckName,
        severity: Severity,
        file: &Path,
        frame: Option<u32>,
        object: Option<ObjectRef>,
        message: String,
    ) {
        if self.opts.runs(check) {
            self.findings.push(Finding {
                severity,
                check,
                file: file.to_path_buf(),
                drive: self.drive.clone(),
                frame,
                object,
                message,
            });
        }
    }

    pub(crate) fn t(&self) -> &Thresholds {
        &self.opts.thresholds
    }
}

/// Frame numbers as ranges: `0-5, 25, 45` (sorted input).
pub fn frame_ranges(frames: &[u32]) -> String {
    let mut out: Vec<String> = Vec::new();
    let mut i = 0;
    while i < frames.len() {
        let mut j = i;
        while j + 1 < frames.len() && frames[j + 1] == frames[j] + 1 {
            j += 1;
        }
        out.push(if i == j {
            frames[i].to_string()
        } else {
            format!("{}-{}", frames[i], frames[j])
        });
        i = j + 1;
    }
    out.join(", ")
}

/// Runs every check in `opts` on `root`; `progress` is told of each scan read. The checks of
/// one drive failing to read a file become findings; only a root that holds nothing to check
/// is an error.
pub fn check(
    root: &Path,
    opts: &CheckOptions,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<CheckReport> {
    let drives = inventory::drives(root, opts.layout)?;
    let layout = drives.first().map(|d| d.dataset).unwrap_or_default();
    let mut report = CheckReport {
        version: 1,
        root: root.to_path_buf(),
        layout,
        checks: CheckName::ALL
            .iter()
            .copied()
            .filter(|c| opts.runs(*c) && c.applies_to(layout))
            .collect(),
        ..Default::default()
    };
    let mut annotations = Vec::new();
    for drive in &drives {
        let mut c = Collector::new(&drive.name(), opts);
        let mut read = inventory::read_drive(drive, &mut c);
        imported::load(&mut read, &mut c);
        tracklets::check(&read, &mut c);
        imported::check(&read, &mut c);
        calibration::check_files(&read, &mut c);
        let labelled = semantic::check_labels(&read, &mut c);
        model_labels::check(&read, &mut c);
        let mut inv = read.inventory.clone();
        if CheckName::ALL
            .iter()
            .any(|k| k.needs_scans() && opts.runs(*k))
        {
            inv.scans_read = scans::check(&read, &mut c, progress);
        }
        inv.alignment = c.alignment;
        inv.camera_overlap = c.overlap;
        annotations.push(splits::DriveAnnotations::of(&read, labelled));
        report.drives.push(inv);
        report.findings.extend(c.findings);
    }
    let mut c = Collector::new("", opts);
    splits::check(&annotations, opts, &mut c);
    report.findings.extend(c.findings);
    report.findings.sort_by(|a, b| {
        (a.check, &a.drive, a.frame, &a.object, &a.file, &a.message)
            .cmp(&(b.check, &b.drive, b.frame, &b.object, &b.file, &b.message))
    });
    Ok(report)
}
