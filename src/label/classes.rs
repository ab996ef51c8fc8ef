//! LABEL: class maps, the one description of what a label id means.
//!
//! A [`ClassMap`] lists the classes of a conversion in id order (name and display colour), says
//! which ground-truth ids are not scored (SemanticKITTI's `unlabeled`), which classes enter the
//! mean IoU, and, for box sources, which object types become which class. The labeller, the
//! statistics, `score`, the previews, the charts, the shards' metadata and the trainer all take
//! it; nothing else knows how many classes there are. The default is the paper's 4-class map.

use std::collections::BTreeMap;
use std::ops::AddAssign;

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
}

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
        }
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
            Err(Error::format(
                path,
                format!(
                    "{} has label {value}, not a class id of {} (0-{})",
                    what(),
                    self.name,
                    self.len() - 1
                ),
            ))
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

/// A count per class id, `counts[id]`.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(transparent)]
pub struct ClassCounts(pub Vec<u64>);

impl ClassCounts {
    /// Zero for each of `n` classes.
    pub fn zeros(n: usize) -> ClassCounts {
        ClassCounts(vec![0; n])
    }

    /// Counts `ids` (each must be below the length).
    pub fn count<I: IntoIterator<Item = ClassId>>(n: usize, ids: I) -> ClassCounts {
        let mut c = ClassCounts::zeros(n);
        for id in ids {
            c.0[id as usize] += 1;
        }
        c
    }

    /// The count of class `id` (0 beyond the length).
    pub fn get(&self, id: ClassId) -> u64 {
        self.0.get(id as usize).copied().unwrap_or(0)
    }

    /// All counts added.
    pub fn total(&self) -> u64 {
        self.0.iter().sum()
    }
}

impl AddAssign<&ClassCounts> for ClassCounts {
    fn add_assign(&mut self, o: &ClassCounts) {
        if self.0.len() < o.0.len() {
            self.0.resize(o.0.len(), 0);
        }
        for (a, b) in self.0.iter_mut().zip(&o.0) {
            *a += b;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
