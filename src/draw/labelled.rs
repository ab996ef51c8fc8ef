//! Pictures of a sequence labelled from boxes (`kitti2pgm label`): each labelled scan from
//! above, its points in their class's colour and the boxes they were labelled by
//! ([`super::boxes::labelled_bird_eye`]), for `kitti2pgm preview`.

use std::path::Path;

use crate::error::{Error, Result};
use crate::format::box_labels;
use crate::label::{ClassMap, LabelBox};
use crate::raster::RgbImage;
use crate::source::annotations::FrameBoxes;
use crate::source::boxes::BoxSource;
use crate::source::kitti::Drive;

/// A labelled sequence, ready to draw.
#[derive(Debug)]
pub struct LabelledSequence {
    /// The sequence.
    pub drive: Drive,
    /// The class map its labels were written with.
    pub map: ClassMap,
    /// The frames labelled, ascending.
    pub frames: Vec<u32>,
    boxes: FrameBoxes,
}

impl LabelledSequence {
    /// The sequence folder `seq`, if `label` labelled it.
    pub fn open(seq: &Path) -> Result<Option<LabelledSequence>> {
        let Some(rec) = box_labels::read(seq)? else {
            return Ok(None);
        };
        let drive = Drive::sequence(seq).ok_or_else(|| Error::Input {
            path: seq.into(),
            message: "not a sequence folder (sequences/<NN>/)".into(),
        })?;
        let boxes = rec.imported_boxes()?;
        let frames = rec.frames.keys().filter_map(|n| n.parse().ok()).collect();
        Ok(Some(LabelledSequence {
            drive,
            map: rec.params.class_map,
            frames,
            boxes,
        }))
    }

    /// The picture of frame `frame`: its scan, its label file's classes, its boxes.
    pub fn picture(&self, frame: u32) -> Result<RgbImage> {
        let scan = crate::source::read_file(&self.drive.scan_path(frame), None)?;
        let labels = crate::format::label_file::read_point_labels(
            &self.drive.point_labels_path(frame),
            &scan,
            &self.drive.scan_path(frame),
            &self.map,
        )?;
        let boxes: Vec<LabelBox> =
            crate::label::label_boxes(&self.boxes.boxes_at(frame), &self.map)
                .into_iter()
                .filter(|b| b.class != self.map.background)
                .collect();
        let title = format!(
            "{} {frame:06}: {} boxes, class map {}",
            self.drive.name(),
            boxes.len(),
            self.map.name
        );
        Ok(super::boxes::labelled_bird_eye(
            &scan.points,
            &labels.class,
            &boxes,
            &self.map,
            &title,
        ))
    }
}
