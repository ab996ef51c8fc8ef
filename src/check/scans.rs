//! The checks that read the scans: points in boxes (empty boxes, boxes off the ground,
//! annotations that end while the object is still there), the camera's view of the points.
//! Each scan is read once, frames in parallel; findings are made in frame order.

use std::collections::BTreeMap;

use rayon::prelude::*;

use super::calibration::{self, edge_scores, overlap_share};
use super::read::DriveRead;
use super::{
    frame_ranges, semantic, CheckName as C, Collector, ObjectRef, Severity as S, Thresholds,
};
use crate::geom::{Matrix3x4, Point3, Real};
use crate::sensor::params::RowsFrom;
use crate::sensor::SensorParams;

use crate::label::LabelBox;
use crate::source::kitti::DatasetKind;

/// A box of one frame, and what the scan says of it.
#[derive(Debug, Clone)]
struct BoxSeen {
    object: ObjectRef,
    /// Carried one frame past the end of its annotation (at its last velocity).
    ghost: bool,
    /// Fully visible by the annotation (occlusion 0).
    visible: bool,
    /// Horizontal distance from the sensor, metres.
    range: Real,
    /// Within the annotated field of view.
    in_fov: bool,
    points: usize,
    /// Bottom minus the ground around it, metres, and the ground points used.
    ground: Option<(Real, usize)>,
}

#[derive(Debug, Default)]
struct FrameSeen {
    frame: u32,
    error: Option<String>,
    boxes: Vec<BoxSeen>,
    overlap: Option<(usize, usize)>,
    edges: Option<(Vec<f64>, usize)>,
    /// Points off the sensor's beam model, and points (scans without a ring field).
    off_model: Option<(u64, usize)>,
}

/// Runs the scan checks of a drive; returns the number of scans read.
pub(crate) fn check(r: &DriveRead, c: &mut Collector, progress: &(dyn Fn(u64) + Sync)) -> usize {
    let frames: Vec<u32> = r.scans.keys().copied().collect();
    let t = c.t().clone();
    let runs = |k: C| c.opts.runs(k);
    let work = Work {
        boxes: runs(C::EmptyBox) || runs(C::BoxGround) || runs(C::AnnotationEnds),
        overlap: runs(C::CameraOverlap),
    };
    // The sensor's model resolved once (a calibration file changed since is said here).
    let sensor = match (&c.opts.sensor, runs(C::BeamModel)) {
        (Some(p), true) => match p.model() {
            Ok(_) => Some(p.clone()),
            Err(e) => {
                c.add(C::Read, S::Error, &r.drive.dir, None, None, e.to_string());
                None
            }
        },
        _ => None,
    };
    let sampled = if runs(C::CameraAlignment) {
        sample(r, &frames, &t)
    } else {
        Vec::new()
    };
    let seen: Vec<FrameSeen> = frames
        .par_iter()
        .map(|&f| {
            let s = frame(r, f, sampled.contains(&f), work, &t, sensor.as_ref());
            progress(1);
            s
        })
        .collect();
    for s in seen.iter().filter(|s| s.error.is_some()) {
        let path = r.drive.scan_path(s.frame);
        c.add(
            C::Read,
            S::Error,
            &path,
            Some(s.frame),
            None,
            s.error.clone().unwrap_or_default(),
        );
    }
    boxes(r, &seen, c);
    let measured: Vec<(usize, bool)> = (seen.iter().flat_map(|s| &s.boxes))
        .map(|b| (b.points, b.ghost))
        .collect();
    super::imported::mostly_empty(r, c, &measured);
    camera(r, &seen, c);
    if let Some(p) = &sensor {
        beam_model(r, &seen, c, &p.name);
    }
    if r.drive.dataset == DatasetKind::Sequence {
        semantic::moving_static(r, c);
    }
    seen.iter().filter(|s| s.error.is_none()).count()
}

/// Frames with a camera-2 image, evenly spaced, whose images judge the alignment.
fn sample(r: &DriveRead, frames: &[u32], t: &Thresholds) -> Vec<u32> {
    let with_image: Vec<u32> = frames
        .iter()
        .copied()
        .filter(|f| r.images.get(&2).is_some_and(|i| i.binary_search(f).is_ok()))
        .collect();
    let n = (t.alignment_frames.max(0.0) as usize).min(with_image.len());
    (0..n)
        .map(|k| with_image[k * with_image.len() / n])
        .collect()
}

/// Camera 2's projection and image size at a frame, when known.
pub(crate) fn camera_at(r: &DriveRead, f: u32) -> Option<(Matrix3x4, Option<[f64; 2]>)> {
    match r.drive.dataset {
        DatasetKind::Raw => r.calib().map(|c| {
            let s = c.cam_to_cam.cameras[2].size_rect;
            (c.velo_to_image(2), Some([s.x, s.y]))
        }),
        DatasetKind::Sequence => r.frame_calib().map(|c| (c.velo_to_image(2), None)),
        DatasetKind::Object => r.object(f).map(|(_, c)| (c.velo_to_image(2), None)),
    }
}

/// What a frame's pass computes, from the checks that run.
#[derive(Debug, Clone, Copy)]
struct Work {
    /// Points in boxes and the ground around them.
    boxes: bool,
    /// The share of front points in the image.
    overlap: bool,
}

fn frame(
    r: &DriveRead,
    f: u32,
    sampled: bool,
    work: Work,
    t: &Thresholds,
    sensor: Option<&SensorParams>,
) -> FrameSeen {
    let mut out = FrameSeen {
        frame: f,
        ..Default::default()
    };
    let path = r.drive.scan_path(f);
    // The rows as convert decides them: a ring field's ids must be the sensor's beams, points
    // placed by the table may fit none.
    let scan = match crate::sensor::read_scan(sensor, &path) {
        Ok((scan, beams)) => {
            if let Some(b) = beams.filter(|b| b.from == RowsFrom::BeamTable) {
                out.off_model = Some((b.off_model, scan.len()));
            }
            scan
        }
        Err(e) => {
            out.error = Some(e.to_string());
            return out;
        }
    };
    if work.boxes {
        out.boxes = measure(&scan.points, &frame_boxes(r, f, t), t);
    }
    if let Some((proj, size)) = camera_at(r, f) {
        let image_path = r.drive.image_path(2, f);
        let size = size.or_else(|| {
            crate::raster::dimensions(&image_path)
                .ok()
                .map(|(w, h)| [w as f64, h as f64])
        });
        if let (Some(size), true) = (size, work.overlap) {
            out.overlap = overlap_share(&scan.points, &proj, size);
        }
        if sampled {
            match crate::source::kitti::camera::read_image(&image_path) {
                Ok(img) => out.edges = Some(edge_scores(&scan.points, &proj, &img)),
                Err(e) => out.error = Some(e.to_string()),
            }
        }
    }
    out
}

/// The boxes of a frame with their facts, and the ghosts of annotations that ended just before.
fn frame_boxes(r: &DriveRead, f: u32, t: &Thresholds) -> Vec<(LabelBox, BoxSeen)> {
    let seen = |object: ObjectRef, b: &LabelBox, ghost: bool, visible: bool| {
        let c = b.pose.translation.vector;
        let half_fov = (t.ends_fov_deg / 2.0).to_radians() as Real;
        BoxSeen {
            object,
            ghost,
            visible,
            range: c.xy().norm(),
            in_fov: c.x > 0.0 && c.y.atan2(c.x).abs() <= half_fov,
            points: 0,
            ground: None,
        }
    };
    r.boxes_at(f)
        .into_iter()
        .map(|b| {
            let s = seen(b.object, &b.label_box, b.ghost, b.visible);
            (b.label_box, s)
        })
        .collect()
}

/// How far from a box's bottom the ground is looked for, metres.
const GROUND_BAND_M: Real = 3.0;
/// The ground is flat when its 10th and 30th height percentiles are this close, metres.
const GROUND_FLAT_M: Real = 0.3;
/// A box is judged against the ground only when the scan sees it: this many points inside.
const MIN_BOX_POINTS: usize = 10;

/// Points in each box, and the ground around it: the 10th percentile of the heights of the
/// points within `ring` metres of its footprint, when they are flat.
fn measure(points: &[Point3], boxes: &[(LabelBox, BoxSeen)], t: &Thresholds) -> Vec<BoxSeen> {
    let ring = t.ground_ring_m as Real;
    let mut ground: Vec<Vec<Real>> = vec![Vec::new(); boxes.len()];
    let mut out: Vec<BoxSeen> = boxes.iter().map(|(_, s)| s.clone()).collect();
    let reach: Vec<Real> = boxes
        .iter()
        .map(|(b, _)| {
            b.cuboid
                .half_extents
                .xy()
                .norm()
                .max(b.cuboid.half_extents.yz().norm())
                + ring
        })
        .collect();
    for p in points {
        for (k, (b, _)) in boxes.iter().enumerate() {
            let d = (p.coords - b.pose.translation.vector).xy();
            if d.norm_squared() > reach[k] * reach[k] {
                continue;
            }
            if b.contains(p) {
                out[k].points += 1;
                continue;
            }
            let local = b.pose.inverse_transform_point(p);
            let h = b.cuboid.half_extents;
            // The box's vertical axis: the local axis closest to the velodyne's z.
            let up = b.pose.rotation * crate::geom::Vector3::z();
            let (a, bb, ha, hb) = if up.z.abs() > 0.7 {
                (local.x, local.y, h.x, h.y)
            } else {
                (local.x, local.z, h.x, h.z)
            };
            if a.abs() <= ha + ring && bb.abs() <= hb + ring {
                ground[k].push(p.z);
            }
        }
    }
    for (k, (b, _)) in boxes.iter().enumerate() {
        // Multipath returns put points metres under the road: judge the ground from the band
        // within GROUND_BAND_M of the box's bottom.
        let base = bottom(b);
        let g = &mut ground[k];
        g.retain(|z| (z - base).abs() <= GROUND_BAND_M);
        if g.len() < t.ground_min_points as usize || out[k].ghost || out[k].points < MIN_BOX_POINTS
        {
            continue;
        }
        g.sort_unstable_by(|a, b| a.total_cmp(b));
        let (low, higher) = (g[g.len() / 10], g[g.len() * 3 / 10]);
        // Bushes, walls and other cars are no ground: judge only a flat one.
        if higher - low <= GROUND_FLAT_M {
            out[k].ground = Some((base - low, g.len()));
        }
    }
    out
}

/// The lowest corner's height.
fn bottom(b: &LabelBox) -> Real {
    let h = b.cuboid.half_extents;
    (0..8)
        .map(|i| {
            let s = |bit: usize, e: Real| if i >> bit & 1 == 1 { e } else { -e };
            (b.pose * Point3::new(s(0, h.x), s(1, h.y), s(2, h.z))).z
        })
        .fold(Real::INFINITY, Real::min)
}

/// The annotation file of a drive's boxes at frame `f`: the tracklets, the frame's imported
/// annotation file, or its `label_2` file.
fn box_file(r: &DriveRead, f: u32) -> std::path::PathBuf {
    match (r.tracklets(), &r.imported) {
        (Some(tr), _) => tr.path.clone(),
        (None, Some(i)) => i.file(f),
        (None, None) => r.drive.object_labels_path(f),
    }
}

/// Box findings, per object: empty boxes, boxes off the ground, annotations that end early.
fn boxes(r: &DriveRead, seen: &[FrameSeen], c: &mut Collector) {
    let t = c.t().clone();
    let file = |f: u32| box_file(r, f);
    // Imported boxes carry no occlusion: every one is taken as visible.
    let marked = match r.imported {
        Some(_) => "a box",
        None => "marked fully visible",
    };
    let mut empty: BTreeMap<ObjectRef, Vec<u32>> = BTreeMap::new();
    let mut off: BTreeMap<ObjectRef, (Vec<u32>, Real, u32)> = BTreeMap::new();
    let mut counts: BTreeMap<(u32, u32), usize> = BTreeMap::new();
    for s in seen {
        for b in s.boxes.iter().filter(|b| !b.ghost) {
            counts.insert((b.object.index, s.frame), b.points);
            if b.visible && b.points == 0 && (b.range as f64) < t.empty_max_range_m {
                empty.entry(b.object.clone()).or_default().push(s.frame);
            }
            if let Some((d, _)) = b
                .ground
                .filter(|(d, _)| (d.abs() as f64) > t.ground_offset_m)
            {
                let e = off
                    .entry(b.object.clone())
                    .or_insert((Vec::new(), 0.0, s.frame));
                e.0.push(s.frame);
                if d.abs() > e.1.abs() {
                    (e.1, e.2) = (d, s.frame);
                }
            }
        }
    }
    for (o, frames) in empty {
        c.add(
            C::EmptyBox,
            S::Warning,
            &file(frames[0]),
            Some(frames[0]),
            Some(o),
            format!(
                "{marked} within {} m, but no point inside: frames {}",
                t.empty_max_range_m,
                frame_ranges(&frames)
            ),
        );
    }
    for (o, (frames, d, worst)) in off {
        let way = if d > 0.0 { "above" } else { "below" };
        c.add(
            C::BoxGround,
            S::Warning,
            &file(worst),
            Some(worst),
            Some(o),
            format!(
                "its bottom is {:.2} m {way} the ground around it (more than {} m); frames {}",
                d.abs(),
                t.ground_offset_m,
                frame_ranges(&frames)
            ),
        );
    }
    for s in seen {
        for b in s.boxes.iter().filter(|b| b.ghost && b.in_fov) {
            let Some(&before) = counts.get(&(b.object.index, s.frame - 1)) else {
                continue;
            };
            if b.points as f64 >= t.ends_min_points
                && b.points as f64 >= t.ends_min_share * before as f64
            {
                c.add(C::AnnotationEnds, S::Warning, &file(s.frame), Some(s.frame), Some(b.object.clone()),
                    format!("the annotation ends at frame {}, but its box carried one frame on holds {} points in scan {} ({} in its last annotated frame): the object is likely still there, unlabelled",
                        s.frame - 1, b.points, s.frame, before));
            }
        }
    }
}

/// The share of a drive's points that fit no beam of the sensor model, with its worst frame.
fn beam_model(r: &DriveRead, seen: &[FrameSeen], c: &mut Collector, sensor: &str) {
    let t = c.t().clone();
    let (mut off, mut total, mut worst) = (0u64, 0usize, None::<(f64, u32)>);
    for s in seen {
        if let Some((o, n)) = s.off_model.filter(|&(_, n)| n > 0) {
            off += o;
            total += n;
            let share = o as f64 / n as f64;
            if worst.is_none_or(|(w, _)| share > w) {
                worst = Some((share, s.frame));
            }
        }
    }
    let Some((w, f)) = worst else {
        return;
    };
    let share = off as f64 / total as f64;
    let sev = match share {
        s if s > t.beam_model_error => S::Error,
        s if s > t.beam_model_warn => S::Warning,
        _ => return,
    };
    c.add(C::BeamModel, sev, &r.drive.scan_path(f), Some(f), None,
        format!("{:.1}% of the points fit no beam of {} (warning above {:.0}%, error above {:.0}%; worst frame {f}: {:.1}%): the points are not in the sensor's frame (a cloud transformed to base_link?), or the scans are another sensor's",
            share * 100.0, sensor, t.beam_model_warn * 100.0, t.beam_model_error * 100.0, w * 100.0));
}

/// Camera findings: the share of front points in the image, the alignment score.
fn camera(r: &DriveRead, seen: &[FrameSeen], c: &mut Collector) {
    let t = c.t().clone();
    let (mut inside, mut total) = (0usize, 0usize);
    let mut worst: Option<(f64, u32)> = None;
    for s in seen {
        if let Some((i, n)) = s.overlap {
            inside += i;
            total += n;
            let share = i as f64 / n as f64;
            if worst.is_none_or(|(w, _)| share < w) {
                worst = Some((share, s.frame));
            }
        }
    }
    if let Some((w, f)) = worst {
        let share = inside as f64 / total as f64;
        let sev = if share < t.overlap_error {
            Some(S::Error)
        } else if share < t.overlap_warn {
            Some(S::Warning)
        } else {
            None
        };
        if let Some(sev) = sev {
            c.add(C::CameraOverlap, sev, &calibration::camera_file(r, f), Some(f), None,
                format!("only {:.0}% of the points ahead of the car land in camera 2's image (warning below {:.0}%, error below {:.0}%; worst frame {f}: {:.0}%): the calibration does not fit these scans",
                    share * 100.0, t.overlap_warn * 100.0, t.overlap_error * 100.0, w * 100.0));
        }
    }
    let mut scores: Vec<f64> = Vec::new();
    let (mut frames, mut points, mut first) = (0, 0, None);
    for s in seen {
        if let Some((sc, n)) = &s.edges {
            if scores.is_empty() {
                scores = vec![0.0; sc.len()];
            }
            scores.iter_mut().zip(sc).for_each(|(a, b)| *a += b);
            frames += 1;
            points += n;
            first.get_or_insert(s.frame);
        }
    }
    if let Some(f) = first {
        let a = calibration::judge(
            c,
            &calibration::camera_file(r, f),
            &scores,
            frames,
            points,
            f,
        );
        c.alignment = a;
        c.overlap = (total > 0).then(|| inside as f64 / total as f64);
    }
}
