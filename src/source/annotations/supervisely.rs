//! The Supervisely point cloud format (also CVAT's "Sly Point Cloud" export, through Datumaro's
//! `sly_pointcloud` plugin): a project folder (`meta.json`, `key_id_map.json`) of datasets, each
//! with `pointcloud/<name>.pcd` and `ann/<name>.pcd.json`. An annotation file lists `objects`
//! (`key`, `classTitle`) and `figures` (`objectKey`, `geometryType`, `geometry`); a
//! `cuboid_3d` figure's geometry is `position` (the box centre), `rotation` (Euler angles x, y, z
//! in radians) and `dimensions` (full extents along the box's x, y, z), in the point cloud's
//! frame (Supervisely's SDK, `supervisely.geometry.cuboid_3d`; Datumaro's format page).
//!
//! The rotation is applied in the `XYZ` order of three.js, on which the web editors of both
//! tools are built (`Rx * Ry * Rz`); the tools turn cuboids about z alone, where every order
//! agrees. An object is one track across the files (its `key`); figures of other shapes are
//! passed over.

use std::collections::{BTreeMap, HashSet};
use std::path::{Path, PathBuf};

use serde_json::Value;

use super::{centred_xyz_euler, read_json, xyz, AnnotatedFrame, Annotations, BoxFormat, Tracks};
use crate::error::{Error, Result};
use crate::source::boxes::AnnotatedBox;

/// The annotation folders under `path`: `path` itself when it is one (`ann/`), its `ann/`, or
/// each dataset's `ann/` in a project folder.
fn ann_dirs(path: &Path) -> Vec<PathBuf> {
    if path.file_name().is_some_and(|n| n == "ann") && path.is_dir() {
        return vec![path.into()];
    }
    if path.join("ann").is_dir() {
        return vec![path.join("ann")];
    }
    let mut dirs: Vec<PathBuf> = (std::fs::read_dir(path).into_iter().flatten().flatten())
        .map(|e| e.path().join("ann"))
        .filter(|p| p.is_dir())
        .collect();
    dirs.sort();
    dirs
}

/// The annotation files (`*.pcd.json`) under `path`.
fn ann_files(path: &Path) -> Result<Vec<PathBuf>> {
    let mut out = Vec::new();
    for dir in ann_dirs(path) {
        out.extend(
            crate::fs::sorted_dir(&dir)?
                .into_iter()
                .filter(|p| p.to_str().is_some_and(|s| s.ends_with(".pcd.json"))),
        );
    }
    Ok(out)
}

/// Whether `path` holds Supervisely point cloud annotations.
pub fn looks_like(path: &Path) -> bool {
    ann_files(path).is_ok_and(|f| !f.is_empty())
}

/// Reads the project, dataset or `ann/` folder at `path`.
pub fn read(path: &Path) -> Result<Annotations> {
    let files = ann_files(path)?;
    if files.is_empty() {
        return Err(Error::Input {
            path: path.into(),
            message: "no Supervisely point cloud annotations (ann/<name>.pcd.json)".into(),
        });
    }
    let mut tracks = Tracks::default();
    let mut frames: BTreeMap<String, AnnotatedFrame> = BTreeMap::new();
    for file in files {
        let name = file.file_name().and_then(|n| n.to_str()).unwrap_or("");
        let scan = name.trim_end_matches(".pcd.json").to_string();
        let frame = read_frame(&file, scan.clone(), &mut tracks)?;
        if let Some(other) = frames.insert(scan.clone(), frame) {
            return Err(Error::Input {
                path: file,
                message: format!("annotates scan {scan} as {} does", other.file.display()),
            });
        }
    }
    Ok(Annotations {
        format: BoxFormat::Supervisely,
        frames,
        tracks: tracks.ids,
    })
}

/// One annotation file's cuboids.
fn read_frame(file: &Path, scan: String, tracks: &mut Tracks) -> Result<AnnotatedFrame> {
    let root = read_json(file)?;
    let list = |key: &str| -> Result<&Vec<Value>> {
        root.get(key).and_then(Value::as_array).ok_or_else(|| {
            Error::format(
                file,
                format!("no \"{key}\" list: not a Supervisely annotation"),
            )
        })
    };
    let mut classes: BTreeMap<&str, &str> = BTreeMap::new();
    for (i, o) in list("objects")?.iter().enumerate() {
        let key = o.get("key").and_then(Value::as_str);
        let class = o.get("classTitle").and_then(Value::as_str);
        let (Some(key), Some(class)) = (key, class) else {
            return Err(Error::format(
                file,
                format!("object {i}: no \"key\" or \"classTitle\""),
            ));
        };
        if classes.insert(key, class).is_some() {
            return Err(Error::format(file, format!("object {key} is listed twice")));
        }
    }
    let mut boxes = Vec::new();
    let mut placed = HashSet::new();
    for (i, f) in list("figures")?.iter().enumerate() {
        if f.get("geometryType").and_then(Value::as_str) != Some("cuboid_3d") {
            continue;
        }
        let key = f.get("objectKey").and_then(Value::as_str).unwrap_or("");
        let what = format!("figure {i} (object {key})");
        let class = classes.get(key).ok_or_else(|| {
            Error::format(
                file,
                format!("{what}: its object is not among the file's objects"),
            )
        })?;
        if !placed.insert(key) {
            return Err(Error::format(
                file,
                format!("{what}: a second cuboid of the object"),
            ));
        }
        let g = f.get("geometry");
        let g = g.ok_or_else(|| Error::format(file, format!("{what}: no \"geometry\"")))?;
        let position = xyz(g.get("position"), "position", file, &what)?;
        let rotation = xyz(g.get("rotation"), "rotation", file, &what)?;
        let dimensions = xyz(g.get("dimensions"), "dimensions", file, &what)?;
        boxes.push(AnnotatedBox {
            geometry: centred_xyz_euler(file, &what, position, dimensions, rotation)?,
            class_name: class.to_string(),
            track: tracks.of(key),
        });
    }
    Ok(AnnotatedFrame {
        scan,
        file: file.into(),
        boxes,
        points: None,
    })
}
