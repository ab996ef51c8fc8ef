//! nuScenes as its devkit lays it out: `DATAROOT/<version>/*.json` (the tables),
//! `DATAROOT/samples/LIDAR_TOP/*.pcd.bin` (the keyframes' scans) and, with nuScenes-lidarseg,
//! `DATAROOT/lidarseg/<version>/<sample_data token>_lidarseg.bin` (one uint8 per point, a
//! general class: [`GENERAL_CLASSES`]).
//!
//! [`NuScenes::open`] reads the scenes and their LIDAR_TOP keyframes (in time order) with their
//! scan and label files. `sample_data.json` runs to gigabytes in v1.0-trainval: it is streamed,
//! only the LIDAR_TOP keyframes kept.

use std::collections::HashMap;
use std::fmt;
use std::io::BufReader;
use std::path::{Path, PathBuf};

use serde::de::{DeserializeOwned, DeserializeSeed, SeqAccess, Visitor};
use serde::Deserialize;

use crate::error::{Error, Result};
use crate::source::{FieldType, PointLayout};

/// A LIDAR_TOP `.pcd.bin` record: `x,y,z,intensity,ring:f32` (20 bytes; the ring index a
/// whole number stored as a float).
pub fn point_layout() -> PointLayout {
    PointLayout::packed(&[
        ("x", FieldType::F32),
        ("y", FieldType::F32),
        ("z", FieldType::F32),
        ("intensity", FieldType::F32),
        ("ring", FieldType::F32),
    ])
}

/// A nuScenes dataset: its scenes with their LIDAR_TOP keyframes.
#[derive(Debug, Clone, PartialEq)]
pub struct NuScenes {
    /// `DATAROOT`.
    pub root: PathBuf,
    /// The version read (`v1.0-mini`, `v1.0-trainval`, ...): the folder of the tables.
    pub version: String,
    /// Whether the version has nuScenes-lidarseg labels (`lidarseg.json`).
    pub lidarseg: bool,
    /// The scenes, by name.
    pub scenes: Vec<Scene>,
}

/// One scene (20 s of driving).
#[derive(Debug, Clone, PartialEq)]
pub struct Scene {
    /// Its name (`scene-0061`).
    pub name: String,
    /// The number in its name (61).
    pub number: u32,
    /// Its LIDAR_TOP keyframes, in time order.
    pub keyframes: Vec<Keyframe>,
}

/// One LIDAR_TOP keyframe.
#[derive(Debug, Clone, PartialEq)]
pub struct Keyframe {
    /// The `sample_data` token.
    pub token: String,
    /// The `sample` token.
    pub sample: String,
    /// Microseconds since the epoch.
    pub timestamp_us: i64,
    /// The scan (`DATAROOT/samples/LIDAR_TOP/....pcd.bin`).
    pub scan: PathBuf,
    /// Its nuScenes-lidarseg labels, where the version has them.
    pub labels: Option<PathBuf>,
}

#[derive(Deserialize)]
struct SceneRow {
    token: String,
    name: String,
}

#[derive(Deserialize)]
struct SampleRow {
    token: String,
    scene_token: String,
}

#[derive(Deserialize)]
struct SampleDataRow {
    token: String,
    sample_token: String,
    filename: String,
    is_key_frame: bool,
    timestamp: i64,
}

#[derive(Deserialize)]
struct LidarsegRow {
    sample_data_token: String,
    filename: String,
}

#[derive(Deserialize)]
struct CategoryRow {
    name: String,
    index: Option<u32>,
}

pub use super::dataset::NUSCENES_GENERAL_CLASSES as GENERAL_CLASSES;

/// Where a LIDAR_TOP keyframe's scan lies, relative to `DATAROOT`.
const LIDAR_TOP: &str = "samples/LIDAR_TOP/";

impl NuScenes {
    /// Reads the tables of `version` under `root` (without a version, the one `v1.0-*` folder
    /// holding `sample_data.json`; several are an error naming them).
    pub fn open(root: &Path, version: Option<&str>) -> Result<NuScenes> {
        let version = match version {
            Some(v) => v.to_string(),
            None => only_version(root)?,
        };
        let tables = root.join(&version);
        let scenes: Vec<SceneRow> = read_table(&tables.join("scene.json"), |_| true)?;
        let samples: Vec<SampleRow> = read_table(&tables.join("sample.json"), |_| true)?;
        let keyframes: Vec<SampleDataRow> =
            read_table(&tables.join("sample_data.json"), |r: &SampleDataRow| {
                r.is_key_frame && r.filename.starts_with(LIDAR_TOP)
            })?;
        let lidarseg_path = tables.join("lidarseg.json");
        let lidarseg = lidarseg_path.exists();
        let labels: HashMap<String, String> = if lidarseg {
            check_categories(&tables.join("category.json"))?;
            read_table(&lidarseg_path, |_: &LidarsegRow| true)?
                .into_iter()
                .map(|r| (r.sample_data_token, r.filename))
                .collect()
        } else {
            HashMap::new()
        };
        let scene_of: HashMap<&str, &str> = samples
            .iter()
            .map(|s| (s.token.as_str(), s.scene_token.as_str()))
            .collect();
        let mut by_scene: HashMap<&str, Vec<Keyframe>> = HashMap::new();
        for k in keyframes {
            let scene = *scene_of.get(k.sample_token.as_str()).ok_or_else(|| {
                Error::format(
                    tables.join("sample_data.json"),
                    format!(
                        "sample_data {} names sample {}, which sample.json does not have",
                        k.token, k.sample_token
                    ),
                )
            })?;
            by_scene.entry(scene).or_default().push(Keyframe {
                labels: labels.get(&k.token).map(|f| root.join(f)),
                scan: root.join(&k.filename),
                token: k.token,
                sample: k.sample_token,
                timestamp_us: k.timestamp,
            });
        }
        let mut out = Vec::new();
        for s in &scenes {
            let mut keyframes = by_scene.remove(s.token.as_str()).unwrap_or_default();
            keyframes.sort_by_key(|k| k.timestamp_us);
            out.push(Scene {
                number: scene_number(&s.name, &tables.join("scene.json"))?,
                name: s.name.clone(),
                keyframes,
            });
        }
        out.sort_by_key(|s| s.number);
        Ok(NuScenes {
            root: root.to_path_buf(),
            version,
            lidarseg,
            scenes: out,
        })
    }
}

/// The folders under `root` holding a `sample_data.json` (nuScenes' versions: `v1.0-mini`...).
fn versions(root: &Path) -> Result<Vec<String>> {
    Ok(crate::fs::sorted_dir(root)?
        .into_iter()
        .filter(|p| p.join("sample_data.json").is_file())
        .filter_map(|p| p.file_name()?.to_str().map(str::to_string))
        .collect())
}

/// Whether `path` is a nuScenes root: a folder (not a ROS 2 bag's, which has a
/// `metadata.yaml`) holding at least one version of the tables.
pub fn is_root(path: &Path) -> bool {
    path.is_dir()
        && !path.join("metadata.yaml").exists()
        && versions(path).is_ok_and(|v| !v.is_empty())
}

/// The one `v1.0-*` folder under `root` with a `sample_data.json`.
fn only_version(root: &Path) -> Result<String> {
    match versions(root)?.as_slice() {
        [one] => Ok(one.clone()),
        [] => Err(Error::Input {
            path: root.into(),
            message: "not a nuScenes root: no folder with sample_data.json (v1.0-mini, v1.0-trainval, ...)".into(),
        }),
        many => Err(Error::Input {
            path: root.into(),
            message: format!("holds several nuScenes versions ({}): name one (--nuscenes-version)", many.join(", ")),
        }),
    }
}

/// The number of a scene name `scene-NNNN` (0-9999, one sequence folder each).
fn scene_number(name: &str, table: &Path) -> Result<u32> {
    name.strip_prefix("scene-")
        .filter(|n| !n.is_empty() && n.len() <= 4 && n.bytes().all(|c| c.is_ascii_digit()))
        .and_then(|n| n.parse().ok())
        .ok_or_else(|| Error::format(table, format!("scene name {name:?} is not scene-NNNN")))
}

/// `category.json` must give the general classes the indices the built-in map has.
fn check_categories(path: &Path) -> Result<()> {
    let rows: Vec<CategoryRow> = read_table(path, |_| true)?;
    for r in rows {
        let Some(i) = r.index else { continue };
        if GENERAL_CLASSES.get(i as usize) != Some(&r.name.as_str()) {
            return Err(Error::format(
                path,
                format!(
                    "category {:?} has index {i}, but nuScenes-lidarseg's general class {i} is {:?}: \
                     not the class list the nuscenes class map knows",
                    r.name,
                    GENERAL_CLASSES.get(i as usize).copied().unwrap_or("none")
                ),
            ));
        }
    }
    Ok(())
}

/// The rows of a JSON table (an array of objects) that `keep` keeps, read as a stream: the
/// others are dropped as they are read.
fn read_table<T: DeserializeOwned>(path: &Path, keep: impl FnMut(&T) -> bool) -> Result<Vec<T>> {
    let (file, _) = crate::fs::open(path)?;
    let mut de = serde_json::Deserializer::from_reader(BufReader::with_capacity(1 << 20, file));
    let rows = Filter {
        keep,
        rows: Vec::new(),
    }
    .deserialize(&mut de)
    .and_then(|rows| de.end().map(|_| rows))
    .map_err(|e| Error::NotFormat {
        path: path.into(),
        format: "a nuScenes table (a JSON array of records)",
        detail: e.to_string(),
    })?;
    Ok(rows)
}

/// A sequence visitor keeping the elements `keep` keeps.
struct Filter<T, F> {
    keep: F,
    rows: Vec<T>,
}

impl<'de, T: DeserializeOwned, F: FnMut(&T) -> bool> DeserializeSeed<'de> for Filter<T, F> {
    type Value = Vec<T>;
    fn deserialize<D: serde::Deserializer<'de>>(
        self,
        d: D,
    ) -> std::result::Result<Vec<T>, D::Error> {
        d.deserialize_seq(self)
    }
}

impl<'de, T: DeserializeOwned, F: FnMut(&T) -> bool> Visitor<'de> for Filter<T, F> {
    type Value = Vec<T>;
    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("an array of records")
    }
    fn visit_seq<A: SeqAccess<'de>>(mut self, mut seq: A) -> std::result::Result<Vec<T>, A::Error> {
        while let Some(row) = seq.next_element::<T>()? {
            if (self.keep)(&row) {
                self.rows.push(row);
            }
        }
        Ok(self.rows)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scene_names_give_their_numbers() {
        let t = Path::new("scene.json");
        assert_eq!(scene_number("scene-0061", t).unwrap(), 61);
        assert_eq!(scene_number("scene-1077", t).unwrap(), 1077);
        for bad in ["scene-", "scene-12345", "61", "scene-6a"] {
            assert!(scene_number(bad, t).is_err(), "{bad}");
        }
    }
}
