//! Tracklets and boxes, from the annotations alone: sizes, pose jumps, heading flips,
//! overlapping boxes, and frames whose annotated-object count falls off.

use std::f64::consts::PI;
use std::path::Path;

use super::read::DriveRead;
use super::{frame_ranges, CheckName as C, Collector, ObjectRef, Severity as S};
use crate::geom::{Point3, Real};
use crate::label::LabelBox;
use crate::source::kitti::tracklets::{Tracklet, Tracklets};

/// Runs the annotation-only box checks of a drive.
pub(crate) fn check(r: &DriveRead, c: &mut Collector) {
    if let Some(t) = r.tracklets() {
        for (i, tr) in t.tracklets.iter().enumerate() {
            let obj = || {
                Some(ObjectRef {
                    index: i as u32,
                    kind: tr.object_type.as_str().into(),
                })
            };
            size(
                c,
                &t.path,
                Some(tr.first_frame),
                obj(),
                tr.object_type.as_str(),
                [tr.l, tr.w, tr.h],
            );
            pose_jumps_of(c, r, &t.path, i, tr);
            yaw_flips(c, &t.path, &TrackRun::of_tracklet(i, tr));
        }
        overlaps_raw(c, t);
        falloff(c, t);
    }
    for (&frame, (objects, _)) in r.objects() {
        let path = r.drive.object_labels_path(frame);
        let boxes: Vec<(ObjectRef, LabelBox)> = r
            .boxes_at(frame)
            .into_iter()
            .filter(|b| !b.ghost)
            .map(|b| (b.object, b.label_box))
            .collect();
        for (obj, _) in &boxes {
            let [h, w, l] = objects[obj.index as usize].hwl;
            size(
                c,
                &path,
                Some(frame),
                Some(obj.clone()),
                &obj.kind,
                [l, w, h],
            );
        }
        overlaps_at(c, &path, frame, &boxes);
    }
}

/// A box's size against its type's plausible range.
pub(super) fn size(
    c: &mut Collector,
    path: &Path,
    frame: Option<u32>,
    obj: Option<ObjectRef>,
    kind: &str,
    lwh: [f64; 3],
) {
    let Some(range) = c.t().sizes.get(kind).copied() else {
        return;
    };
    let factor = c.t().size_error_factor.max(1.0);
    let mut worst: Option<(S, String)> = None;
    for (name, v, [lo, hi]) in [
        ("length", lwh[0], range.l),
        ("width", lwh[1], range.w),
        ("height", lwh[2], range.h),
    ] {
        let sev = if v > hi * factor || v < lo / factor {
            S::Error
        } else if v > hi || v < lo {
            S::Warning
        } else {
            continue;
        };
        if worst.as_ref().is_none_or(|(s, _)| sev > *s) {
            worst = Some((
                sev,
                format!("{kind} {name} {v:.2} m outside the plausible {lo}-{hi} m"),
            ));
        }
    }
    if let Some((sev, msg)) = worst {
        c.add(C::BoxSize, sev, path, frame, obj, msg);
    }
}

/// One object's boxes in consecutive frames, as the motion checks see them (a tracklet, or a
/// run of an imported track's frames).
pub(super) struct TrackRun {
    /// The object, as findings name it.
    pub(super) object: ObjectRef,
    /// The frame of the first box.
    pub(super) first_frame: u32,
    /// A fixed point of each box (its centre, or its bottom face's), one a frame.
    pub(super) positions: Vec<[f64; 3]>,
    /// Each box's heading, radians about z.
    pub(super) yaws: Vec<f64>,
    /// Whether the object is a vehicle (one that cannot turn fast).
    pub(super) vehicle: bool,
}

impl TrackRun {
    fn of_tracklet(i: usize, tr: &Tracklet) -> TrackRun {
        TrackRun {
            object: ObjectRef {
                index: i as u32,
                kind: tr.object_type.as_str().into(),
            },
            first_frame: tr.first_frame,
            positions: tr.poses.iter().map(|p| p.t).collect(),
            yaws: tr.poses.iter().map(|p| p.r[2]).collect(),
            vehicle: matches!(tr.object_type.as_str(), "Car" | "Van" | "Truck" | "Tram"),
        }
    }
}

fn pose_jumps_of(c: &mut Collector, r: &DriveRead, path: &Path, i: usize, tr: &Tracklet) {
    let dt = |f: u32| -> f64 {
        let ts = r.timestamps();
        let at = |f: u32| ts.and_then(|v| v.get(f as usize).copied().flatten());
        match (at(f), at(f + 1)) {
            (Some(a), Some(b)) if b.as_secs_f64() > a.as_secs_f64() => {
                b.as_secs_f64() - a.as_secs_f64()
            }
            _ => 0.1,
        }
    };
    pose_jumps(c, path, &TrackRun::of_tracklet(i, tr), &dt);
}

/// Speeds above the plausible and jumps in the displacement along a run of frames; `dt(f)` is
/// the time from frame `f` to the next, seconds.
pub(super) fn pose_jumps(c: &mut Collector, path: &Path, run: &TrackRun, dt: &dyn Fn(u32) -> f64) {
    let t = c.t().clone();
    let pos = &run.positions;
    let step = |k: usize| -> [f64; 3] { std::array::from_fn(|d| pos[k + 1][d] - pos[k][d]) };
    let norm = |v: [f64; 3]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
    let mut worst: Option<(S, u32, String)> = None;
    let mut frames = Vec::new();
    let mut consider = |sev: S, frame: u32, msg: String| {
        frames.push(frame);
        if worst.as_ref().is_none_or(|(s, _, _)| sev > *s) {
            worst = Some((sev, frame, msg));
        }
    };
    for k in 0..pos.len().saturating_sub(1) {
        let speed = norm(step(k)) / dt(run.first_frame + k as u32);
        if speed > t.max_speed_mps {
            consider(S::Error, run.first_frame + k as u32 + 1,
                format!("moves {:.2} m in one frame: {speed:.0} m/s relative to the sensor, above {} m/s", norm(step(k)), t.max_speed_mps));
        }
        if k + 2 < pos.len() {
            let (a, b) = (step(k), step(k + 1));
            let jump = norm(std::array::from_fn(|d| b[d] - a[d]));
            let frame = run.first_frame + k as u32 + 1;
            if jump > t.jump_error_m {
                consider(S::Error, frame, format!("jumps: its displacement changes by {jump:.2} m between frames (error above {} m)", t.jump_error_m));
            } else if jump > t.jump_warn_m {
                consider(S::Warning, frame, format!("jumps: its displacement changes by {jump:.2} m between frames (warning above {} m)", t.jump_warn_m));
            }
        }
    }
    if let Some((sev, frame, msg)) = worst {
        frames.sort_unstable();
        frames.dedup();
        let more = if frames.len() > 1 {
            format!("; frames {}", frame_ranges(&frames))
        } else {
            String::new()
        };
        let obj = Some(run.object.clone());
        c.add(
            C::PoseJump,
            sev,
            path,
            Some(frame),
            obj,
            format!("{msg}{more}"),
        );
    }
}

/// The heading change from `a` to `b`, wrapped to [0, pi].
fn turn(a: f64, b: f64) -> f64 {
    let d = (b - a).rem_euclid(2.0 * PI);
    d.min(2.0 * PI - d)
}

/// Headings that turn faster than the object can, along a run of frames.
pub(super) fn yaw_flips(c: &mut Collector, path: &Path, run: &TrackRun) {
    let (warn, flip) = (c.t().yaw_warn_rad, c.t().yaw_flip_rad);
    let limit = if run.vehicle { warn.min(flip) } else { flip };
    let mut frames = Vec::new();
    let mut worst = 0.0f64;
    for (k, w) in run.yaws.windows(2).enumerate() {
        let d = turn(w[0], w[1]);
        if d > limit {
            frames.push(run.first_frame + k as u32 + 1);
            worst = worst.max(d);
        }
    }
    if let Some(&first) = frames.first() {
        let what = if run.vehicle {
            format!("a vehicle turns by up to {worst:.2} rad in one frame (above {limit} rad)")
        } else {
            format!("its heading flips by up to {worst:.2} rad in one frame (above {limit} rad)")
        };
        c.add(
            C::YawFlip,
            S::Warning,
            path,
            Some(first),
            Some(run.object.clone()),
            format!("{what}; frames {}", frame_ranges(&frames)),
        );
    }
}

/// The share of `small`'s volume inside `big`, from a 6x6x6 grid of cell centres.
fn inside_share(small: &LabelBox, big: &LabelBox) -> f64 {
    const N: usize = 6;
    let h = small.cuboid.half_extents;
    let mut inside = 0;
    for i in 0..N {
        for j in 0..N {
            for k in 0..N {
                let f = |n: usize, e: Real| (2.0 * (n as Real + 0.5) / N as Real - 1.0) * e;
                let p = small.pose * Point3::new(f(i, h.x), f(j, h.y), f(k, h.z));
                inside += big.contains(&p) as usize;
            }
        }
    }
    inside as f64 / (N * N * N) as f64
}

/// Overlap share of two boxes (of the smaller's volume), 0 when they are far apart.
pub(crate) fn overlap(a: &LabelBox, b: &LabelBox) -> f64 {
    let reach = a.cuboid.half_extents.norm() + b.cuboid.half_extents.norm();
    if (a.pose.translation.vector - b.pose.translation.vector).norm() > reach {
        return 0.0;
    }
    if a.volume() <= b.volume() {
        inside_share(a, b)
    } else {
        inside_share(b, a)
    }
}

/// One finding per pair of boxes that overlap in some frame, at its worst frame.
pub(super) fn overlaps_at(
    c: &mut Collector,
    path: &Path,
    frame: u32,
    boxes: &[(ObjectRef, LabelBox)],
) {
    for (i, (oa, a)) in boxes.iter().enumerate() {
        for (ob, b) in &boxes[i + 1..] {
            let share = overlap(a, b);
            if let Some(sev) = overlap_severity(c, share) {
                c.add(
                    C::BoxOverlap,
                    sev,
                    path,
                    Some(frame),
                    Some(oa.clone()),
                    format!(
                        "{:.0}% of the smaller box overlaps object {} ({})",
                        share * 100.0,
                        ob.index,
                        ob.kind
                    ),
                );
            }
        }
    }
}

fn overlap_severity(c: &Collector, share: f64) -> Option<S> {
    if share >= c.t().overlap_share_error {
        Some(S::Error)
    } else if share >= c.t().overlap_share_warn {
        Some(S::Warning)
    } else {
        None
    }
}

fn overlaps_raw(c: &mut Collector, t: &Tracklets) {
    // (a, b) -> (frames, worst share, its frame)
    let mut pairs: std::collections::BTreeMap<(usize, usize), (Vec<u32>, f64, u32)> =
        Default::default();
    for frame in 0..t.end_frame() {
        let boxes: Vec<(usize, LabelBox)> = t
            .at(frame)
            .map(|(i, tr, p)| {
                (
                    i,
                    LabelBox::of(&tr.box_at(p), 0, crate::label::instance_of(i)),
                )
            })
            .collect();
        for (k, (ia, a)) in boxes.iter().enumerate() {
            for (ib, b) in &boxes[k + 1..] {
                let share = overlap(a, b);
                if overlap_severity(c, share).is_some() {
                    let e = pairs.entry((*ia, *ib)).or_insert((Vec::new(), 0.0, frame));
                    e.0.push(frame);
                    if share > e.1 {
                        e.1 = share;
                        e.2 = frame;
                    }
                }
            }
        }
    }
    for ((a, b), (frames, share, worst)) in pairs {
        let sev = overlap_severity(c, share).expect("kept above");
        let kind = |i: usize| t.tracklets[i].object_type.as_str().to_string();
        c.add(
            C::BoxOverlap,
            sev,
            &t.path,
            Some(worst),
            Some(ObjectRef {
                index: a as u32,
                kind: kind(a),
            }),
            format!(
                "up to {:.0}% of the smaller box overlaps tracklet {b} ({}); frames {}",
                share * 100.0,
                kind(b),
                frame_ranges(&frames)
            ),
        );
    }
}

/// Runs of frames whose annotated-object count falls below a share of the drive's median.
fn falloff(c: &mut Collector, t: &Tracklets) {
    let counts: Vec<usize> = (0..t.end_frame()).map(|f| t.count_at(f)).collect();
    let mut sorted: Vec<usize> = counts.iter().copied().filter(|&n| n > 0).collect();
    sorted.sort_unstable();
    let Some(&median) = sorted.get(sorted.len() / 2) else {
        return;
    };
    if median < 4 {
        return;
    }
    let limit = c.t().falloff_share * median as f64;
    let min_len = c.t().falloff_min_frames.max(1.0) as usize;
    let mut f = 0;
    while f < counts.len() {
        if (counts[f] as f64) >= limit {
            f += 1;
            continue;
        }
        let start = f;
        while f < counts.len() && (counts[f] as f64) < limit {
            f += 1;
        }
        if f - start >= min_len {
            let run = &counts[start..f];
            let (lo, hi) = (
                run.iter().min().copied().unwrap_or(0),
                run.iter().max().copied().unwrap_or(0),
            );
            let end_note = if f == counts.len() {
                ", up to the annotation's end"
            } else {
                ""
            };
            let frames = format!("frames {start}-{}{end_note}", f - 1);
            if hi == 0 {
                c.add(C::AnnotationFalloff, S::Note, &t.path, Some(start as u32), None,
                    format!("{frames}: no annotated object, against the drive's median {median}: an empty road, or objects left unlabelled (the scans tell)"));
            } else {
                c.add(C::AnnotationFalloff, S::Warning, &t.path, Some(start as u32), None,
                    format!("{frames}: {lo}-{hi} annotated objects per frame, against the drive's median {median} (below {:.0}%): objects there are likely unlabelled",
                        c.t().falloff_share * 100.0));
            }
        }
    }
}
