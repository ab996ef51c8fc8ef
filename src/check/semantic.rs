//! Per-point labels (SemanticKITTI): ids the class map's yaml does not know, one instance id
//! with several classes in a sequence, and moving classes on points that do not move.

use std::collections::{BTreeMap, HashMap};

use rayon::prelude::*;

use super::read::DriveRead;
use super::{CheckName as C, Collector, ObjectRef, Severity as S};
use crate::format::label_file;
use crate::geom::{na, Point3};
use crate::label::ClassMap;
use crate::source::Scan;

/// SemanticKITTI's moving classes: raw ids 252-259 (`moving-car` ... `moving-other-vehicle`).
pub const MOVING_IDS: std::ops::RangeInclusive<u32> = 252..=259;

/// What one label file says.
#[derive(Default)]
struct FileLabels {
    unknown: BTreeMap<u32, usize>,
    /// Points per class name.
    classes: BTreeMap<String, u64>,
    /// instance -> raw id -> points.
    instances: BTreeMap<u32, BTreeMap<u32, usize>>,
    error: Option<String>,
}

fn read_labels(path: &std::path::Path, map: &ClassMap) -> FileLabels {
    let mut out = FileLabels::default();
    match label_file::read_raw(path) {
        Ok(raw) => {
            for v in raw {
                let (id, inst) = (v & 0xffff, v >> 16);
                match map.class_of_raw(id) {
                    Some(c) => *out.classes.entry(map.name(c).to_string()).or_default() += 1,
                    None => *out.unknown.entry(id).or_default() += 1,
                }
                if inst != 0 {
                    *out.instances
                        .entry(inst)
                        .or_default()
                        .entry(id)
                        .or_default() += 1;
                }
            }
        }
        Err(e) => out.error = Some(e.to_string()),
    }
    out
}

/// One finding per instance id that carries several raw ids in the sequence.
fn instance_classes(
    c: &mut Collector,
    labels: &std::path::Path,
    instances: &BTreeMap<u32, BTreeMap<u32, (usize, u32)>>,
) {
    for (inst, ids) in instances.iter().filter(|(_, ids)| ids.len() > 1) {
        let (&first_id, &(_, frame)) = ids.iter().next().expect("two or more");
        let parts: Vec<String> = ids
            .iter()
            .map(|(id, (k, f))| format!("{id} ({k} points from frame {f})"))
            .collect();
        let moving = |i: &u32| MOVING_IDS.contains(i);
        let why = if ids.keys().any(moving) && !ids.keys().all(moving) {
            ": moving in some scans, static in others"
        } else {
            ""
        };
        let object = ObjectRef {
            index: *inst,
            kind: first_id.to_string(),
        };
        c.add(
            C::InstanceClasses,
            S::Warning,
            labels,
            Some(frame),
            Some(object),
            format!(
                "instance {inst} carries {} raw ids in this sequence{why}: {}",
                ids.len(),
                parts.join(", ")
            ),
        );
    }
}

/// Label ids and instance classes of a sequence's label files; returns the labelled points
/// per class of each frame (for the balance check), ignored classes left out.
pub(crate) fn check_labels(r: &DriveRead, c: &mut Collector) -> Vec<(u32, BTreeMap<String, u64>)> {
    if r.label_frames().is_empty() {
        return Vec::new();
    }
    let drive = &r.drive;
    // The map asked for, else the one `kitti2pgm label` wrote these labels with, else
    // SemanticKITTI's.
    let recorded = || {
        crate::format::box_labels::recorded_map_of(&drive.dir)
            .ok()
            .flatten()
    };
    let map = (c.opts.class_map.clone())
        .or_else(recorded)
        .unwrap_or_else(ClassMap::semantic_kitti);
    let files: Vec<(u32, FileLabels)> = r
        .label_frames()
        .par_iter()
        .map(|&f| (f, read_labels(&drive.point_labels_path(f), &map)))
        .collect();
    let ignored: Vec<&str> = map.ignore.iter().map(|&i| map.name(i)).collect();
    // instance -> raw id -> (points, first frame)
    let mut instances: BTreeMap<u32, BTreeMap<u32, (usize, u32)>> = BTreeMap::new();
    for (f, l) in &files {
        let path = drive.point_labels_path(*f);
        if let Some(e) = &l.error {
            c.add(C::Read, S::Error, &path, Some(*f), None, e.clone());
        }
        if !l.unknown.is_empty() {
            let n: usize = l.unknown.values().sum();
            let ids: Vec<String> = l
                .unknown
                .iter()
                .map(|(id, k)| format!("{id} ({k} points)"))
                .collect();
            c.add(
                C::LabelIds,
                S::Error,
                &path,
                Some(*f),
                None,
                format!(
                    "{n} points carry ids the class map ({}) does not list: {}",
                    map.name,
                    ids.join(", ")
                ),
            );
        }
        for (inst, ids) in &l.instances {
            for (id, k) in ids {
                let e = instances
                    .entry(*inst)
                    .or_default()
                    .entry(*id)
                    .or_insert((0, *f));
                e.0 += k;
            }
        }
    }
    instance_classes(c, &drive.dir.join("labels"), &instances);
    files
        .into_iter()
        .map(|(f, mut l)| {
            l.classes.retain(|k, _| !ignored.contains(&k.as_str()));
            (f, l.classes)
        })
        .collect()
}

/// Cell of a 3D hash grid.
fn cell(p: &Point3, size: f32) -> (i32, i32, i32) {
    (
        (p.x / size).floor() as i32,
        (p.y / size).floor() as i32,
        (p.z / size).floor() as i32,
    )
}

/// A moving-class instance of scan `frame` that lies on the previous scan's points.
struct Still {
    frame: u32,
    instance: u32,
    raw_id: u32,
    share: f64,
}

/// An instance needs this many points to be judged.
const MIN_MOVING_POINTS: usize = 20;

/// The velodyne pose of each scan: `Tr⁻¹ · P · Tr` (poses.txt gives camera-0 poses).
fn velo_poses(
    poses: &[crate::geom::Matrix3x4],
    velo_to_cam: &crate::geom::Matrix3x4,
) -> Option<Vec<na::Matrix4<f64>>> {
    let homogeneous = |m: &crate::geom::Matrix3x4| {
        let mut h = na::Matrix4::identity();
        h.fixed_view_mut::<3, 4>(0, 0).copy_from(m);
        h
    };
    let tr = homogeneous(velo_to_cam);
    let tr_inv = tr.try_inverse()?;
    Some(poses.iter().map(|p| tr_inv * homogeneous(p) * tr).collect())
}

/// Moving-class instances whose points lie on the previous scan's points (poses applied).
pub(crate) fn moving_static(r: &DriveRead, c: &mut Collector) {
    let drive = &r.drive;
    let (Some(poses), Some(calib)) = (r.poses(), r.frame_calib()) else {
        if !r.label_frames().is_empty() {
            c.add(C::MovingStatic, S::Note, &drive.dir.join("poses.txt"), None, None,
                "not judged: the sequence has no poses.txt (or calib.txt) to carry one scan onto the next".into());
        }
        return;
    };
    let Some(velo) = velo_poses(poses, &calib.velo_to_cam) else {
        return;
    };
    let (still, share) = (c.t().moving_still_m as f32, c.t().moving_still_share);
    let labelled = |f: u32| r.label_frames().binary_search(&f).is_ok() && r.scans.contains_key(&f);
    let pairs: Vec<u32> = r
        .label_frames()
        .iter()
        .copied()
        .filter(|&f| f > 0 && labelled(f) && labelled(f - 1))
        .collect();
    let found: Vec<Vec<Still>> = pairs
        .par_iter()
        .map(|&f| {
            let (Some(a), Some(b)) = (velo.get(f as usize - 1), velo.get(f as usize)) else {
                return Vec::new();
            };
            let Some(a_inv) = a.try_inverse() else {
                return Vec::new();
            };
            still_instances(r, f, &(a_inv * b).cast::<f32>(), still, share)
        })
        .collect();
    for s in found.into_iter().flatten() {
        c.add(C::MovingStatic, S::Warning, &drive.point_labels_path(s.frame), Some(s.frame),
            Some(ObjectRef { index: s.instance, kind: s.raw_id.to_string() }),
            format!("labelled moving (raw id {}), but {:.0}% of its points lie within {still} m of the previous scan's points, poses applied: it did not move", s.raw_id, s.share * 100.0));
    }
}

/// The moving instances of scan `f` whose points, carried by `to_prev` into scan f-1's frame,
/// lie within `still` metres of its points for at least `share` of them. Unreadable files
/// judge nothing (the read check names them).
fn still_instances(
    r: &DriveRead,
    f: u32,
    to_prev: &na::Matrix4<f32>,
    still: f32,
    share: f64,
) -> Vec<Still> {
    let drive = &r.drive;
    let (Ok(prev), Ok(cur), Ok(labels)) = (
        Scan::read(&drive.scan_path(f - 1)),
        Scan::read(&drive.scan_path(f)),
        label_file::read_raw(&drive.point_labels_path(f)),
    ) else {
        return Vec::new();
    };
    if cur.file_len != labels.len() {
        return Vec::new();
    }
    let mut grid: HashMap<(i32, i32, i32), Vec<Point3>> = HashMap::new();
    for p in &prev.points {
        grid.entry(cell(p, still)).or_default().push(*p);
    }
    let near = |q: &Point3| {
        let (x, y, z) = cell(q, still);
        (-1..=1).any(|dx| {
            (-1..=1).any(|dy| {
                (-1..=1).any(|dz| {
                    grid.get(&(x + dx, y + dy, z + dz))
                        .is_some_and(|v| v.iter().any(|o| (o - q).norm() <= still))
                })
            })
        })
    };
    // (instance, raw id) -> (points, points near the previous scan's)
    let mut per: BTreeMap<(u32, u32), (usize, usize)> = BTreeMap::new();
    for (p, &i) in cur.points.iter().zip(&cur.file_indices()) {
        let v = labels[i as usize];
        let (id, inst) = (v & 0xffff, v >> 16);
        if MOVING_IDS.contains(&id) {
            let q = Point3::from((to_prev * p.to_homogeneous()).xyz());
            let e = per.entry((inst, id)).or_default();
            e.0 += 1;
            e.1 += near(&q) as usize;
        }
    }
    per.into_iter()
        .filter(|(_, (n, k))| *n >= MIN_MOVING_POINTS && *k as f64 >= share * *n as f64)
        .map(|((instance, raw_id), (n, k))| Still {
            frame: f,
            instance,
            raw_id,
            share: k as f64 / n as f64,
        })
        .collect()
}
