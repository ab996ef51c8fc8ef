//! Xtreme1's (and BasicAI's) export: a dataset folder with `point_cloud/<name>.pcd` and
//! `result/<name>.json` (Xtreme1 docs, "Export data": folder structure, "Data annotation
//! result"). A result file is a list of annotation sources (`sourceName`: `Ground Truth`, a
//! model run), each with `objects`; a `3D_BOX` object has `className`, `trackId` and a
//! `contour` with `center3D` (the box centre), `size3D` (full extents along the box's x, y, z)
//! and `rotation3D` (Euler angles x, y, z in radians), in the point cloud's frame (the docs'
//! "Coordinate System": positions are relative to the point cloud's coordinate system).
//!
//! The rotation is applied in three.js's `XYZ` order (`Rx * Ry * Rz`), as the tool's web editor
//! is built on three.js (**assumed**: the docs' example turns about z alone, where every order
//! agrees). Objects of other types (`2D_BOX`, `2D_RECT`, ...) are passed over. A file with 3D
//! boxes from several sources uses its `Ground Truth` source; without one it is an error that
//! names them. A track is the object's `trackId` (its `id` without one).

use std::collections::HashSet;
use std::path::{Path, PathBuf};

use serde_json::Value;

use super::{centred_xyz_euler, read_json, xyz, AnnotatedFrame, Annotations, BoxFormat, Tracks};
use crate::error::{Error, Result};
use crate::source::boxes::AnnotatedBox;

/// The result folder at `path`: `path/result`, or `path` itself.
fn result_dir(path: &Path) -> PathBuf {
    if path.join("result").is_dir() {
        path.join("result")
    } else {
        path.into()
    }
}

fn json_files(dir: &Path) -> Result<Vec<PathBuf>> {
    Ok(crate::fs::sorted_dir(dir)?
        .into_iter()
        .filter(|p| p.extension().is_some_and(|e| e == "json"))
        .collect())
}

/// Whether `path` is an Xtreme1 export (a `result/` folder beside `point_cloud/`).
pub fn looks_like(path: &Path) -> bool {
    let dir = result_dir(path);
    dir.file_name().is_some_and(|n| n == "result")
        && dir.with_file_name("point_cloud").is_dir()
        && json_files(&dir).is_ok_and(|f| !f.is_empty())
}

/// Reads the export (or its `result/` folder) at `path`.
pub fn read(path: &Path) -> Result<Annotations> {
    let dir = result_dir(path);
    let files = if dir.is_dir() {
        json_files(&dir)?
    } else {
        Vec::new()
    };
    if files.is_empty() {
        return Err(Error::Input {
            path: path.into(),
            message: "no Xtreme1 annotation results (result/<name>.json)".into(),
        });
    }
    super::frames_by_stem(BoxFormat::Xtreme1, files, read_frame)
}

/// Whether an object is a 3D box.
fn is_box(o: &Value) -> bool {
    o.get("type").and_then(Value::as_str) == Some("3D_BOX")
}

/// The source of a result file whose 3D boxes are read.
fn source<'a>(file: &Path, root: &'a Value) -> Result<Option<&'a Value>> {
    let sources: Vec<&Value> = match root {
        Value::Array(a) => a.iter().collect(),
        Value::Object(_) => vec![root],
        _ => {
            return Err(Error::format(
                file,
                "not an Xtreme1 result (a list of sources)",
            ))
        }
    };
    let with_boxes: Vec<&Value> = (sources.into_iter())
        .filter(|s| {
            let objects = s.get("objects").and_then(Value::as_array);
            objects.is_some_and(|o| o.iter().any(is_box))
        })
        .collect();
    let name = |s: &Value| {
        s.get("sourceName")
            .and_then(Value::as_str)
            .unwrap_or("?")
            .to_string()
    };
    match with_boxes.as_slice() {
        [] => Ok(None),
        [one] => Ok(Some(one)),
        many => many
            .iter()
            .find(|s| name(s).eq_ignore_ascii_case("ground truth"))
            .map(|s| Some(*s))
            .ok_or_else(|| {
                let names: Vec<String> = many.iter().map(|s| name(s)).collect();
                Error::format(
                    file,
                    format!(
                        "3D boxes from {} sources ({}) and none is \"Ground Truth\"",
                        many.len(),
                        names.join(", ")
                    ),
                )
            }),
    }
}

/// One result file's 3D boxes.
fn read_frame(file: &Path, scan: String, tracks: &mut Tracks) -> Result<AnnotatedFrame> {
    let root = read_json(file)?;
    let mut boxes = Vec::new();
    let mut seen = HashSet::new();
    let objects = (source(file, &root)?)
        .and_then(|s| s.get("objects"))
        .and_then(Value::as_array);
    for (i, o) in objects
        .into_iter()
        .flatten()
        .enumerate()
        .filter(|(_, o)| is_box(o))
    {
        let id = o.get("id").and_then(Value::as_str).unwrap_or("");
        let what = format!("object {i} ({id})");
        let class = o.get("className").and_then(Value::as_str);
        let class =
            class.ok_or_else(|| Error::format(file, format!("{what}: no \"className\"")))?;
        let track = o.get("trackId").and_then(Value::as_str).unwrap_or(id);
        if track.is_empty() {
            return Err(Error::format(
                file,
                format!("{what}: no \"trackId\" or \"id\""),
            ));
        }
        if !seen.insert(track) {
            return Err(Error::format(
                file,
                format!("{what}: track {track} has a second 3D box in the frame"),
            ));
        }
        let c = o.get("contour");
        let c = c.ok_or_else(|| Error::format(file, format!("{what}: no \"contour\"")))?;
        let centre = xyz(c.get("center3D"), "center3D", file, &what)?;
        let size = xyz(c.get("size3D"), "size3D", file, &what)?;
        let rotation = xyz(c.get("rotation3D"), "rotation3D", file, &what)?;
        boxes.push(AnnotatedBox {
            geometry: centred_xyz_euler(file, &what, centre, size, rotation)?,
            class_name: class.to_string(),
            track: tracks.of(track),
        });
    }
    Ok(AnnotatedFrame {
        scan,
        file: file.into(),
        boxes,
        points: None,
    })
}
