//! The box checks on imported boxes: a sequence labelled by `kitti2pgm label` has its box export
//! read again, with the options its record holds (`format::box_labels`), and the checks that
//! KITTI's tracklets get run on its boxes: box sizes per type (`box-size`), speeds and jumps
//! along each track (`pose-jump`) and heading flips (`yaw-flip`) over runs of consecutive
//! frames, overlapping boxes (`box-overlap`), and, reading the scans, boxes that hold no point
//! (`empty-box`: a box drawn in another frame than the scan's, or off the sensor's view).
//! Each finding names the annotation file, the frame and the object (its track index, type and
//! the tool's own id).

use std::collections::BTreeMap;
use std::path::Path;

use super::read::DriveRead;
use super::tracklets::{overlaps_at, pose_jumps, size, yaw_flips, TrackRun};
use super::{CheckName as C, Collector, ObjectRef, Severity as S};
use crate::format::box_labels::BoxLabelRecord;
use crate::label::{ClassMap, LabelBox};
use crate::source::annotations::{self, Annotations};
use crate::source::boxes::AnnotatedBox;
use crate::source::kitti::DatasetKind;

/// One imported box at its frame.
struct Seen<'a> {
    frame: u32,
    file: &'a Path,
    b: &'a AnnotatedBox,
}

/// Runs the box checks on the boxes a labelled sequence was made from.
pub(crate) fn check(r: &DriveRead, c: &mut Collector) {
    if r.drive.dataset != DatasetKind::Sequence {
        return;
    }
    let rec = match crate::format::box_labels::read(&r.drive.dir) {
        Ok(Some(rec)) => rec,
        Ok(None) => return,
        Err(e) => return c.add(C::Read, S::Error, &r.drive.dir, None, None, e.to_string()),
    };
    let a = match read_again(&rec) {
        Ok(a) => a,
        Err(e) => return c.add(C::Read, S::Error, &rec.boxes, None, None, e.to_string()),
    };
    // Annotated frames by frame number, as the record matched them.
    let frames: BTreeMap<u32, &annotations::AnnotatedFrame> = (rec.frames.iter())
        .filter_map(|(name, f)| Some((name.parse().ok()?, a.frames.get(&f.annotation)?)))
        .collect();
    let map = &rec.params.class_map;
    let object = |b: &AnnotatedBox| ObjectRef {
        index: b.track as u32,
        kind: format!(
            "{} ({})",
            b.class_name,
            a.tracks.get(b.track).map_or("", |s| s.as_str())
        ),
    };
    let mut tracks: BTreeMap<usize, Vec<Seen>> = BTreeMap::new();
    for (&frame, f) in &frames {
        let mut boxes = Vec::with_capacity(f.boxes.len());
        for b in &f.boxes {
            let e = b.geometry.half_extents * 2.0;
            let kind = size_kind(c, map, &b.class_name);
            size(
                c,
                &f.file,
                Some(frame),
                Some(object(b)),
                &kind,
                [e.x, e.y, e.z].map(f64::from),
            );
            tracks.entry(b.track).or_default().push(Seen {
                frame,
                file: &f.file,
                b,
            });
            boxes.push((
                object(b),
                LabelBox::of(&b.geometry, 0, crate::label::instance_of(b.track)),
            ));
        }
        overlaps_at(c, &f.file, frame, &boxes);
    }
    let times = crate::source::kitti::poses::read_times(&r.drive.dir.join("times.txt")).ok();
    let dt = |f: u32| match (times.as_ref())
        .and_then(|t| Some((t.get(f as usize)?, t.get(f as usize + 1)?)))
    {
        Some((a, b)) if b > a => b - a,
        _ => 0.1,
    };
    for seen in tracks.values() {
        for run in runs(seen, map, &object) {
            pose_jumps(c, run.1, &run.0, &dt);
            yaw_flips(c, run.1, &run.0);
        }
    }
    if c.opts.scans && c.opts.runs(C::EmptyBox) {
        empty_boxes(r, c, &frames, &object);
    }
}

/// The export read again as the label run read it.
fn read_again(rec: &BoxLabelRecord) -> crate::Result<Annotations> {
    annotations::read(&rec.boxes, rec.params.format, &rec.params.read_options())
}

/// The type the size table knows a box by: its own, else its class's name as the table spells
/// it (`car` -> `Car`).
fn size_kind(c: &Collector, map: &ClassMap, object_type: &str) -> String {
    let sizes = &c.t().sizes;
    if sizes.contains_key(object_type) {
        return object_type.to_string();
    }
    let class = map.name(map.class_of_object(object_type));
    (sizes.keys())
        .find(|k| k.eq_ignore_ascii_case(class))
        .cloned()
        .unwrap_or_else(|| object_type.to_string())
}

/// A track's runs of consecutive frames, as the motion checks see them (the box centre and
/// heading a frame), each with the file of its first box.
fn runs<'a>(
    seen: &'a [Seen<'a>],
    map: &ClassMap,
    object: &dyn Fn(&AnnotatedBox) -> ObjectRef,
) -> Vec<(TrackRun, &'a Path)> {
    let mut out: Vec<(TrackRun, &Path)> = Vec::new();
    for s in seen {
        let centre = s.b.geometry.pose.translation.vector;
        let x = s.b.geometry.pose.rotation * crate::geom::Vector3::x();
        let yaw = f64::from(x.y).atan2(f64::from(x.x));
        let p = [centre.x, centre.y, centre.z].map(f64::from);
        match out.last_mut() {
            Some((run, _)) if run.first_frame + run.positions.len() as u32 == s.frame => {
                run.positions.push(p);
                run.yaws.push(yaw);
            }
            _ => {
                let class = map
                    .name(map.class_of_object(&s.b.class_name))
                    .to_ascii_lowercase();
                let vehicle = ["car", "van", "truck", "bus", "tram", "trailer", "vehicle"]
                    .iter()
                    .any(|v| class.contains(v));
                let run = TrackRun {
                    object: object(s.b),
                    first_frame: s.frame,
                    positions: vec![p],
                    yaws: vec![yaw],
                    vehicle,
                };
                out.push((run, s.file));
            }
        }
    }
    out
}

/// Boxes that hold no point of their scan; when most boxes of the sequence hold none, one error
/// says the boxes are likely in another frame than the scans'.
fn empty_boxes(
    r: &DriveRead,
    c: &mut Collector,
    frames: &BTreeMap<u32, &annotations::AnnotatedFrame>,
    object: &dyn Fn(&AnnotatedBox) -> ObjectRef,
) {
    let (mut total, mut empty) = (0usize, 0usize);
    for (&frame, f) in frames {
        let scan = match crate::source::read_file(&r.drive.scan_path(frame), None) {
            Ok(s) => s,
            Err(e) => {
                c.add(
                    C::Read,
                    S::Error,
                    &r.drive.scan_path(frame),
                    Some(frame),
                    None,
                    e.to_string(),
                );
                continue;
            }
        };
        for b in &f.boxes {
            total += 1;
            let lb = LabelBox::of(&b.geometry, 1, 1);
            if scan.points.iter().any(|p| lb.contains(p)) {
                continue;
            }
            empty += 1;
            c.add(
                C::EmptyBox,
                S::Warning,
                &f.file,
                Some(frame),
                Some(object(b)),
                format!(
                    "holds no point of scan {frame:06} (centre {:.1} m from the sensor)",
                    b.geometry.centre().coords.norm()
                ),
            );
        }
    }
    if total >= 4 && empty * 10 >= total * 9 {
        c.add(C::EmptyBox, S::Error, &r.drive.dir, None, None,
            format!("{empty} of {total} imported boxes hold no point: the boxes are likely in another frame than the scans' (a vehicle frame: label --sensor-pose), or annotate other scans"));
    }
}
