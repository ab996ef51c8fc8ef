//! Inventory and coverage: what each drive holds, compared source by source; each drive's
//! files are read here once for the other checks ([`read_drive`] -> [`DriveRead`]).

use std::path::{Path, PathBuf};

use super::read::{frames_in, missing, DriveRead};
use super::{frame_ranges, layouts, CheckName as C, Collector, Severity as S};
use crate::error::Result;
use crate::source::kitti::velodyne::POINT_BYTES;
use crate::source::kitti::{discover_as, DatasetKind, Drive};

/// The drives under `root`: what `convert` finds, or else drive-named folders holding a
/// `tracklet_labels.xml` (a folder of annotations without scans).
pub(crate) fn drives(root: &Path, layout: Option<DatasetKind>) -> Result<Vec<Drive>> {
    let found = discover_as(root, layout);
    if let Ok(d) = &found {
        if !d.drives.is_empty() {
            return Ok(d.drives.clone());
        }
    }
    if matches!(layout, None | Some(DatasetKind::Raw)) && root.is_dir() {
        let mut drives: Vec<Drive> = crate::fs::sorted_dir(root)?
            .iter()
            .filter(|p| p.join("tracklet_labels.xml").is_file())
            .filter_map(|p| Drive::from_dir(p))
            .collect();
        if drives.is_empty() {
            drives.extend(Drive::from_dir(root).filter(|d| d.tracklets_path().is_file()));
        }
        if !drives.is_empty() {
            return Ok(drives);
        }
    }
    found.map(|d| d.drives)
}

/// Reads a drive's annotations, calibration and file lists, and compares them.
pub(crate) fn read_drive(drive: &Drive, c: &mut Collector) -> DriveRead {
    let mut r = DriveRead::new(drive);
    list_scans(drive, &mut r, c);
    let width = drive.frame_id(0).frame_name().len();
    for cam in 0..4u8 {
        let dir = match drive.dataset {
            DatasetKind::Raw => drive.dir.join(format!("image_{cam:02}/data")),
            _ => drive.dir.join(format!("image_{cam}")),
        };
        if dir.is_dir() {
            let frames = frames_in(&dir, width, ".png");
            let name = dir
                .strip_prefix(&drive.dir)
                .unwrap_or(&dir)
                .display()
                .to_string();
            r.inventory.images.insert(name, frames.len());
            r.images.insert(cam, frames);
        }
    }
    match drive.dataset {
        DatasetKind::Raw => layouts::read_raw(drive, &mut r, c),
        DatasetKind::Sequence => layouts::read_sequence(drive, &mut r, c),
        DatasetKind::Object => layouts::read_object(drive, &mut r, c),
    }
    compare_images(drive, &r, c);
    r
}

fn list_scans(drive: &Drive, r: &mut DriveRead, c: &mut Collector) {
    let listing = match drive.scan_listing() {
        Ok(l) => l,
        Err(e) => {
            c.add(C::Read, S::Error, &drive.dir, None, None, e.to_string());
            return;
        }
    };
    for p in &listing.not_frames {
        c.add(
            C::Inventory,
            S::Warning,
            p,
            None,
            None,
            "not a scan (`<frame>.bin`) in the velodyne folder: no conversion reads it".into(),
        );
    }
    // Another sensor's `.bin` scans of a declared layout (`--fields`).
    let layout = (c.opts.sensor.as_ref()).and_then(|s| s.layout().ok().flatten());
    for f in listing.frames {
        let path = drive.scan_path(f);
        if !crate::source::is_kitti_bin(&path) || layout.is_some() {
            // Another sensor's scan: its point count from its header or its declared layout.
            match crate::source::points_in_file_as(&path, layout.as_ref()) {
                Some(n) => {
                    r.scans.insert(f, n as usize);
                }
                None => {
                    let e = crate::source::read_file(&path, layout.as_ref()).err();
                    let why = e.map_or("cannot be read".to_string(), |e| e.to_string());
                    c.add(C::Read, S::Error, &path, Some(f), None, why);
                }
            }
            continue;
        }
        match crate::fs::regular(&path) {
            Ok(m) if (m.len() as usize).is_multiple_of(POINT_BYTES) => {
                r.scans.insert(f, m.len() as usize / POINT_BYTES);
            }
            Ok(m) => c.add(
                C::Read,
                S::Error,
                &path,
                Some(f),
                None,
                format!(
                    "{} bytes, not a multiple of {POINT_BYTES} (x, y, z, reflectance as float32)",
                    m.len()
                ),
            ),
            Err(e) => c.add(C::Read, S::Error, &path, Some(f), None, e.to_string()),
        }
    }
    r.inventory.scans = r.scans.len();
}

/// Scans without the camera's image (the colour channels need it) and images without a scan.
fn compare_images(drive: &Drive, r: &DriveRead, c: &mut Collector) {
    let scans: Vec<u32> = r.scans.keys().copied().collect();
    for (cam, frames) in &r.images {
        let dir: PathBuf = drive
            .image_path(*cam, 0)
            .parent()
            .map(Path::to_path_buf)
            .unwrap_or_default();
        missing(
            c,
            C::Inventory,
            S::Warning,
            &dir,
            &scans,
            frames,
            "scans have no image (no colour for them)",
        );
        let orphans: Vec<u32> = frames
            .iter()
            .copied()
            .filter(|f| !r.scans.contains_key(f))
            .collect();
        if let (Some(&first), false) = (orphans.first(), scans.is_empty()) {
            c.add(
                C::Inventory,
                S::Note,
                &dir,
                Some(first),
                None,
                format!(
                    "{} images have no scan: frames {}",
                    orphans.len(),
                    frame_ranges(&orphans)
                ),
            );
        }
    }
    if !scans.is_empty() && !r.images.contains_key(&2) && drive.dataset != DatasetKind::Sequence {
        c.add(
            C::Inventory,
            S::Note,
            &drive.dir,
            None,
            None,
            "no camera-2 images: no colour channels for these scans".into(),
        );
    }
}
