//! ASAM OpenLABEL 1.0 (JSON; the standard's schema, `openlabel_json_schema_v1.0.0`, and its
//! reference library, Vicomtech's VCD): one `.json` file, or a folder of them, each an
//! `openlabel` object with `objects` (by uid: `name`, `type`, static `object_data`) and
//! `frames` (by frame number: `objects` with per-frame `object_data`, `frame_properties` with
//! `streams` and their `uri`).
//!
//! A `cuboid`'s `val` is 9 numbers, `(x, y, z, rx, ry, rz, sx, sy, sz)`: the centre, Euler
//! angles applied `Rz(rz) * Ry(ry) * Rx(rx)` (VCD's `generate_cuboid_points_ref_4x8`:
//! `euler2R([rz, ry, rx])`, sequence `ZYX`) and the extents along the box's x, y, z; or 10,
//! `(x, y, z, qx, qy, qz, qw, sx, sy, sz)` with a rotation quaternion. Each names its
//! `coordinate_system`; kitti2pgm takes it to be the scan's (boxes in another frame, a vehicle
//! frame, are moved with `--sensor-pose`), and cuboids of one file in two coordinate systems
//! are an error naming both. An object's uid is its track; its `type` the class name. A frame's
//! scan is the file stem of a stream `uri` in its `frame_properties`; else, for a file of one
//! frame, the file's stem; else the frame number. Static cuboids (an object's own
//! `object_data`) hold in each frame of its `frame_intervals` (every frame without them; the
//! file's one frame when it has no `frames`).

use std::collections::{BTreeMap, HashSet};
use std::path::{Path, PathBuf};

use serde_json::{Map, Value};

use super::{
    centred_euler, centred_quaternion, read_json, AnnotatedFrame, Annotations, BoxFormat,
    EulerOrder, Tracks,
};
use crate::error::{Error, Result};
use crate::source::boxes::AnnotatedBox;

/// The `.json` files at `path` (itself, or a folder's).
fn files(path: &Path) -> Result<Vec<PathBuf>> {
    if path.is_file() {
        return Ok(vec![path.into()]);
    }
    Ok(crate::fs::sorted_dir(path)?
        .into_iter()
        .filter(|p| p.extension().is_some_and(|e| e == "json"))
        .collect())
}

/// Whether `path` holds OpenLABEL files.
pub fn looks_like(path: &Path) -> bool {
    files(path).is_ok_and(|f| {
        f.first()
            .is_some_and(|f| read_json(f).is_ok_and(|v| v.get("openlabel").is_some()))
    })
}

/// Reads the OpenLABEL file, or folder of files, at `path`.
pub fn read(path: &Path) -> Result<Annotations> {
    let files = files(path)?;
    if files.is_empty() {
        return Err(Error::Input {
            path: path.into(),
            message: "no OpenLABEL file (.json)".into(),
        });
    }
    let mut tracks = Tracks::default();
    let mut frames: BTreeMap<String, AnnotatedFrame> = BTreeMap::new();
    for file in files {
        for frame in read_file(&file, &mut tracks)? {
            let scan = frame.scan.clone();
            if let Some(other) = frames.insert(scan.clone(), frame) {
                return Err(Error::Input {
                    path: file,
                    message: format!("annotates scan {scan} as {} does", other.file.display()),
                });
            }
        }
    }
    Ok(Annotations {
        format: BoxFormat::OpenLabel,
        frames,
        tracks: tracks.ids,
    })
}

/// An object's data: its type and static cuboids.
struct Object<'a> {
    kind: &'a str,
    cuboids: Vec<&'a Value>,
    /// Frame intervals of its static data (empty: every frame).
    intervals: Vec<(u64, u64)>,
}

/// One file's frames.
fn read_file(file: &Path, tracks: &mut Tracks) -> Result<Vec<AnnotatedFrame>> {
    let root = read_json(file)?;
    let ol = root.get("openlabel").and_then(Value::as_object);
    let ol =
        ol.ok_or_else(|| Error::format(file, "no \"openlabel\" object: not an OpenLABEL file"))?;
    let empty = Map::new();
    let objects = objects_of(file, ol)?;
    let numbered = numbered_frames(file, ol)?;
    let single = numbered.len() == 1;
    let mut systems: BTreeMap<String, String> = BTreeMap::new();
    let mut out = Vec::with_capacity(numbered.len());
    for (n, f) in numbered {
        let scan = scan_name(f, file, n, single);
        let what = format!("frame {n}");
        let mut boxes = Vec::new();
        let mut placed = HashSet::new();
        let per_frame = f
            .get("objects")
            .and_then(Value::as_object)
            .unwrap_or(&empty);
        for (uid, o) in &objects {
            let statics =
                o.intervals.is_empty() || o.intervals.iter().any(|&(a, b)| (a..=b).contains(&n));
            let dynamic = per_frame.get(*uid).map(cuboids_of).unwrap_or_default();
            let all = (statics.then_some(&o.cuboids).into_iter().flatten()).chain(&dynamic);
            for c in all {
                let obj = format!("{what} object {uid}");
                if !placed.insert(*uid) {
                    return Err(Error::format(
                        file,
                        format!("{obj}: a second cuboid of the object"),
                    ));
                }
                note_system(file, &obj, c, &mut systems)?;
                boxes.push(AnnotatedBox {
                    geometry: cuboid(file, &obj, c)?,
                    class_name: o.kind.to_string(),
                    track: tracks.of(uid),
                });
            }
        }
        if let Some(uid) = per_frame.keys().find(|k| !objects.contains_key(k.as_str())) {
            return Err(Error::format(
                file,
                format!("{what}: object {uid} is not among the file's objects"),
            ));
        }
        out.push(AnnotatedFrame {
            scan,
            file: file.into(),
            boxes,
            points: None,
        });
    }
    Ok(out)
}

/// A file's objects by uid.
fn objects_of<'a>(
    file: &Path,
    ol: &'a Map<String, Value>,
) -> Result<BTreeMap<&'a str, Object<'a>>> {
    let mut objects = BTreeMap::new();
    for (uid, o) in ol
        .get("objects")
        .and_then(Value::as_object)
        .into_iter()
        .flatten()
    {
        let kind = o.get("type").and_then(Value::as_str);
        let kind = kind.ok_or_else(|| Error::format(file, format!("object {uid}: no \"type\"")))?;
        let object = Object {
            kind,
            cuboids: cuboids_of(o),
            intervals: intervals(o),
        };
        objects.insert(uid.as_str(), object);
    }
    Ok(objects)
}

/// A file's frames with their numbers (one frame 0 without data when it has no `frames`).
fn numbered_frames<'a>(file: &Path, ol: &'a Map<String, Value>) -> Result<Vec<(u64, &'a Value)>> {
    let Some(frames) = ol.get("frames").and_then(Value::as_object) else {
        return Ok(vec![(0, &Value::Null)]);
    };
    (frames.iter())
        .map(|(k, v)| {
            let n = k
                .parse::<u64>()
                .map_err(|_| Error::format(file, format!("frame {k:?} is not a frame number")))?;
            Ok((n, v))
        })
        .collect()
}

/// The cuboids of an object's `object_data`.
fn cuboids_of(o: &Value) -> Vec<&Value> {
    (o.pointer("/object_data/cuboid").and_then(Value::as_array))
        .map(|a| a.iter().collect())
        .unwrap_or_default()
}

/// An object's `frame_intervals`.
fn intervals(o: &Value) -> Vec<(u64, u64)> {
    (o.get("frame_intervals")
        .and_then(Value::as_array)
        .into_iter()
        .flatten())
    .filter_map(|i| {
        let a = i.get("frame_start").and_then(Value::as_u64)?;
        let b = i.get("frame_end").and_then(Value::as_u64)?;
        Some((a, b))
    })
    .collect()
}

/// A frame's scan name ([module docs](self)).
fn scan_name(frame: &Value, file: &Path, n: u64, single: bool) -> String {
    let uri = (frame
        .pointer("/frame_properties/streams")
        .and_then(Value::as_object))
    .into_iter()
    .flat_map(|s| s.values())
    .find_map(|s| s.get("uri").and_then(Value::as_str));
    match uri {
        Some(u) => super::uri_stem(u),
        None if single => file
            .file_stem()
            .map_or(n.to_string(), |s| s.to_string_lossy().into_owned()),
        None => n.to_string(),
    }
}

/// Records a cuboid's coordinate system; a second one in the file is an error.
fn note_system(
    file: &Path,
    what: &str,
    c: &Value,
    seen: &mut BTreeMap<String, String>,
) -> Result<()> {
    let cs = c
        .get("coordinate_system")
        .and_then(Value::as_str)
        .unwrap_or("");
    if let Some((other, at)) = seen.iter().next().filter(|(s, _)| s.as_str() != cs) {
        return Err(Error::format(
            file,
            format!(
                "{what}: a cuboid in coordinate system {cs:?}, {at}'s in {other:?}: kitti2pgm reads one (the scan's)"
            ),
        ));
    }
    seen.entry(cs.to_string())
        .or_insert_with(|| what.to_string());
    Ok(())
}

/// A cuboid's box, from its 9 (Euler) or 10 (quaternion) values.
fn cuboid(file: &Path, what: &str, c: &Value) -> Result<crate::source::boxes::Box3> {
    let val = c.get("val").and_then(Value::as_array);
    let val =
        val.ok_or_else(|| Error::format(file, format!("{what}: a cuboid without \"val\"")))?;
    let v: Vec<f64> = (val.iter().map(Value::as_f64).collect::<Option<_>>()).ok_or_else(|| {
        Error::format(
            file,
            format!("{what}: a cuboid \"val\" that is not all numbers"),
        )
    })?;
    match *v.as_slice() {
        [x, y, z, rx, ry, rz, sx, sy, sz] => centred_euler(
            file,
            what,
            ([x, y, z], [sx, sy, sz]),
            [rx, ry, rz],
            EulerOrder::Zyx,
        ),
        [x, y, z, qx, qy, qz, qw, sx, sy, sz] => {
            centred_quaternion(file, what, [x, y, z], [sx, sy, sz], [qx, qy, qz, qw])
        }
        _ => Err(Error::format(
            file,
            format!(
                "{what}: a cuboid of {} values (OpenLABEL's have 9 or 10)",
                v.len()
            ),
        )),
    }
}
