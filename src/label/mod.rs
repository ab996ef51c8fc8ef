//! LABEL: the class of every point of a scan.
//!
//! - [`classes`]: the [`ClassMap`] (ids, names, colours, ignored and averaged ids, object types)
//!   and per-class counts ([`counts`]); raw per-point ids to classes and back (`raw_ids`);
//!   [`nuscenes`]: nuScenes-lidarseg's classes;
//! - [`boxes`]: boxes as parry cuboids and the [`Labeller`] that finds each point's box.
//!
//! The rule that turns a box into a class lives here ([`label_boxes`]), not in the readers:
//! they only say what their files say, as [`AnnotatedBox`]es (`source::boxes`, the seam), and
//! `label` reads no file.

pub mod box_maps;
pub mod boxes;
pub mod classes;
pub mod counts;
pub mod nuscenes;
mod raw_ids;

pub use box_maps::TypeRule;
pub use boxes::{LabelBox, Labeller, PointLabels};
pub use classes::{ClassId, ClassInfo, ClassMap};
pub use counts::ClassCounts;

use crate::source::boxes::AnnotatedBox;

/// The instance id of track `track` (its index in its source): `track + 1`, saturating at 65535.
pub fn instance_of(track: usize) -> u16 {
    u16::try_from(track + 1).unwrap_or(u16::MAX)
}

/// The class rule for boxes: each box takes the class `map` gives its class name, and the
/// instance id of its track ([`instance_of`]).
pub fn label_boxes(boxes: &[AnnotatedBox], map: &ClassMap) -> Vec<LabelBox> {
    (boxes.iter())
        .map(|b| {
            LabelBox::of(
                &b.geometry,
                map.class_of_object(&b.class_name),
                instance_of(b.track),
            )
        })
        .collect()
}
