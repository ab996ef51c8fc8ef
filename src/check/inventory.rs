//! Inventory and coverage: what each drive holds, compared source by source, and the files
//! read once here for the other checks ([`DriveRead`]).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use super::{
    frame_ranges, layouts, CheckName as C, Collector, DriveInventory, ObjectRef, Severity as S,
};
use crate::error::Result;
use crate::geom::Matrix3x4;
use crate::kitti::calib::{Calibration, FrameCalib};
use crate::kitti::object::ObjectLabel;
use crate::kitti::timestamps::Timestamp;
use crate::kitti::tracklets::{Occlusion, Tracklets};
use crate::kitti::velodyne::POINT_BYTES;
use crate::kitti::{discover_as, Drive, Layout};
use crate::label::LabelBox;

/// A drive's annotations, calibration and file lists, read once.
#[derive(Debug, Default)]
pub(crate) struct DriveRead {
    pub drive: Option<Drive>,
    pub inventory: DriveInventory,
    /// Frames with a scan, ascending, and each scan's point count (from its size).
    pub scans: BTreeMap<u32, usize>,
    /// Raw: the tracklets, when they could be read.
    pub tracklets: Option<Tracklets>,
    /// Raw: the velodyne timestamps.
    pub timestamps: Option<Vec<Option<Timestamp>>>,
    /// Raw: the day's calibration.
    pub calib: Option<Calibration>,
    /// Sequences: `calib.txt`.
    pub frame_calib: Option<FrameCalib>,
    /// Object set: each frame's boxes and calibration, where both could be read.
    pub objects: BTreeMap<u32, (Vec<ObjectLabel>, FrameCalib)>,
    /// Sequences: `poses.txt`.
    pub poses: Option<Vec<Matrix3x4>>,
    /// Sequences: frames with a label file.
    pub label_frames: Vec<u32>,
    /// Camera number -> frames with an image.
    pub images: BTreeMap<u8, Vec<u32>>,
}

/// A box of one frame: a tracklet's or a `label_2` object's, or a tracklet's carried one frame
/// past its end (a ghost).
pub(crate) struct FrameBox {
    pub object: ObjectRef,
    pub label_box: LabelBox,
    /// Carried one frame past the end of its annotation.
    pub ghost: bool,
    /// Fully visible by the annotation (tracklet occlusion 0).
    pub visible: bool,
}

impl DriveRead {
    pub(crate) fn drive(&self) -> &Drive {
        self.drive.as_ref().expect("set by read_drive")
    }

    /// The boxes at `frame` (`DontCare` regions left out), and the ghosts of the tracklets
    /// that ended just before ([`FrameBox::ghost`]).
    pub(crate) fn boxes_at(&self, frame: u32) -> Vec<FrameBox> {
        let mut out = Vec::new();
        if let Some(t) = &self.tracklets {
            for (i, tr, p) in t.at(frame) {
                out.push(FrameBox {
                    object: ObjectRef {
                        index: i as u32,
                        kind: tr.object_type.as_str().into(),
                    },
                    label_box: LabelBox::new(i, tr, p, 0),
                    ghost: false,
                    visible: p.occlusion == Occlusion::Visible,
                });
            }
            for (i, tr) in t.tracklets.iter().enumerate() {
                if let Some(pose) = super::scans::carried_on(tr, frame) {
                    out.push(FrameBox {
                        object: ObjectRef {
                            index: i as u32,
                            kind: tr.object_type.as_str().into(),
                        },
                        label_box: LabelBox::new(i, tr, &pose, 0),
                        ghost: true,
                        visible: false,
                    });
                }
            }
        }
        if let Some((objects, calib)) = self.objects.get(&frame) {
            let rect_to_velo = calib.velo_to_rect().try_inverse().unwrap_or_default();
            for (i, o) in objects
                .iter()
                .enumerate()
                .filter(|(_, o)| o.kind != "DontCare")
            {
                out.push(FrameBox {
                    object: ObjectRef {
                        index: i as u32,
                        kind: o.kind.clone(),
                    },
                    label_box: LabelBox::from_object(i, o, &rect_to_velo, 0),
                    ghost: false,
                    visible: false,
                });
            }
        }
        out
    }
}

/// The drives under `root`: what `convert` finds, or else drive-named folders holding a
/// `tracklet_labels.xml` (a folder of annotations without scans).
pub(crate) fn drives(root: &Path, layout: Option<Layout>) -> Result<Vec<Drive>> {
    let found = discover_as(root, layout);
    if let Ok(d) = &found {
        if !d.drives.is_empty() {
            return Ok(d.drives.clone());
        }
    }
    if matches!(layout, None | Some(Layout::Raw)) && root.is_dir() {
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

pub(crate) fn frames_in(dir: &Path, width: usize, ext: &str) -> Vec<u32> {
    let Ok(entries) = crate::fs::sorted_dir(dir) else {
        return Vec::new();
    };
    let mut v: Vec<u32> = entries
        .iter()
        .filter_map(|p| {
            let name = p.file_name()?.to_str()?;
            let stem = name.strip_suffix(ext)?;
            (stem.len() == width).then(|| stem.parse().ok())?
        })
        .collect();
    v.sort_unstable();
    v
}

pub(crate) fn read_or_note<T>(c: &mut Collector, check: C, path: &Path, r: Result<T>) -> Option<T> {
    match r {
        Ok(v) => Some(v),
        Err(e) => {
            c.add(check, S::Error, path, None, None, e.to_string());
            None
        }
    }
}

/// Reads a drive's annotations, calibration and file lists, and compares them.
pub(crate) fn read_drive(drive: &Drive, c: &mut Collector) -> DriveRead {
    let mut r = DriveRead {
        drive: Some(drive.clone()),
        inventory: DriveInventory {
            drive: drive.name(),
            ..Default::default()
        },
        ..Default::default()
    };
    list_scans(drive, &mut r, c);
    let width = drive.frame_id(0).frame_name().len();
    for cam in 0..4u8 {
        let dir = match drive.layout {
            Layout::Raw => drive.dir.join(format!("image_{cam:02}/data")),
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
    match drive.layout {
        Layout::Raw => layouts::read_raw(drive, &mut r, c),
        Layout::Sequence => layouts::read_sequence(drive, &mut r, c),
        Layout::Object => layouts::read_object(drive, &mut r, c),
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
    for f in listing.frames {
        let path = drive.scan_path(f);
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

/// Names the frames of `expected` that `have` lacks, as one finding.
pub(crate) fn missing(
    c: &mut Collector,
    check: C,
    sev: S,
    file: &Path,
    expected: &[u32],
    have: &[u32],
    what: &str,
) {
    let lacking: Vec<u32> = expected
        .iter()
        .copied()
        .filter(|f| have.binary_search(f).is_err())
        .collect();
    if let Some(&first) = lacking.first() {
        c.add(
            check,
            sev,
            file,
            Some(first),
            None,
            format!(
                "{} {what}: frames {}",
                lacking.len(),
                frame_ranges(&lacking)
            ),
        );
    }
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
    if !scans.is_empty() && !r.images.contains_key(&2) && drive.layout != Layout::Sequence {
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
