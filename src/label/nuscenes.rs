//! nuScenes-lidarseg's classes: the 32 general classes a `_lidarseg.bin` file holds (one uint8
//! per point, the `index` of `category.json`) and the benchmark's 16 classes they map to
//! (nuscenes-devkit's lidarseg evaluation; mmdetection3d's `labels_map` is the same), with 0 the
//! ignored `noise` and the classes the benchmark leaves out.

use std::collections::BTreeMap;

use super::classes::{AbsentInMiou, ClassInfo, ClassMap};
#[cfg(test)]
use crate::source::dataset::NUSCENES_GENERAL_CLASSES as GENERAL_CLASSES;

/// The benchmark's classes: name, colour (the devkit's), the general classes it takes, and the
/// one a prediction of it is written back as. Class 0 takes every general class not listed.
const CLASSES: [(&str, [u8; 3], &[u32], u32); 17] = [
    ("ignore", [0, 0, 0], &[], 0),
    ("barrier", [112, 128, 144], &[9], 9),
    ("bicycle", [220, 20, 60], &[14], 14),
    ("bus", [255, 127, 80], &[15, 16], 16),
    ("car", [255, 158, 0], &[17], 17),
    ("construction_vehicle", [233, 150, 70], &[18], 18),
    ("motorcycle", [255, 61, 99], &[21], 21),
    ("pedestrian", [0, 0, 230], &[2, 3, 4, 6], 2),
    ("traffic_cone", [47, 79, 79], &[12], 12),
    ("trailer", [255, 140, 0], &[22], 22),
    ("truck", [255, 99, 71], &[23], 23),
    ("driveable_surface", [0, 207, 191], &[24], 24),
    ("other_flat", [175, 0, 75], &[25], 25),
    ("sidewalk", [75, 0, 75], &[26], 26),
    ("terrain", [112, 180, 60], &[27], 27),
    ("manmade", [222, 184, 135], &[28], 28),
    ("vegetation", [0, 175, 0], &[30], 30),
];

impl ClassMap {
    /// nuScenes-lidarseg's benchmark map (`nuscenes`): raw ids are the 32 general classes
    /// ([`NUSCENES_GENERAL_CLASSES`](crate::source::dataset::NUSCENES_GENERAL_CLASSES)),
    /// classes the 16 of the benchmark plus 0 `ignore` (noise, animal, personal mobility,
    /// stroller, wheelchair, debris, pushable / pullable, bicycle rack, ambulance, police
    /// vehicle, static other, ego vehicle), which is not scored. The mean IoU
    /// leaves out a class absent from truth and prediction (the devkit's `nanmean`).
    pub fn nuscenes() -> ClassMap {
        let mut learning_map: BTreeMap<u32, u8> = (0..32).map(|raw| (raw, 0)).collect();
        for (c, (_, _, general, _)) in CLASSES.iter().enumerate() {
            for &raw in *general {
                learning_map.insert(raw, c as u8);
            }
        }
        ClassMap {
            name: "nuscenes".into(),
            classes: CLASSES
                .iter()
                .map(|(name, colour, _, _)| ClassInfo {
                    name: (*name).into(),
                    colour: *colour,
                })
                .collect(),
            background: 0,
            ignore: vec![0],
            miou: (1..CLASSES.len() as u8).collect(),
            object_types: BTreeMap::new(),
            reference_weights: None,
            learning_map,
            learning_map_inv: CLASSES.iter().map(|c| c.3).collect(),
            absent_in_miou: AbsentInMiou::LeftOut,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_32_general_classes_make_the_16_of_the_benchmark() {
        let m = ClassMap::nuscenes();
        m.validate().unwrap();
        assert_eq!(m.len(), 17);
        let class = |general: &str| {
            let raw = GENERAL_CLASSES.iter().position(|g| *g == general).unwrap() as u32;
            m.classes[m.class_of_raw(raw).unwrap() as usize]
                .name
                .as_str()
        };
        assert_eq!(class("human.pedestrian.police_officer"), "pedestrian");
        assert_eq!(class("vehicle.bus.bendy"), "bus");
        assert_eq!(class("vehicle.emergency.ambulance"), "ignore");
        assert_eq!(class("static.other"), "ignore");
        assert_eq!(class("static.vegetation"), "vegetation");
        // Every class is reached, and written back as a general class it takes.
        for c in 1..17u8 {
            let raw = m.raw_of_class(c).unwrap();
            assert_eq!(m.class_of_raw(raw), Some(c));
        }
        assert_eq!(m.class_of_raw(32), None);
    }
}
