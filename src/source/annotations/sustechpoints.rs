//! SUSTechPOINTS' labels: a scene folder with `lidar/<frame>.pcd` and `label/<frame>.json`, one
//! file a frame holding its objects (a list, or `{"objs": [...]}` as later versions write it):
//! `obj_type` (the class name), `obj_id` (the object's id across the scene's frames) and `psr`:
//! `position` (the box centre), `scale` (full extents along the box's x, y, z) and `rotation`
//! (Euler angles x, y, z in radians, applied as `Rx * Ry * Rz`: the tool's
//! `tools/utils.py::euler_angle_to_rotate_matrix`), in the point cloud's frame.

use std::collections::HashSet;
use std::path::{Path, PathBuf};

use serde_json::Value;

use super::{centred_xyz_euler, read_json, xyz, AnnotatedFrame, Annotations, BoxFormat, Tracks};
use crate::error::{Error, Result};
use crate::source::boxes::AnnotatedBox;

/// The label folder of the scene at `path` (or `path` itself when it is one).
fn label_dir(path: &Path) -> PathBuf {
    if path.join("label").is_dir() {
        path.join("label")
    } else {
        path.into()
    }
}

/// Whether `path` holds SUSTechPOINTS labels: a `label/` folder of `.json` files beside `lidar/`.
pub fn looks_like(path: &Path) -> bool {
    let dir = label_dir(path);
    dir.file_name().is_some_and(|n| n == "label")
        && dir.with_file_name("lidar").is_dir()
        && crate::fs::sorted_dir(&dir).is_ok_and(|f| f.iter().any(|p| is_json(p)))
}

fn is_json(p: &Path) -> bool {
    p.extension().is_some_and(|e| e == "json")
}

/// Reads the scene (or `label/` folder) at `path`.
pub fn read(path: &Path) -> Result<Annotations> {
    let dir = label_dir(path);
    if !dir.is_dir() {
        return Err(Error::Input {
            path: path.into(),
            message: "no SUSTechPOINTS label folder (label/<frame>.json)".into(),
        });
    }
    let files: Vec<PathBuf> = (crate::fs::sorted_dir(&dir)?.into_iter())
        .filter(|p| is_json(p))
        .collect();
    if files.is_empty() {
        return Err(Error::Input {
            path: dir,
            message: "holds no label file (<frame>.json)".into(),
        });
    }
    super::frames_by_stem(BoxFormat::SusTechPoints, files, read_frame)
}

/// One frame's label file.
fn read_frame(file: &Path, scan: String, tracks: &mut Tracks) -> Result<AnnotatedFrame> {
    let root = read_json(file)?;
    let objects = match &root {
        Value::Array(a) => a,
        Value::Object(o) => o.get("objs").and_then(Value::as_array).ok_or_else(|| {
            Error::format(
                file,
                "an object without an \"objs\" list: not a SUSTechPOINTS label",
            )
        })?,
        _ => {
            return Err(Error::format(
                file,
                "not a list of objects: not a SUSTechPOINTS label",
            ))
        }
    };
    let mut seen = HashSet::new();
    let mut boxes = Vec::with_capacity(objects.len());
    for (i, o) in objects.iter().enumerate() {
        let id = match o.get("obj_id") {
            Some(Value::String(s)) if !s.is_empty() => s.clone(),
            Some(Value::Number(n)) => n.to_string(),
            // No id: the box is a track of its own.
            _ => format!("{scan}#{i}"),
        };
        let what = format!("object {i} (obj_id {id})");
        if !seen.insert(id.clone()) {
            return Err(Error::format(
                file,
                format!("{what}: the id is in the frame twice"),
            ));
        }
        let class = o
            .get("obj_type")
            .and_then(Value::as_str)
            .ok_or_else(|| Error::format(file, format!("{what}: no \"obj_type\"")))?;
        let psr = o.get("psr");
        let psr = psr.ok_or_else(|| Error::format(file, format!("{what}: no \"psr\"")))?;
        let position = xyz(psr.get("position"), "position", file, &what)?;
        let scale = xyz(psr.get("scale"), "scale", file, &what)?;
        let rotation = xyz(psr.get("rotation"), "rotation", file, &what)?;
        boxes.push(AnnotatedBox {
            geometry: centred_xyz_euler(file, &what, position, scale, rotation)?,
            class_name: class.to_string(),
            track: tracks.of(&id),
        });
    }
    Ok(AnnotatedFrame {
        scan,
        file: file.into(),
        boxes,
        points: None,
    })
}
