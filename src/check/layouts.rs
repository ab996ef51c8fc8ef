//! Each layout's own files: raw drives (tracklets, day calibration, timestamps, OXTS), sequences
//! (calib.txt, poses, times, per-point labels) and the object set (label_2, calib), read into
//! the [`DriveRead`] and compared with the scans.

use super::read::{frames_in, missing, read_or_note, DriveRead, LayoutRead};
use super::{frame_ranges, CheckName as C, Collector, Severity as S};
use crate::geom::Matrix3x4;
use crate::source::kitti::calib::{Calibration, FrameCalib, CAM_TO_CAM, VELO_TO_CAM};
use crate::source::kitti::object;
use crate::source::kitti::timestamps::{self, Timestamp};
use crate::source::kitti::tracklets::Tracklets;
use crate::source::kitti::{poses, Drive};

/// A raw drive's velodyne timestamps and OXTS records, the latter compared with the scans.
fn read_raw_records(
    drive: &Drive,
    r: &mut DriveRead,
    c: &mut Collector,
) -> Option<Vec<Option<Timestamp>>> {
    let ts = drive.scan_timestamps_path();
    let mut read = None;
    if crate::fs::present(&ts) {
        read = read_or_note(c, C::Read, &ts, timestamps::read(&ts));
        r.inventory.timestamps = read.as_ref().map(Vec::len);
    }
    let oxts = drive.dir.join("oxts/data");
    if oxts.is_dir() {
        let frames = frames_in(&oxts, 10, ".txt");
        r.inventory.poses = Some(frames.len());
        let scans: Vec<u32> = r.scans.keys().copied().collect();
        let what = "scans without an OXTS record";
        missing(c, C::Inventory, S::Warning, &oxts, &scans, &frames, what);
    }
    read
}

pub(crate) fn read_raw(drive: &Drive, r: &mut DriveRead, c: &mut Collector) {
    let tpath = drive.tracklets_path();
    let tracklets = if crate::fs::present(&tpath) {
        read_or_note(c, C::Read, &tpath, Tracklets::read(&tpath))
    } else {
        c.add(
            C::Inventory,
            S::Warning,
            &tpath,
            None,
            None,
            "no tracklet_labels.xml: every point of this drive would be background".into(),
        );
        None
    };
    let date = drive.date_dir();
    let calib = if [CAM_TO_CAM, VELO_TO_CAM]
        .iter()
        .all(|f| crate::fs::present(&date.join(f)))
    {
        read_or_note(c, C::Calibration, &date, Calibration::read_dir(&date)).map(Box::new)
    } else {
        if !r.scans.is_empty() {
            c.add(C::Inventory, S::Note, &date, None, None,
                format!("no {CAM_TO_CAM} / {VELO_TO_CAM} beside the drive: no colour channels, no camera checks"));
        }
        None
    };
    let timestamps = read_raw_records(drive, r, c);
    if let Some(t) = &tracklets {
        raw_coverage(drive, r, t, c);
    }
    r.layout = LayoutRead::Raw {
        tracklets,
        timestamps,
        calib,
    };
}

/// A raw drive's annotation compared with its timestamps and scans.
fn raw_coverage(drive: &Drive, r: &mut DriveRead, t: &Tracklets, c: &mut Collector) {
    let annotated: Vec<u32> = (0..t.end_frame()).filter(|&f| t.count_at(f) > 0).collect();
    r.inventory.annotated = annotated.len();
    r.inventory.annotated_range = annotated
        .first()
        .zip(annotated.last())
        .map(|(a, b)| (*a, *b));
    let (ts, tpath) = (drive.scan_timestamps_path(), drive.tracklets_path());
    if let Some(n) = r.inventory.timestamps {
        let all: Vec<u32> = (0..n as u32).collect();
        let scans: Vec<u32> = r.scans.keys().copied().collect();
        if !scans.is_empty() {
            missing(
                c,
                C::Inventory,
                S::Warning,
                &ts,
                &all,
                &scans,
                &format!("frames listed in the timestamps ({n}) have no scan"),
            );
        }
        if t.end_frame() as usize > n {
            c.add(
                C::Coverage,
                S::Error,
                &tpath,
                Some(n as u32),
                None,
                format!(
                    "tracklets reach frame {}, past the drive's {n} frames (timestamps)",
                    t.end_frame() - 1
                ),
            );
        }
    }
    coverage_raw(drive, r, &annotated, c);
}

fn coverage_raw(drive: &Drive, r: &DriveRead, annotated: &[u32], c: &mut Collector) {
    if r.scans.is_empty() {
        return;
    }
    let scans: Vec<u32> = r.scans.keys().copied().collect();
    let dir = drive.dir.join("velodyne_points/data");
    missing(
        c,
        C::Coverage,
        S::Warning,
        &dir,
        annotated,
        &scans,
        "annotated frames have no scan (their labels cannot be used)",
    );
    if let Some(&last) = annotated.last() {
        let beyond: Vec<u32> = scans.iter().copied().filter(|&f| f > last).collect();
        if let Some(&first) = beyond.first() {
            c.add(C::Coverage, S::Warning, &drive.tracklets_path(), Some(first), None,
                format!("the annotation ends at frame {last}, but {} scans follow: frames {} (all background if every scan is converted)",
                    beyond.len(), frame_ranges(&beyond)));
        }
    }
}

/// A sequence's `poses.txt` and `times.txt`, each compared with the scans (up to `last`).
fn read_sequence_poses(
    drive: &Drive,
    r: &mut DriveRead,
    c: &mut Collector,
    last: Option<u32>,
) -> Option<Vec<Matrix3x4>> {
    let pose_path = drive.dir.join("poses.txt");
    let mut read = None;
    if crate::fs::present(&pose_path) {
        read = read_or_note(c, C::Read, &pose_path, poses::read(&pose_path));
        r.inventory.poses = read.as_ref().map(Vec::len);
    }
    let times = drive.dir.join(crate::source::kitti::sequence::TIMES);
    if crate::fs::present(&times) {
        r.inventory.timestamps = read_or_note(c, C::Read, &times, poses::count_lines(&times));
    }
    for (what, n, path) in [
        ("poses", r.inventory.poses, &pose_path),
        ("times", r.inventory.timestamps, &times),
    ] {
        if let (Some(n), Some(last)) = (n, last) {
            if n as u32 <= last {
                c.add(
                    C::Inventory,
                    S::Warning,
                    path,
                    Some(n as u32),
                    None,
                    format!("{n} {what} for scans up to frame {last}"),
                );
            }
        }
    }
    read
}

/// Label files whose size is not 4 bytes per point of their scan (from the sizes alone).
fn label_counts(drive: &Drive, r: &DriveRead, label_frames: &[u32], c: &mut Collector) {
    for &f in label_frames {
        let Some(&points) = r.scans.get(&f) else {
            continue;
        };
        let path = drive.point_labels_path(f);
        if let Ok(m) = std::fs::metadata(&path) {
            let n = m.len() as usize / 4;
            if m.len() % 4 != 0 || n != points {
                c.add(
                    C::LabelCount,
                    S::Error,
                    &path,
                    Some(f),
                    None,
                    format!(
                        "{} bytes = {n} labels for a scan of {points} points",
                        m.len()
                    ),
                );
            }
        }
    }
}

pub(crate) fn read_sequence(drive: &Drive, r: &mut DriveRead, c: &mut Collector) {
    let calib_path = drive.calib_path(0);
    let calib = if crate::fs::present(&calib_path) {
        read_or_note(
            c,
            C::Calibration,
            &calib_path,
            FrameCalib::read(&calib_path).map(Box::new),
        )
    } else {
        // Another sensor's recording (`--sensor`) often has no camera: a note, not a warning.
        let severity = match c.opts.sensor {
            Some(_) => S::Note,
            None => S::Warning,
        };
        c.add(
            C::Inventory,
            severity,
            &calib_path,
            None,
            None,
            "no calib.txt: colour and the camera checks are not possible".into(),
        );
        None
    };
    let scans: Vec<u32> = r.scans.keys().copied().collect();
    let poses = read_sequence_poses(drive, r, c, scans.last().copied());
    let label_frames = sequence_labels(drive, r, &scans, c);
    r.layout = LayoutRead::Sequence {
        calib,
        poses,
        label_frames,
    };
}

/// A sequence's label files (their frames; none without a labels/ folder) compared with its
/// scans `scans`.
fn sequence_labels(drive: &Drive, r: &mut DriveRead, scans: &[u32], c: &mut Collector) -> Vec<u32> {
    let labels = drive.dir.join("labels");
    if !labels.is_dir() {
        c.add(
            C::Coverage,
            S::Note,
            &labels,
            None,
            None,
            "no labels/ folder (a test sequence): nothing to train on".into(),
        );
        return Vec::new();
    }
    let label_frames = frames_in(&labels, 6, ".label");
    r.inventory.label_files = Some(label_frames.len());
    r.inventory.annotated = label_frames.len();
    r.inventory.annotated_range = label_frames
        .first()
        .zip(label_frames.last())
        .map(|(a, b)| (*a, *b));
    missing(
        c,
        C::Coverage,
        S::Warning,
        &labels,
        scans,
        &label_frames,
        "scans have no label file",
    );
    extra_labels(drive, scans, c);
    label_counts(drive, r, &label_frames, c);
    label_frames
}

fn extra_labels(drive: &Drive, scans: &[u32], c: &mut Collector) {
    match drive.labels_without_scan(scans) {
        Ok(extra) => {
            for p in extra {
                c.add(
                    C::Inventory,
                    S::Warning,
                    &p,
                    None,
                    None,
                    "a label file without a scan".into(),
                );
            }
        }
        Err(e) => c.add(C::Read, S::Error, &drive.dir, None, None, e.to_string()),
    }
}

pub(crate) fn read_object(drive: &Drive, r: &mut DriveRead, c: &mut Collector) {
    let scans: Vec<u32> = r.scans.keys().copied().collect();
    let labels = frames_in(&drive.dir.join("label_2"), 6, ".txt");
    let calibs = frames_in(&drive.dir.join("calib"), 6, ".txt");
    r.inventory.label_files = Some(labels.len());
    missing(
        c,
        C::Inventory,
        S::Error,
        &drive.dir.join("calib"),
        &scans,
        &calibs,
        "scans have no calibration file",
    );
    if drive.dir.join("label_2").is_dir() {
        missing(
            c,
            C::Coverage,
            S::Warning,
            &drive.dir.join("label_2"),
            &scans,
            &labels,
            "scans have no label_2 file",
        );
        extra_labels(drive, &scans, c);
    }
    let mut annotated = Vec::new();
    let mut objects = std::collections::BTreeMap::new();
    for &f in &scans {
        let (lp, cp) = (drive.object_labels_path(f), drive.calib_path(f));
        let boxes = crate::fs::present(&lp)
            .then(|| read_or_note(c, C::Read, &lp, object::read(&lp)))
            .flatten();
        let calib = crate::fs::present(&cp)
            .then(|| read_or_note(c, C::Calibration, &cp, FrameCalib::read(&cp)))
            .flatten();
        if let (Some(b), Some(k)) = (boxes, calib) {
            if b.iter().any(|o| o.kind != "DontCare") {
                annotated.push(f);
            }
            objects.insert(f, (b, k));
        }
    }
    r.inventory.annotated = annotated.len();
    r.inventory.annotated_range = annotated
        .first()
        .zip(annotated.last())
        .map(|(a, b)| (*a, *b));
    r.layout = LayoutRead::Object { objects };
}
