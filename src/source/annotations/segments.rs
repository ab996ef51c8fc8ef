//! Segments.ai's release file (one JSON file; Segments.ai docs, "Structure of the release
//! file", "Label formats", "Sample formats"): `dataset.task_attributes.categories` (`id`,
//! `name`) and `dataset.samples`, each with its `attributes` (a point cloud: `pcd.url`,
//! optional `name` and `ego_pose`; a sequence: `frames` of those) and its `labels` by label set
//! (`ground-truth`), whose `attributes` hold the `annotations` (a sequence: `frames` of them).
//!
//! A `cuboid` annotation has `position` (the centre, "in world coordinates"), `dimensions` x,
//! y, z (length, width, height: the extents along the box's x, y, z), `yaw` (radians about z)
//! and, where 3D rotation is on in the dataset, `rotation` (a quaternion `qx qy qz qw`, taken
//! before the yaw); `track_id` in sequences. Where a frame has an `ego_pose` (the sensor's
//! `position` and `heading` quaternion in the world), the boxes are brought into the scan's
//! frame by its inverse; without one the world is the scan's frame. A frame's scan is its
//! `name`, else the stem of its point cloud's URL. A segmentation label's `point_annotations`
//! (each point's object id, in the point cloud's order, 0 for none) is each point's annotation,
//! its objects' categories their classes. Annotations of other types are passed over; a label
//! set other than `ground-truth` is read only when it is the sample's one.

use std::collections::BTreeMap;
use std::path::Path;

use serde_json::Value;

use super::{
    centred_quaternion, number, read_json, unit_quaternion, xyz, AnnotatedFrame, Annotations,
    BoxFormat, PointAnnotations, Tracks,
};
use crate::error::{Error, Result};
use crate::geom::na;
use crate::source::boxes::{AnnotatedBox, BoxConvention, BoxRotation};

/// Whether `path` is a Segments.ai release file.
pub fn looks_like(path: &Path) -> bool {
    path.is_file()
        && path.extension().is_some_and(|e| e == "json")
        && read_json(path).is_ok_and(|v| v.pointer("/dataset/samples").is_some())
}

/// Reads the release file at `path`.
pub fn read(path: &Path) -> Result<Annotations> {
    if !path.is_file() {
        return Err(Error::Input {
            path: path.into(),
            message: "not a Segments.ai release file (a .json file)".into(),
        });
    }
    let root = read_json(path)?;
    let samples = root.pointer("/dataset/samples").and_then(Value::as_array);
    let samples = samples.ok_or_else(|| {
        Error::format(
            path,
            "no \"dataset\".\"samples\" list: not a Segments.ai release file",
        )
    })?;
    let categories = categories(path, &root)?;
    let mut r = Reader {
        file: path,
        categories,
        tracks: Tracks::default(),
        frames: BTreeMap::new(),
    };
    for (i, s) in samples.iter().enumerate() {
        r.sample(i, s)?;
    }
    Ok(Annotations {
        format: BoxFormat::SegmentsAi,
        frames: r.frames,
        tracks: r.tracks.ids,
    })
}

/// The category names by id.
fn categories(file: &Path, root: &Value) -> Result<BTreeMap<u64, String>> {
    let list = root
        .pointer("/dataset/task_attributes/categories")
        .and_then(Value::as_array);
    let list = list.ok_or_else(|| {
        Error::format(
            file,
            "no \"dataset\".\"task_attributes\".\"categories\" list",
        )
    })?;
    let mut out = BTreeMap::new();
    for (i, c) in list.iter().enumerate() {
        let id = c.get("id").and_then(Value::as_u64);
        let name = c.get("name").and_then(Value::as_str);
        let (Some(id), Some(name)) = (id, name) else {
            return Err(Error::format(
                file,
                format!("category {i}: no \"id\" or \"name\""),
            ));
        };
        out.insert(id, name.to_string());
    }
    Ok(out)
}

struct Reader<'a> {
    file: &'a Path,
    categories: BTreeMap<u64, String>,
    tracks: Tracks,
    frames: BTreeMap<String, AnnotatedFrame>,
}

impl Reader<'_> {
    /// One sample: a point cloud or a sequence of them.
    fn sample(&mut self, i: usize, s: &Value) -> Result<()> {
        let sample = s
            .get("name")
            .and_then(Value::as_str)
            .unwrap_or("")
            .to_string();
        let what = format!("sample {i} ({sample})");
        let Some(label) = label_attributes(self.file, &what, s)? else {
            return Ok(());
        };
        let attributes = s.get("attributes").unwrap_or(&Value::Null);
        match attributes.get("frames").and_then(Value::as_array) {
            Some(frames) => {
                let labels = label.get("frames").and_then(Value::as_array);
                let labels = labels.ok_or_else(|| {
                    Error::format(
                        self.file,
                        format!("{what}: a sequence whose label has no \"frames\""),
                    )
                })?;
                for (k, (f, l)) in frames.iter().zip(labels).enumerate() {
                    self.frame(&format!("{what} frame {k}"), &sample, f, l)?;
                }
                Ok(())
            }
            None => self.frame(&what, &sample, attributes, label),
        }
    }

    /// One point cloud's cuboids and per-point annotations.
    fn frame(&mut self, what: &str, sample: &str, attributes: &Value, label: &Value) -> Result<()> {
        let scan = scan_name(attributes, sample);
        let to_scan = ego_pose(self.file, what, attributes)?.map(|p| p.inverse());
        let mut boxes = Vec::new();
        let mut objects: BTreeMap<u32, (String, usize)> = BTreeMap::new();
        let list = label.get("annotations").and_then(Value::as_array);
        for a in list.into_iter().flatten() {
            let id = a.get("id").and_then(Value::as_u64).unwrap_or(0);
            let obj = format!("{what} annotation {id}");
            let (class, track) = self.object(&obj, sample, id, a)?;
            let id = u32::try_from(id).map_err(|_| {
                Error::format(self.file, format!("{obj}: an object id beyond 32 bits"))
            })?;
            if objects.insert(id, (class.clone(), track)).is_some() {
                return Err(Error::format(
                    self.file,
                    format!("{obj}: id {id} twice in the frame"),
                ));
            }
            if a.get("type").and_then(Value::as_str) == Some("cuboid") {
                let mut geometry = cuboid(self.file, &obj, a)?;
                if let Some(m) = &to_scan {
                    geometry = geometry.moved(m);
                }
                boxes.push(AnnotatedBox {
                    geometry,
                    class_name: class,
                    track,
                });
            }
        }
        let points = match label.get("point_annotations").and_then(Value::as_array) {
            Some(ids) => Some(self.point_annotations(what, ids, objects)?),
            None => None,
        };
        let frame = AnnotatedFrame {
            scan: scan.clone(),
            file: self.file.into(),
            boxes,
            points,
        };
        if self.frames.insert(scan.clone(), frame).is_some() {
            return Err(Error::format(
                self.file,
                format!("{what}: scan {scan} is annotated twice"),
            ));
        }
        Ok(())
    }

    /// An annotation's class name (by its category) and track.
    fn object(&mut self, obj: &str, sample: &str, id: u64, a: &Value) -> Result<(String, usize)> {
        let category = a.get("category_id").and_then(Value::as_u64);
        let class = category
            .and_then(|c| self.categories.get(&c))
            .ok_or_else(|| {
                Error::format(
                    self.file,
                    format!("{obj}: category {category:?} is not among the categories"),
                )
            })?;
        let track = match a.get("track_id").and_then(Value::as_u64) {
            Some(t) => format!("track {t}"),
            None => format!("{sample}/{id}"),
        };
        Ok((class.clone(), self.tracks.of(&track)))
    }

    /// A segmentation label's `point_annotations` (each point's object id, 0 for none): every
    /// id one of the label's annotations.
    fn point_annotations(
        &self,
        what: &str,
        ids: &[Value],
        classes: BTreeMap<u32, (String, usize)>,
    ) -> Result<PointAnnotations> {
        let mut objects = Vec::with_capacity(ids.len());
        for (k, v) in ids.iter().enumerate() {
            let id = v.as_u64().and_then(|v| u32::try_from(v).ok());
            match id {
                Some(id) if id == 0 || classes.contains_key(&id) => objects.push(id),
                _ => {
                    return Err(Error::format(
                        self.file,
                        format!("{what}: point {k} names object {v}, which the label's annotations do not list"),
                    ))
                }
            }
        }
        Ok(PointAnnotations { objects, classes })
    }
}

/// The label attributes of a sample: its `ground-truth` label set's, else its only one's.
fn label_attributes<'a>(file: &Path, what: &str, s: &'a Value) -> Result<Option<&'a Value>> {
    let Some(labels) = s.get("labels").and_then(Value::as_object) else {
        return Ok(None);
    };
    let set = match labels.get("ground-truth") {
        Some(l) => l,
        None if labels.len() == 1 => labels.values().next().expect("one"),
        None if labels.is_empty() => return Ok(None),
        None => {
            let names: Vec<&str> = labels.keys().map(String::as_str).collect();
            return Err(Error::format(
                file,
                format!(
                    "{what}: label sets {} and no \"ground-truth\"",
                    names.join(", ")
                ),
            ));
        }
    };
    Ok(set.get("attributes").filter(|a| !a.is_null()))
}

/// A frame's scan name: its `name`, else its point cloud URL's file stem, else the sample's.
fn scan_name(attributes: &Value, sample: &str) -> String {
    let stem = super::uri_stem;
    (attributes.get("name").and_then(Value::as_str).map(stem))
        .or_else(|| {
            attributes
                .pointer("/pcd/url")
                .and_then(Value::as_str)
                .map(stem)
        })
        .unwrap_or_else(|| stem(sample))
}

/// A `{qx, qy, qz, qw}` object's four numbers.
fn quaternion(v: &Value, file: &Path, what: &str) -> Result<[f64; 4]> {
    Ok([
        number(v, "qx", file, what)?,
        number(v, "qy", file, what)?,
        number(v, "qz", file, what)?,
        number(v, "qw", file, what)?,
    ])
}

/// The frame's ego pose (the sensor in the world), if it has one.
fn ego_pose(file: &Path, what: &str, attributes: &Value) -> Result<Option<na::Isometry3<f64>>> {
    let Some(p) = attributes.get("ego_pose").filter(|p| !p.is_null()) else {
        return Ok(None);
    };
    let what = format!("{what} ego_pose");
    let t = xyz(p.get("position"), "position", file, &what)?;
    let heading = p.get("heading");
    let heading = heading.ok_or_else(|| Error::format(file, format!("{what}: no \"heading\"")))?;
    let q = quaternion(heading, file, &what)?;
    if let Some(v) = t.iter().chain(&q).find(|v| !v.is_finite()) {
        return Err(Error::format(file, format!("{what}: {v} is not finite")));
    }
    let r = unit_quaternion(file, &what, q)?;
    Ok(Some(na::Isometry3::from_parts(
        na::Translation3::new(t[0], t[1], t[2]),
        r,
    )))
}

/// A cuboid annotation's box (quaternion where the file has one, else yaw).
fn cuboid(file: &Path, what: &str, a: &Value) -> Result<crate::source::boxes::Box3> {
    let centre = xyz(a.get("position"), "position", file, what)?;
    let sizes = xyz(a.get("dimensions"), "dimensions", file, what)?;
    if let Some(r) = a.get("rotation").filter(|r| !r.is_null()) {
        return centred_quaternion(file, what, centre, sizes, quaternion(r, file, what)?);
    }
    let yaw = number(a, "yaw", file, what)?;
    super::check_box(file, what, centre, sizes, &[yaw])?;
    Ok(BoxConvention::CENTRED_LWH.place(centre, sizes, &BoxRotation::Yaw(yaw), None))
}
