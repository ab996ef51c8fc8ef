//! labelCloud's centroid formats: a label folder (`labels/`, the tool's default) holding
//! `<point cloud stem>.json` for each labelled cloud (`_classes.json`, the class definitions,
//! beside them), each with `objects`: `name` (the class), `centroid` (x, y, z: the box centre),
//! `dimensions` (`length`, `width`, `height`: the full extents along the box's x, y, z) and
//! `rotations` (x, y, z), applied as `Rz(z) * Ry(y) * Rx(x)` (the tool's
//! `utils/math3d.py::rotate_around_zyx`, and its OpenGL drawing). `centroid_abs` (the tool's
//! default `label_format`) writes the angles in degrees (0-360), `centroid_rel` in radians
//! (-pi..pi); the files do not say which: option `angles`, default degrees. labelCloud gives a
//! box no id across frames: each box is a track of its own.

use std::path::{Path, PathBuf};

use serde_json::Value;

use super::{
    check_box, number, read_json, xyz, AngleUnit, AnnotatedFrame, Annotations, BoxFormat,
    ReadOptions, Tracks,
};
use crate::error::{Error, Result};
use crate::source::boxes::{AnnotatedBox, BoxConvention, BoxRotation};

/// The label folder of `path`: its `labels/`, or itself.
fn label_dir(path: &Path) -> PathBuf {
    if path.join("labels").is_dir() {
        path.join("labels")
    } else {
        path.into()
    }
}

/// The label files under `path` (`*.json` but `_classes.json`).
fn label_files(path: &Path) -> Result<Vec<PathBuf>> {
    Ok(crate::fs::sorted_dir(&label_dir(path))?
        .into_iter()
        .filter(|p| p.is_file() && p.extension().is_some_and(|e| e == "json"))
        .filter(|p| p.file_name().is_some_and(|n| n != "_classes.json"))
        .collect())
}

/// Whether `path` holds labelCloud's centroid labels (its first file has `centroid`s).
pub fn looks_like(path: &Path) -> bool {
    let first = label_files(path).ok().and_then(|f| f.into_iter().next());
    first.is_some_and(|f| {
        crate::fs::read_text(&f, crate::fs::Limit::Text)
            .is_ok_and(|t| t.contains("\"objects\"") && t.contains("\"centroid\""))
    })
}

/// Reads the label folder (or the project holding `labels/`) at `path`.
pub fn read(path: &Path, opts: &ReadOptions) -> Result<Annotations> {
    let files = label_files(path)?;
    if files.is_empty() {
        return Err(Error::Input {
            path: path.into(),
            message: "no labelCloud label file (labels/<point cloud>.json)".into(),
        });
    }
    let radians_per_unit = match opts.angles.unwrap_or(AngleUnit::Degrees) {
        AngleUnit::Degrees => std::f64::consts::PI / 180.0,
        AngleUnit::Radians => 1.0,
    };
    super::frames_by_stem(BoxFormat::LabelCloud, files, |file, scan, tracks| {
        read_frame(file, scan, tracks, radians_per_unit)
    })
}

/// One label file's boxes, its angles in `radians_per_unit`.
fn read_frame(
    file: &Path,
    scan: String,
    tracks: &mut Tracks,
    radians_per_unit: f64,
) -> Result<AnnotatedFrame> {
    let root = read_json(file)?;
    let objects = root
        .get("objects")
        .and_then(Value::as_array)
        .ok_or_else(|| {
            Error::format(file, "no \"objects\" list: not a labelCloud centroid label")
        })?;
    let mut boxes = Vec::with_capacity(objects.len());
    for (i, o) in objects.iter().enumerate() {
        let what = format!("object {i}");
        let class = o.get("name").and_then(Value::as_str);
        let class = class.ok_or_else(|| Error::format(file, format!("{what}: no \"name\"")))?;
        let what = format!("object {i} ({class})");
        let centre = xyz(o.get("centroid"), "centroid", file, &what)?;
        let d = o.get("dimensions");
        let d = d.ok_or_else(|| Error::format(file, format!("{what}: no \"dimensions\"")))?;
        let w = |k: &str| number(d, k, file, &format!("{what} dimensions"));
        let sizes = [w("length")?, w("width")?, w("height")?];
        let angles = xyz(o.get("rotations"), "rotations", file, &what)?;
        check_box(file, &what, centre, sizes, &angles)?;
        let geometry = BoxConvention::CENTRED_LWH.place(
            centre,
            sizes,
            &BoxRotation::Euler(angles.map(|a| a * radians_per_unit)),
            None,
        );
        boxes.push(AnnotatedBox {
            geometry,
            class_name: class.to_string(),
            track: tracks.of(&format!("{scan}#{i}")),
        });
    }
    Ok(AnnotatedFrame {
        scan,
        file: file.into(),
        boxes,
        points: None,
    })
}
