//! Pictures of flagged frames: a bird's-eye view of the scan with its boxes (the flagged object
//! in red), or, for the camera checks, the points over the camera image.

use std::collections::BTreeMap;
use std::path::Path;

use super::inventory;
use super::read::DriveRead;
use super::{CheckName, CheckOptions, Collector, Finding};
use crate::draw::boxes::{bird_eye, camera_overlay, Drawn};
use crate::error::Result;
use crate::label::{ClassMap, LabelBox};
use crate::source::Scan;

/// Draws findings' pictures, reading each drive's annotations once.
pub struct Pictures<'a> {
    opts: &'a CheckOptions,
    drives: BTreeMap<String, crate::source::kitti::Drive>,
    read: BTreeMap<String, DriveRead>,
}

impl<'a> Pictures<'a> {
    /// For the drives under `root`.
    pub fn new(root: &Path, opts: &'a CheckOptions) -> Result<Pictures<'a>> {
        let drives = inventory::drives(root, opts.layout)?
            .into_iter()
            .map(|d| (d.name(), d))
            .collect();
        Ok(Pictures {
            opts,
            drives,
            read: BTreeMap::new(),
        })
    }

    /// The picture of `f`, when its check is [pictured](CheckName::pictured) and it is about
    /// a frame whose scan is there.
    pub fn draw(&mut self, f: &Finding) -> Result<Option<crate::raster::RgbImage>> {
        if !f.check.pictured() {
            return Ok(None);
        }
        let (Some(frame), Some(drive)) = (f.frame, self.drives.get(&f.drive)) else {
            return Ok(None);
        };
        let scan_path = drive.scan_path(frame);
        if !scan_path.is_file() {
            return Ok(None);
        }
        if !self.read.contains_key(&f.drive) {
            let mut quiet = Collector::new(&f.drive, self.opts);
            let mut r = inventory::read_drive(drive, &mut quiet);
            super::imported::load(&mut r, &mut quiet);
            self.read.insert(f.drive.clone(), r);
        }
        let r = &self.read[&f.drive];
        let scan = Scan::read(&scan_path)?;
        let title = format!("{} {} frame {frame}: {}", f.severity, f.check, f.drive);
        if matches!(
            f.check,
            CheckName::CameraOverlap | CheckName::CameraAlignment | CheckName::Calibration
        ) {
            let image = drive.image_path(2, frame);
            let Some((proj, _)) = super::scans::camera_at(r, frame) else {
                return Ok(None);
            };
            if !image.is_file() {
                return Ok(None);
            }
            let img = crate::source::kitti::camera::read_image(&image)?;
            return Ok(Some(camera_overlay(&img, &scan.points, &proj, &title)));
        }
        let ghosts = if f.check == CheckName::AnnotationEnds {
            Ghosts::Drawn
        } else {
            Ghosts::Left
        };
        let boxes = boxes(r, frame, ghosts);
        let map = ClassMap::kitti_paper();
        let flagged = f.object.as_ref().map(|o| o.index);
        let drawn: Vec<Drawn> = boxes
            .iter()
            .map(|(i, kind, b)| Drawn {
                label_box: b,
                colour: map.colour(map.class_of_object(kind)).map(|c| c.max(90)),
                flagged: Some(*i) == flagged,
                text: format!("#{i} {kind}"),
                show_text: false,
            })
            .collect();
        let centre = drawn
            .iter()
            .find(|d| d.flagged)
            .map(|d| {
                (
                    d.label_box.pose.translation.x,
                    d.label_box.pose.translation.y,
                )
            })
            .unwrap_or((0.0, 0.0));
        Ok(Some(bird_eye(
            &scan.points,
            None,
            &drawn,
            centre,
            20.0,
            &title,
        )))
    }
}

/// Whether a picture shows the ghosts of annotations that ended just before its frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Ghosts {
    /// Drawn (an `annotation-ends` finding: where the object went on).
    Drawn,
    /// Left out.
    Left,
}

/// The boxes at a frame (with the ghosts of annotations that ended just before, when `ghosts`
/// says so): object index, type, box.
fn boxes(r: &DriveRead, frame: u32, ghosts: Ghosts) -> Vec<(u32, String, LabelBox)> {
    r.boxes_at(frame)
        .into_iter()
        .filter(|b| ghosts == Ghosts::Drawn || !b.ghost)
        .map(|b| {
            let kind = if b.ghost {
                format!("{} (ended)", b.object.kind)
            } else {
                b.object.kind
            };
            (b.object.index, kind, b.label_box)
        })
        .collect()
}
