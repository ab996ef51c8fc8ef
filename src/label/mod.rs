//! LABEL: the class of every velodyne point.
//!
//! - [`classes`]: the [`ClassMap`] (ids, names, colours, ignored and averaged ids, object types)
//!   and per-class counts ([`counts`]); raw per-point ids to classes and back (`raw_ids`);
//!   [`nuscenes`]: nuScenes-lidarseg's classes;
//! - [`boxes`]: boxes as parry cuboids and the [`Labeller`] that finds each point's box.
//!
//! The rule that turns a tracklet into a class lives here ([`tracklet_boxes`]), not in the
//! reader: `kitti::tracklets` only says what the file says.

pub mod boxes;
pub mod classes;
pub mod counts;
pub mod nuscenes;
mod raw_ids;

pub use boxes::{LabelBox, Labeller, PointLabels};
pub use classes::{ClassId, ClassInfo, ClassMap};
pub use counts::ClassCounts;

use crate::source::kitti::tracklets::Tracklets;

/// The boxes of `tracklets` present at `frame`, each of the class `map` gives its object type.
pub fn tracklet_boxes(tracklets: &Tracklets, frame: u32, map: &ClassMap) -> Vec<LabelBox> {
    tracklets
        .at(frame)
        .map(|(i, t, p)| LabelBox::new(i, t, p, map.class_of_object(t.object_type.as_str())))
        .collect()
}
