//! LABEL: class maps for box annotations: which class each object type (the class name an
//! annotation tool writes) becomes, with the aliases a project uses (`Van` -> car, `Rider` ->
//! cyclist), and the shipped maps for the common sets: SUSTechPOINTS' types
//! ([`ClassMap::sustechpoints`]) and nuScenes' detection classes
//! ([`ClassMap::nuscenes_detection`]); KITTI's types are the paper's map
//! ([`ClassMap::kitti_paper`]).
//!
//! A box class map file (YAML) lists the classes in id order, each with the types it takes:
//!
//! ```yaml
//! name: own-boxes
//! classes:
//!   - {name: background, colour: [0, 0, 0]}
//!   - {name: car, colour: [100, 150, 245], types: [Car, Van]}
//!   - {name: cyclist, colour: [200, 40, 255], types: [Cyclist, Rider]}
//! background_types: [DontCare, Misc]   # known types whose boxes label nothing
//! ```
//!
//! The first class is the background (points in no box) unless `background:` names another;
//! every other class enters the mean IoU.

use std::collections::BTreeMap;
use std::path::Path;

use serde::Deserialize;

use super::classes::{AbsentInMiou, ClassId, ClassInfo, ClassMap};
use crate::error::{Error, Result};

/// One class of a box class map file.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct BoxClassYaml {
    name: String,
    #[serde(default, alias = "color")]
    colour: Option<[u8; 3]>,
    #[serde(default)]
    types: Vec<String>,
}

/// A box class map file.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct BoxMapYaml {
    #[serde(default)]
    name: Option<String>,
    classes: Vec<BoxClassYaml>,
    #[serde(default)]
    background: Option<String>,
    #[serde(default)]
    background_types: Vec<String>,
}

/// Colours for classes a file gives none (SemanticKITTI's palette order, RGB).
const PALETTE: [[u8; 3]; 10] = [
    [0, 0, 0],
    [100, 150, 245],
    [30, 30, 255],
    [200, 40, 255],
    [80, 30, 180],
    [100, 80, 250],
    [255, 0, 0],
    [150, 60, 30],
    [255, 0, 255],
    [0, 175, 0],
];

/// A box map's table: class name, colour, the object types it takes.
type BoxClasses = &'static [(&'static str, [u8; 3], &'static [&'static str])];

/// SUSTechPOINTS' types ([`ClassMap::sustechpoints`]).
const SUSTECH_CLASSES: BoxClasses = &[
    ("background", [0, 0, 0], &[]),
    (
        "car",
        [100, 150, 245],
        &["Car", "Van", "PoliceCar", "TourCar"],
    ),
    (
        "truck",
        [80, 30, 180],
        &[
            "Truck",
            "ConcreteTruck",
            "LongVehicle",
            "Excavator",
            "ForkLift",
            "Crane",
            "RoadRoller",
            "Bulldozer",
        ],
    ),
    ("bus", [100, 80, 250], &["Bus", "Tram"]),
    (
        "pedestrian",
        [30, 30, 255],
        &["Pedestrian", "RoadWorker", "Child"],
    ),
    (
        "rider",
        [200, 40, 255],
        &[
            "ScooterRider",
            "BicycleRider",
            "MotorcyleRider",
            "MotorcycleRider",
        ],
    ),
    (
        "two-wheeler",
        [100, 230, 245],
        &[
            "Scooter",
            "Bicycle",
            "Motorcycle",
            "BicycleGroup",
            "Trimotorcycle",
            "FreightTricycle",
        ],
    ),
    (
        "traffic-object",
        [255, 120, 50],
        &[
            "Cone",
            "RoadBarrel",
            "TrafficBarrier",
            "SaftyTriangle",
            "FireHydrant",
        ],
    ),
];

/// SUSTechPOINTS' types that label nothing.
const SUSTECH_BACKGROUND: &[&str] = &[
    "BabyCart",
    "PlatformCart",
    "ConstructionCart",
    "Animal",
    "TrashCan",
    "DontCare",
    "Misc",
    "Unknown",
    "Unknown1",
    "Unknown2",
    "Unknown3",
    "Unknown4",
    "Unknown5",
];

/// nuScenes' detection classes ([`ClassMap::nuscenes_detection`]).
const NUSCENES_CLASSES: BoxClasses = &[
    ("background", [0, 0, 0], &[]),
    (
        "barrier",
        [112, 128, 144],
        &["barrier", "movable_object.barrier"],
    ),
    ("bicycle", [220, 20, 60], &["bicycle", "vehicle.bicycle"]),
    (
        "bus",
        [255, 127, 80],
        &["bus", "vehicle.bus.bendy", "vehicle.bus.rigid"],
    ),
    ("car", [255, 158, 0], &["car", "vehicle.car"]),
    (
        "construction_vehicle",
        [233, 150, 70],
        &["construction_vehicle", "vehicle.construction"],
    ),
    (
        "motorcycle",
        [255, 61, 99],
        &["motorcycle", "vehicle.motorcycle"],
    ),
    (
        "pedestrian",
        [0, 0, 230],
        &[
            "pedestrian",
            "human.pedestrian.adult",
            "human.pedestrian.child",
            "human.pedestrian.construction_worker",
            "human.pedestrian.police_officer",
        ],
    ),
    (
        "traffic_cone",
        [47, 79, 79],
        &["traffic_cone", "movable_object.trafficcone"],
    ),
    ("trailer", [255, 140, 0], &["trailer", "vehicle.trailer"]),
    ("truck", [255, 99, 71], &["truck", "vehicle.truck"]),
];

/// nuScenes' categories the detection benchmark leaves out.
const NUSCENES_BACKGROUND: &[&str] = &[
    "animal",
    "human.pedestrian.personal_mobility",
    "human.pedestrian.stroller",
    "human.pedestrian.wheelchair",
    "movable_object.debris",
    "movable_object.pushable_pullable",
    "static_object.bicycle_rack",
    "vehicle.emergency.ambulance",
    "vehicle.emergency.police",
];

/// A box class map's rule for object types, with the class that the types it does not know
/// become (without one, such types have no class: the caller's error).
#[derive(Debug, Clone, Copy)]
pub struct TypeRule<'a> {
    /// The map.
    pub map: &'a ClassMap,
    unknown: Option<ClassId>,
}

impl<'a> TypeRule<'a> {
    /// The rule of `map`, unknown types becoming the class called `unknown_class` (a class
    /// name that is not the map's is an error listing its classes).
    pub fn new(map: &'a ClassMap, unknown_class: Option<&str>) -> Result<TypeRule<'a>> {
        let unknown = match unknown_class {
            None => None,
            Some(name) => Some(map.id_of(name).ok_or_else(|| {
                Error::Config(format!(
                    "unknown class {name:?}: not a class of {} ({})",
                    map.name,
                    map.names().join(", ")
                ))
            })?),
        };
        Ok(TypeRule { map, unknown })
    }

    /// The class of a box (or object) of type `object_type`, and whether it is the unknown
    /// types' class; `None` for a type the map does not know, without an unknown class.
    pub fn class_of(&self, object_type: &str) -> Option<(ClassId, bool)> {
        match (self.map.object_types.get(object_type), self.unknown) {
            (Some(&c), _) => Some((c, false)),
            (None, Some(c)) => Some((c, true)),
            (None, None) => None,
        }
    }
}

impl ClassMap {
    /// Whether the map names the object type `name` (as a class's type or a background type):
    /// a box of a type it does not know is the user's to decide (`label --unknown-class`).
    pub fn knows_type(&self, name: &str) -> bool {
        self.object_types.contains_key(name)
    }

    /// The map as per-point labels written by `label` use it: a box map without a
    /// `learning_map` gets the identity (a `.label` entry holds the class id itself).
    pub fn for_point_labels(mut self) -> ClassMap {
        if self.learning_map.is_empty() {
            self.learning_map = self.ids().map(|c| (u32::from(c), c)).collect();
            self.learning_map_inv = self.ids().map(u32::from).collect();
        }
        self
    }

    /// A box class map from its YAML file ([module docs](self)); `path` names it in errors.
    pub fn from_box_yaml(text: &str, path: &Path) -> Result<ClassMap> {
        let y: BoxMapYaml = serde_norway::from_str(text).map_err(|e| Error::NotFormat {
            path: path.into(),
            format: "a box class map (classes: [{name, colour, types}])",
            detail: e.to_string(),
        })?;
        let bad = |m: String| Error::format(path, m);
        let mut types = BTreeMap::new();
        for (id, c) in y.classes.iter().enumerate() {
            for t in &c.types {
                if let Some(other) = types.insert(t.clone(), id as ClassId) {
                    return Err(bad(format!(
                        "type {t:?} is listed by class {:?} and by class {:?}",
                        y.classes[other as usize].name, c.name
                    )));
                }
            }
        }
        let background = match &y.background {
            None => 0,
            Some(name) => y
                .classes
                .iter()
                .position(|c| &c.name == name)
                .ok_or_else(|| bad(format!("background {name:?} is not one of its classes")))?
                as ClassId,
        };
        for t in &y.background_types {
            if types.insert(t.clone(), background).is_some() {
                return Err(bad(format!(
                    "type {t:?} is both a class's type and a background type"
                )));
            }
        }
        let n = y.classes.len();
        let map = ClassMap {
            name: y.name.unwrap_or_else(|| {
                path.file_stem()
                    .map_or("boxes".into(), |s| s.to_string_lossy().into_owned())
            }),
            classes: (y.classes.iter().enumerate())
                .map(|(i, c)| ClassInfo {
                    name: c.name.clone(),
                    colour: c.colour.unwrap_or(PALETTE[i % PALETTE.len()]),
                })
                .collect(),
            background,
            ignore: Vec::new(),
            miou: (0..n)
                .map(|c| c as ClassId)
                .filter(|&c| c != background)
                .collect(),
            object_types: types,
            reference_weights: None,
            learning_map: BTreeMap::new(),
            learning_map_inv: Vec::new(),
            absent_in_miou: AbsentInMiou::LeftOut,
        };
        map.validate().map_err(|e| bad(e.to_string()))?;
        Ok(map)
    }

    /// A box map from a table of (class, colour, its types), class 0 the background, with
    /// `background_types` known and labelling nothing.
    fn box_map(name: &str, classes: BoxClasses, background_types: &[&str]) -> ClassMap {
        let mut object_types: BTreeMap<String, ClassId> = (classes.iter().enumerate())
            .flat_map(|(c, (_, _, types))| types.iter().map(move |t| (t.to_string(), c as u8)))
            .collect();
        object_types.extend(background_types.iter().map(|t| (t.to_string(), 0)));
        ClassMap {
            name: name.into(),
            classes: (classes.iter())
                .map(|(n, colour, _)| ClassInfo {
                    name: (*n).into(),
                    colour: *colour,
                })
                .collect(),
            background: 0,
            ignore: Vec::new(),
            miou: (1..classes.len() as u8).collect(),
            object_types,
            reference_weights: None,
            learning_map: BTreeMap::new(),
            learning_map_inv: Vec::new(),
            absent_in_miou: AbsentInMiou::LeftOut,
        }
    }

    /// The paper's 4 classes for KITTI's box types as annotation tools export them (CVAT's
    /// Kitti Raw format): [`ClassMap::kitti_paper`]'s types, and Tram, Misc and DontCare known
    /// and labelling nothing (the paper's map leaves them background too).
    pub fn kitti_boxes() -> ClassMap {
        let mut m = ClassMap::kitti_paper();
        m.name = "kitti-boxes".into();
        for t in ["Tram", "Misc", "DontCare"] {
            m.object_types.insert(t.into(), m.background);
        }
        m
    }

    /// SUSTechPOINTS' object types (its `obj_type_map`, public/js/obj_cfg.js) in 8 classes:
    /// background, car (Car, Van, PoliceCar, TourCar), truck (Truck, ConcreteTruck,
    /// LongVehicle and the machines), bus (Bus, Tram), pedestrian (Pedestrian, RoadWorker,
    /// Child), rider (the Rider types), two-wheeler (Scooter, Bicycle, Motorcycle, the
    /// tricycles, BicycleGroup), traffic-object (Cone, RoadBarrel, TrafficBarrier,
    /// SaftyTriangle, FireHydrant); the other types (carts, Animal, TrashCan, DontCare, Misc,
    /// Unknown*) are known and label nothing.
    pub fn sustechpoints() -> ClassMap {
        ClassMap::box_map("sustechpoints", SUSTECH_CLASSES, SUSTECH_BACKGROUND)
    }

    /// nuScenes' 10 detection classes (the devkit's `category_to_detection_name`), each taking
    /// its own name and the nuScenes categories it stands for (`vehicle.car`,
    /// `human.pedestrian.adult`, ...); the categories the detection benchmark leaves out
    /// (animal, personal mobility, strollers, wheelchairs, debris, pushable / pullable, bicycle
    /// racks, emergency vehicles) are known and label nothing.
    pub fn nuscenes_detection() -> ClassMap {
        ClassMap::box_map("nuscenes-detection", NUSCENES_CLASSES, NUSCENES_BACKGROUND)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shipped_box_maps_are_valid_and_know_their_types() {
        for m in [ClassMap::sustechpoints(), ClassMap::nuscenes_detection()] {
            m.validate().unwrap();
            assert!(
                m.knows_type("DontCare") || m.knows_type("animal"),
                "{}",
                m.name
            );
        }
        let k = ClassMap::kitti_boxes();
        assert!(k.knows_type("Tram") && k.class_of_object("Tram") == k.background);
        assert_eq!(k.name(k.class_of_object("Van")), "car");
        let s = ClassMap::sustechpoints();
        assert_eq!(s.name(s.class_of_object("Van")), "car");
        assert_eq!(s.name(s.class_of_object("MotorcyleRider")), "rider");
        assert_eq!(s.class_of_object("TrashCan"), s.background);
        assert!(!s.knows_type("Rider"));
        let n = ClassMap::nuscenes_detection();
        assert_eq!(n.len(), 11);
        assert_eq!(
            n.name(n.class_of_object("human.pedestrian.child")),
            "pedestrian"
        );
        assert_eq!(n.name(n.class_of_object("vehicle.bus.bendy")), "bus");
    }

    #[test]
    fn a_box_map_file_names_types_and_aliases() {
        let text = "name: own\nclasses:\n  - {name: background}\n  - {name: car, types: [Car, Van]}\n  - {name: cyclist, colour: [1, 2, 3], types: [Cyclist, Rider]}\nbackground_types: [DontCare]\n";
        let m = ClassMap::from_box_yaml(text, Path::new("own.yaml")).unwrap();
        assert_eq!(m.names(), ["background", "car", "cyclist"]);
        assert_eq!(m.class_of_object("Rider"), 2);
        assert_eq!(m.colour(2), [1, 2, 3]);
        assert!(m.knows_type("DontCare") && !m.knows_type("Tram"));
        assert_eq!(m.miou, [1, 2]);
        let rule = TypeRule::new(&m, Some("background")).unwrap();
        assert_eq!(rule.class_of("Rider"), Some((2, false)));
        assert_eq!(rule.class_of("Tram"), Some((0, true)));
        assert_eq!(TypeRule::new(&m, None).unwrap().class_of("Tram"), None);
        assert!(TypeRule::new(&m, Some("tram")).is_err());
        let p = m.clone().for_point_labels();
        assert_eq!(p.class_of_raw(2), Some(2));
        assert_eq!(p.raw_of_class(1), Some(1));
        for (bad, says) in [
            (
                "classes:\n  - {name: a, types: [X]}\n  - {name: b, types: [X]}\n",
                "listed by class",
            ),
            (
                "classes:\n  - {name: a}\nbackground: z\n",
                "background \"z\"",
            ),
            ("classes:\n  - {name: a}\n  - {name: a}\n", "appears twice"),
            ("classes: []\n", "0 classes"),
            ("classes:\n  - {name: a, kind: 3}\n", "unknown field"),
        ] {
            let e = ClassMap::from_box_yaml(bad, Path::new("m.yaml")).unwrap_err();
            assert!(e.to_string().contains(says), "{bad}: {e}");
            assert!(e.to_string().starts_with("m.yaml"), "{e}");
        }
    }
}
