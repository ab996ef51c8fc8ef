//! The kinds of dataset the tool reads: KITTI raw drives, sequence folders (SemanticKITTI,
//! KITTI odometry, and any sensor's scans laid out the same way) and the KITTI object set.

/// Which kind of dataset a folder of frames, and its frames, belong to: its folder layout,
/// its frame names and where its labels come from. Another sensor's sequence folders (PCD
/// scans, unpacked bags and nuScenes scenes) are `Sequence`s.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum DatasetKind {
    /// KITTI raw (tracklet boxes).
    #[default]
    Raw,
    /// SemanticKITTI / KITTI odometry sequences (per-point labels).
    Sequence,
    /// The KITTI 3D object set (`label_2` boxes).
    Object,
}

crate::named_enum!(DatasetKind, "dataset", [
    Raw => "raw" [] "KITTI raw drives with tracklet_labels.xml",
    Sequence => "semantickitti" ["sequences", "sequence"] "SemanticKITTI / KITTI odometry sequences with per-point labels",
    Object => "object" [] "The KITTI 3D object set with label_2 boxes",
]);

impl DatasetKind {
    /// The dataset's name, for messages (`KITTI raw`, `SemanticKITTI`, `the KITTI object set`).
    pub fn dataset(self) -> &'static str {
        match self {
            DatasetKind::Raw => "KITTI raw",
            DatasetKind::Sequence => "SemanticKITTI",
            DatasetKind::Object => "the KITTI object set",
        }
    }

    /// What its folders of frames are called (`drives`, `sequences`, `splits`).
    pub fn units(self) -> &'static str {
        match self {
            DatasetKind::Raw => "drives",
            DatasetKind::Sequence => "sequences",
            DatasetKind::Object => "splits",
        }
    }
}

/// nuScenes-lidarseg's general classes in index order, as `category.json` names them: the
/// dataset's vocabulary, which its reader ([`super::nuscenes`]) checks and the class map reads (the
/// `_lidarseg.bin` files hold these indices; [`crate::label::nuscenes`] maps them to the
/// benchmark's 16).
pub const NUSCENES_GENERAL_CLASSES: [&str; 32] = [
    "noise",
    "animal",
    "human.pedestrian.adult",
    "human.pedestrian.child",
    "human.pedestrian.construction_worker",
    "human.pedestrian.personal_mobility",
    "human.pedestrian.police_officer",
    "human.pedestrian.stroller",
    "human.pedestrian.wheelchair",
    "movable_object.barrier",
    "movable_object.debris",
    "movable_object.pushable_pullable",
    "movable_object.trafficcone",
    "static_object.bicycle_rack",
    "vehicle.bicycle",
    "vehicle.bus.bendy",
    "vehicle.bus.rigid",
    "vehicle.car",
    "vehicle.construction",
    "vehicle.emergency.ambulance",
    "vehicle.emergency.police",
    "vehicle.motorcycle",
    "vehicle.trailer",
    "vehicle.truck",
    "flat.driveable_surface",
    "flat.other",
    "flat.sidewalk",
    "flat.terrain",
    "static.manmade",
    "static.other",
    "static.vegetation",
    "vehicle.ego",
];
