//! LABEL: class maps, the one description of what a label id means.
//!
//! A [`ClassMap`] lists the classes of a conversion in id order (name and display colour), says
//! which ground-truth ids are not scored (SemanticKITTI's `unlabeled`), which classes enter the
//! mean IoU, and, for box sources, which object types become which class. The labeller, the
//! statistics, `score`, the previews, the charts, the shards' metadata and the trainer all take
//! it; nothing else knows how many classes there are. The default is the paper's 4-class map.

use std::collections::BTreeMap;
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};

/// A class id as written to files: the label channel, the low 16 bits of a `.label` entry.
pub type ClassId = u8;

/// One class of a map.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct ClassInfo {
    /// Lower-case name (`car`, `pedestrian`, ...), unique in the map.
    pub name: String,
    /// Display colour, RGB.
    pub colour: [u8; 3],
}

/// The classes of a conversion and how they are labelled and scored.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ClassMap {
    /// The map's name (`kitti-paper-4`).
    pub name: String,
    /// Classes in id order: `classes[id]`.
    pub classes: Vec<ClassInfo>,
    /// The id of everything that no source labels (points outside every box).
    pub background: ClassId,
    /// Ground-truth ids whose elements are not scored.
    pub ignore: Vec<ClassId>,
    /// Ids averaged into the mean IoU.
    pub miou: Vec<ClassId>,
    /// Box sources: object type (as the dataset writes it) to class id. A type not listed here
    /// becomes [`ClassMap::background`].
    pub object_types: BTreeMap<String, ClassId>,
    /// The loss weights the dataset's reference network was trained with, when it has some
    /// (SqueezeSeg's `[1/15, 1, 10, 10]`).
    pub reference_weights: Option<Vec<f64>>,
    /// Per-point sources (SemanticKITTI): the dataset's raw label id (low 16 bits of a
    /// `.label` entry) to class id, its `learning_map`. Empty for box sources.
    #[serde(default)]
    pub learning_map: BTreeMap<u32, ClassId>,
    /// Per-point sources: the raw id each class is written back as (`learning_map_inv`: what
    /// a benchmark submission holds). Empty for box sources.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub learning_map_inv: Vec<u32>,
    /// How a class absent from both truth and prediction enters the mean IoU: left out
    /// (SqueezeSeg's evaluation, the default) or counted as 0 (SemanticKITTI's benchmark).
    #[serde(default)]
    pub absent_in_miou: AbsentInMiou,
}

/// How a class absent from both truth and prediction enters the mean IoU.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum AbsentInMiou {
    /// Left out of the mean.
    #[default]
    LeftOut,
    /// Counted as IoU 0 (SemanticKITTI's `evaluate_semantics.py`: IoU = TP / (TP+FP+FN+1e-15)).
    Zero,
}

crate::named_enum!(AbsentInMiou, "rule for absent classes", [
    LeftOut => "left_out" [] "left out of the mean (SqueezeSeg's evaluation)",
    Zero => "zero" [] "counted as IoU 0 (SemanticKITTI's benchmark)",
]);

/// The parts of a `semantic-kitti.yaml` that make a class map.
#[derive(Debug, Deserialize)]
struct SemanticKittiYaml {
    labels: BTreeMap<u32, String>,
    color_map: BTreeMap<u32, [u8; 3]>,
    learning_map: BTreeMap<u32, u32>,
    learning_map_inv: BTreeMap<u32, u32>,
    learning_ignore: BTreeMap<u32, bool>,
}

/// The dataset's own `semantic-kitti.yaml`, embedded: the default SemanticKITTI class map.
pub const SEMANTIC_KITTI_YAML: &str = include_str!("semantic-kitti.yaml");

impl Default for ClassMap {
    fn default() -> Self {
        ClassMap::kitti_paper()
    }
}

impl ClassMap {
    /// The paper's and SqueezeSeg's map: 0 background (red), 1 car (green: Car, Van, Truck),
    /// 2 pedestrian (light blue: Pedestrian, Person sitting), 3 cyclist (violet: Cyclist); Tram
    /// and Misc stay background. mIoU over car, pedestrian and cyclist.
    pub fn kitti_paper() -> ClassMap {
        let class = |name: &str, colour| ClassInfo {
            name: name.into(),
            colour,
        };
        let types = [
            ("Car", 1),
            ("Van", 1),
            ("Truck", 1),
            ("Pedestrian", 2),
            ("Person (sitting)", 2),
            ("Person_sitting", 2),
            ("Cyclist", 3),
        ];
        ClassMap {
            name: "kitti-paper-4".into(),
            classes: vec![
                class("background", [200, 40, 40]),
                class("car", [40, 200, 60]),
                class("pedestrian", [120, 200, 255]),
                class("cyclist", [170, 70, 220]),
            ],
            background: 0,
            ignore: Vec::new(),
            miou: vec![1, 2, 3],
            object_types: types.iter().map(|(t, c)| (t.to_string(), *c)).collect(),
            reference_weights: Some(vec![1.0 / 15.0, 1.0, 10.0, 10.0]),
            learning_map: BTreeMap::new(),
            learning_map_inv: Vec::new(),
            absent_in_miou: AbsentInMiou::LeftOut,
        }
    }

    /// The built-in map called `name`: the name outputs record (`kitti-paper-4`,
    /// `semantic-kitti`, `nuscenes`, and the box maps `kitti-boxes`, `sustechpoints`,
    /// `nuscenes-detection`) or
    /// its short forms (`kitti-paper`, `kitti_paper`, `semantic_kitti`, `nuscenes-16`,
    /// `nuscenes-lidarseg`, `sustech`).
    pub fn builtin(name: &str) -> Option<ClassMap> {
        match name {
            "kitti-paper-4" | "kitti-paper" | "kitti_paper" | "kitti_paper_4" => {
                Some(ClassMap::kitti_paper())
            }
            "semantic-kitti" | "semantic_kitti" => Some(ClassMap::semantic_kitti()),
            "nuscenes" | "nuscenes-16" | "nuscenes-lidarseg" => Some(ClassMap::nuscenes()),
            "sustechpoints" | "sustech" => Some(ClassMap::sustechpoints()),
            "kitti-boxes" | "kitti_boxes" => Some(ClassMap::kitti_boxes()),
            "nuscenes-detection" | "nuscenes_detection" => Some(ClassMap::nuscenes_detection()),
            _ => None,
        }
    }

    /// The names of the built-in maps, as outputs record them.
    pub const BUILTIN: [&'static str; 6] = [
        "kitti-paper-4",
        "semantic-kitti",
        "nuscenes",
        "kitti-boxes",
        "sustechpoints",
        "nuscenes-detection",
    ];

    /// A class map by built-in name ([`ClassMap::builtin`]) or from a file: a
    /// `semantic-kitti.yaml`-style one (with `learning_map`) or a box class map (with
    /// `classes`, [`ClassMap::from_box_yaml`]).
    pub fn named_or_file(name_or_path: &Path) -> Result<ClassMap> {
        if let Some(m) = name_or_path.to_str().and_then(ClassMap::builtin) {
            return Ok(m);
        }
        if !name_or_path.exists() && name_or_path.extension().is_none() {
            return Err(Error::Config(format!(
                "no class map called {:?}: the built-in maps are {}, or give a YAML file",
                name_or_path.display().to_string(),
                ClassMap::BUILTIN.join(", ")
            )));
        }
        let text = crate::fs::read_text(name_or_path, crate::fs::Limit::Text)?;
        let is_box_map = serde_norway::from_str::<serde_norway::Value>(&text)
            .is_ok_and(|v| v.get("classes").is_some() && v.get("learning_map").is_none());
        if is_box_map {
            ClassMap::from_box_yaml(&text, name_or_path)
        } else {
            ClassMap::from_semantic_kitti_yaml(&text, name_or_path)
        }
    }

    /// The default classes of a layout: SemanticKITTI's 20 for sequences, the paper's 4 for
    /// box sources (KITTI raw tracklets, KITTI object labels).
    pub fn default_for(layout: crate::source::DatasetKind) -> ClassMap {
        match layout {
            crate::source::DatasetKind::Sequence => ClassMap::semantic_kitti(),
            _ => ClassMap::kitti_paper(),
        }
    }

    /// SemanticKITTI's 20 training classes, from the dataset's own `semantic-kitti.yaml`
    /// (embedded): class `c` is named after `labels[learning_map_inv[c]]` and coloured with
    /// that label's `color_map` entry (BGR in the file); 0 `unlabeled` is ignored; mIoU over the
    /// 19 others, absent classes counting 0, as the benchmark computes it.
    pub fn semantic_kitti() -> ClassMap {
        // Parsed once: every Python call that names it (`unproject`, `label_points`) asks again.
        static PARSED: std::sync::OnceLock<ClassMap> = std::sync::OnceLock::new();
        PARSED
            .get_or_init(|| {
                ClassMap::from_semantic_kitti_yaml(
                    SEMANTIC_KITTI_YAML,
                    Path::new("semantic-kitti.yaml"),
                )
                .expect("the embedded semantic-kitti.yaml is valid")
            })
            .clone()
    }

    /// A class map from a `semantic-kitti.yaml`-style file (`labels`, `color_map`,
    /// `learning_map`, `learning_map_inv`, `learning_ignore`); `path` names it in errors.
    pub fn from_semantic_kitti_yaml(text: &str, path: &Path) -> Result<ClassMap> {
        let y: SemanticKittiYaml = serde_norway::from_str(text).map_err(|e| Error::NotFormat {
            path: path.into(),
            format: "a semantic-kitti.yaml class file",
            detail: e.to_string(),
        })?;
        let bad = |m: String| Error::format(path, m);
        let n = y.learning_map_inv.len();
        if n == 0 || n > 256 {
            return Err(bad(format!(
                "learning_map_inv has {n} classes, expected 1-256"
            )));
        }
        let mut classes = Vec::with_capacity(n);
        let mut inverse = Vec::with_capacity(n);
        for c in 0..n as u32 {
            let raw = *y.learning_map_inv.get(&c).ok_or_else(|| {
                bad(format!(
                    "learning_map_inv has no class {c} (ids must be 0..{n})"
                ))
            })?;
            let name = y.labels.get(&raw).ok_or_else(|| {
                bad(format!(
                    "labels has no id {raw} (learning_map_inv of class {c})"
                ))
            })?;
            let [b, g, r] = *y
                .color_map
                .get(&raw)
                .ok_or_else(|| bad(format!("color_map has no id {raw}")))?;
            classes.push(ClassInfo {
                name: name.clone(),
                colour: [r, g, b],
            });
            inverse.push(raw);
        }
        let learning_map = y
            .learning_map
            .iter()
            .map(|(&raw, &c)| {
                if (c as usize) < n {
                    Ok((raw, c as ClassId))
                } else {
                    Err(bad(format!(
                        "learning_map sends id {raw} to class {c}, beyond the {n} classes"
                    )))
                }
            })
            .collect::<Result<BTreeMap<_, _>>>()?;
        let ignore: Vec<ClassId> = (0..n as u32)
            .filter(|c| y.learning_ignore.get(c).copied().unwrap_or(false))
            .map(|c| c as ClassId)
            .collect();
        let map = ClassMap {
            name: path.file_stem().map_or("semantic-kitti".into(), |s| {
                s.to_string_lossy().into_owned()
            }),
            miou: (0..n as ClassId).filter(|c| !ignore.contains(c)).collect(),
            background: ignore.first().copied().unwrap_or(0),
            ignore,
            classes,
            object_types: BTreeMap::new(),
            reference_weights: None,
            learning_map,
            learning_map_inv: inverse,
            absent_in_miou: AbsentInMiou::Zero,
        };
        map.validate().map_err(|e| bad(e.to_string()))?;
        Ok(map)
    }

    /// Number of classes.
    pub fn len(&self) -> usize {
        self.classes.len()
    }

    /// True for a map without classes (never valid).
    pub fn is_empty(&self) -> bool {
        self.classes.is_empty()
    }

    /// Every id, in order.
    pub fn ids(&self) -> impl Iterator<Item = ClassId> + '_ {
        (0..self.classes.len()).map(|i| i as ClassId)
    }

    /// Whether `id` is a class of the map.
    pub fn contains(&self, id: impl Into<u64>) -> bool {
        id.into() < self.classes.len() as u64
    }

    /// The name of class `id` (`?` when it is not a class of the map).
    pub fn name(&self, id: ClassId) -> &str {
        self.classes.get(id as usize).map_or("?", |c| &c.name)
    }

    /// The names in id order.
    pub fn names(&self) -> Vec<&str> {
        self.classes.iter().map(|c| c.name.as_str()).collect()
    }

    /// The display colour of class `id` (grey when it is not a class of the map).
    pub fn colour(&self, id: ClassId) -> [u8; 3] {
        self.classes
            .get(id as usize)
            .map_or([128, 128, 128], |c| c.colour)
    }

    /// The id of the class called `name`.
    pub fn id_of(&self, name: &str) -> Option<ClassId> {
        self.classes
            .iter()
            .position(|c| c.name == name)
            .map(|i| i as ClassId)
    }

    /// Whether the map has a rule for the annotations of `layout`: object types for box
    /// sources (KITTI raw tracklets, the object set), a `learning_map` for SemanticKITTI's
    /// per-point labels. Without one, every point would be the background class.
    pub fn can_label(&self, layout: crate::source::DatasetKind) -> bool {
        use crate::source::DatasetKind;
        match layout {
            DatasetKind::Raw | DatasetKind::Object => {
                self.object_types.values().any(|&c| c != self.background)
            }
            DatasetKind::Sequence => !self.learning_map.is_empty(),
        }
    }

    /// The class of a box's object type; types the map does not list are background.
    pub fn class_of_object(&self, object_type: &str) -> ClassId {
        self.object_types
            .get(object_type)
            .copied()
            .unwrap_or(self.background)
    }

    /// Whether ground truth `id` is scored.
    pub fn is_scored(&self, id: ClassId) -> bool {
        !self.ignore.contains(&id)
    }

    /// The classes other than background and the ignored ones (the "objects" of a box map).
    pub fn labelled(&self) -> Vec<ClassId> {
        self.ids()
            .filter(|&c| c != self.background && self.is_scored(c))
            .collect()
    }

    /// `values[id]` keyed by class name, for reports and JSON.
    pub fn keyed<T: Clone>(&self, values: &[T]) -> BTreeMap<String, T> {
        self.classes
            .iter()
            .zip(values)
            .map(|(c, v)| (c.name.clone(), v.clone()))
            .collect()
    }

    /// A label value read from a file, checked to be a class id of this map; `what` names the
    /// element in the error (built only on failure).
    pub fn check(
        &self,
        value: u64,
        path: &std::path::Path,
        what: impl FnOnce() -> String,
    ) -> Result<ClassId> {
        if self.contains(value) {
            Ok(value as ClassId)
        } else {
            Err(Error::NotAClass {
                path: path.into(),
                what: what(),
                value: value as f64,
                map: self.name.clone(),
                max: self.len() - 1,
                hint: None,
            })
        }
    }

    /// Checks that the map is usable: 1-256 classes with unique names, every id it names in
    /// range.
    pub fn validate(&self) -> Result<()> {
        let bad = |m: String| Err(Error::Config(format!("class map {}: {m}", self.name)));
        if self.classes.is_empty() || self.classes.len() > 256 {
            return bad(format!("{} classes, expected 1-256", self.classes.len()));
        }
        for (i, c) in self.classes.iter().enumerate() {
            if self.classes[..i].iter().any(|o| o.name == c.name) {
                return bad(format!("class name {:?} appears twice", c.name));
            }
        }
        let ids = std::iter::once(&self.background)
            .chain(&self.ignore)
            .chain(&self.miou)
            .chain(self.object_types.values());
        if let Some(id) = ids.into_iter().find(|&&id| !self.contains(id)) {
            return bad(format!(
                "names class id {id}, beyond its {} classes",
                self.len()
            ));
        }
        if let Some(w) = &self.reference_weights {
            if w.len() != self.len() {
                return bad(format!(
                    "{} reference weights for {} classes",
                    w.len(),
                    self.len()
                ));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::label::ClassCounts;

    #[test]
    fn paper_map() {
        let m = ClassMap::kitti_paper();
        m.validate().unwrap();
        assert_eq!(m.names(), ["background", "car", "pedestrian", "cyclist"]);
        assert_eq!(m.class_of_object("Van"), 1);
        assert_eq!(m.class_of_object("Person (sitting)"), 2);
        assert_eq!(m.class_of_object("Tram"), 0);
        assert_eq!(m.labelled(), [1, 2, 3]);
        let j = serde_json::to_string(&m).unwrap();
        assert_eq!(serde_json::from_str::<ClassMap>(&j).unwrap(), m);
    }

    #[test]
    fn semantic_kitti_map() {
        let m = ClassMap::semantic_kitti();
        assert_eq!(m.len(), 20);
        assert_eq!(m.name(0), "unlabeled");
        assert_eq!(m.name(1), "car");
        assert_eq!(m.name(19), "traffic-sign");
        assert_eq!(m.ignore, [0]);
        assert_eq!(m.miou.len(), 19);
        // color_map is BGR: car is [245, 150, 100] there.
        assert_eq!(m.colour(1), [100, 150, 245]);
        assert_eq!(m.class_of_raw(252), Some(1), "moving-car is car");
        assert_eq!(m.class_of_raw(52), Some(0));
        assert_eq!(m.class_of_raw(7), None);
        assert_eq!(m.absent_in_miou, AbsentInMiou::Zero);
        let e = ClassMap::from_semantic_kitti_yaml("labels: 3", Path::new("x.yaml")).unwrap_err();
        assert!(
            e.to_string()
                .starts_with("x.yaml: not a semantic-kitti.yaml"),
            "{e}"
        );
    }

    #[test]
    fn bad_maps_are_refused() {
        let mut m = ClassMap::kitti_paper();
        m.miou.push(9);
        assert!(m.validate().unwrap_err().to_string().contains("class id 9"));
        let mut m = ClassMap::kitti_paper();
        m.classes[2].name = "car".into();
        assert!(m.validate().is_err());
    }

    #[test]
    fn counts_add() {
        let mut a = ClassCounts::count(4, [0, 1, 1, 3]);
        a += &ClassCounts::count(4, [1]);
        assert_eq!(a.0, [1, 3, 0, 1]);
        assert_eq!(a.total(), 5);
    }
}
