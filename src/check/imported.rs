//! The box checks on imported boxes: a sequence labelled by `kitti2pgm label` has its box export
//! read again, with the options its record holds ([`BoxLabelRecord::imported_boxes`](crate::format::box_labels::BoxLabelRecord::imported_boxes)),
//! and the checks that KITTI's tracklets get run on its boxes: box sizes per type
//! (`box-size`), speeds and jumps along each track (`pose-jump`) and heading flips (`yaw-flip`)
//! over runs of consecutive frames, overlapping boxes (`box-overlap`) here; and, with the scans
//! (`scans.rs`, through [`super::read::DriveRead::boxes_at`]), boxes that hold no point
//! (`empty-box`), boxes off the ground (`box-ground`) and tracks that end while the object is
//! still there (`annotation-ends`). Each finding names the annotation file, the frame and the
//! object (`<type> (<the tool's id>)`, its index the instance id - 1).

use std::collections::BTreeMap;

use super::read::{DriveRead, Imported};
use super::tracklets::{overlaps_at, pose_jumps, size, yaw_flips, TrackRun};
use super::{CheckName as C, Collector, Severity as S};
use crate::label::{ClassMap, LabelBox};
use crate::source::boxes::AnnotatedBox;
use crate::source::kitti::DatasetKind;

/// Reads the boxes a labelled sequence was made from into `r` (a record or export that cannot
/// be read is a `read` error naming it).
pub(crate) fn load(r: &mut DriveRead, c: &mut Collector) {
    if r.drive.dataset != DatasetKind::Sequence {
        return;
    }
    let dir = r.drive.dir.clone();
    let loaded = crate::format::box_labels::read(&dir).and_then(|rec| {
        let Some(rec) = rec else { return Ok(None) };
        let boxes = rec.imported_boxes()?;
        Ok(Some(Imported {
            boxes,
            map: rec.params.class_map,
        }))
    });
    match loaded {
        Ok(i) => r.imported = i,
        Err(e) => c.add(C::Read, S::Error, &dir, None, None, e.to_string()),
    }
}

/// The annotation-only box checks on a labelled sequence's imported boxes.
pub(crate) fn check(r: &DriveRead, c: &mut Collector) {
    let Some(i) = &r.imported else { return };
    let mut tracks: BTreeMap<usize, Vec<(u32, &AnnotatedBox)>> = BTreeMap::new();
    for (&frame, boxes) in &i.boxes.frames {
        let file = i.file(frame);
        let mut labelled = Vec::with_capacity(boxes.len());
        for b in boxes {
            let e = b.geometry.half_extents * 2.0;
            let kind = size_kind(c, &i.map, &b.class_name);
            size(
                c,
                &file,
                Some(frame),
                Some(i.object(b)),
                &kind,
                [e.x, e.y, e.z].map(f64::from),
            );
            tracks.entry(b.track).or_default().push((frame, b));
            labelled.push((
                i.object(b),
                LabelBox::of(&b.geometry, 0, crate::label::instance_of(b.track)),
            ));
        }
        overlaps_at(c, &file, frame, &labelled);
    }
    let times = crate::source::kitti::poses::read_times(&r.drive.dir.join("times.txt")).ok();
    let dt = |f: u32| match (times.as_ref())
        .and_then(|t| Some((t.get(f as usize)?, t.get(f as usize + 1)?)))
    {
        Some((a, b)) if b > a => b - a,
        _ => 0.1,
    };
    for seen in tracks.values() {
        for run in runs(seen, i) {
            let file = i.file(run.first_frame);
            pose_jumps(c, &file, &run, &dt);
            yaw_flips(c, &file, &run);
        }
    }
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
/// heading a frame).
fn runs(seen: &[(u32, &AnnotatedBox)], i: &Imported) -> Vec<TrackRun> {
    let mut out: Vec<TrackRun> = Vec::new();
    for &(frame, b) in seen {
        let centre = b.geometry.pose.translation.vector;
        let x = b.geometry.pose.rotation * crate::geom::Vector3::x();
        let yaw = f64::from(x.y).atan2(f64::from(x.x));
        let p = [centre.x, centre.y, centre.z].map(f64::from);
        match out.last_mut() {
            Some(run) if run.first_frame + run.positions.len() as u32 == frame => {
                run.positions.push(p);
                run.yaws.push(yaw);
            }
            _ => {
                let class = i
                    .map
                    .name(i.map.class_of_object(&b.class_name))
                    .to_ascii_lowercase();
                let vehicle = ["car", "van", "truck", "bus", "tram", "trailer", "vehicle"]
                    .iter()
                    .any(|v| class.contains(v));
                out.push(TrackRun {
                    object: i.object(b),
                    first_frame: frame,
                    positions: vec![p],
                    yaws: vec![yaw],
                    vehicle,
                });
            }
        }
    }
    out
}

/// One error when most imported boxes (90% of 4 or more) hold no point: they are likely in
/// another frame than the scans'. `seen` is (points in the box, ghost) of every box measured.
pub(crate) fn mostly_empty(r: &DriveRead, c: &mut Collector, seen: &[(usize, bool)]) {
    if r.imported.is_none() {
        return;
    }
    let real: Vec<usize> = seen.iter().filter(|(_, g)| !g).map(|(n, _)| *n).collect();
    let empty = real.iter().filter(|&&n| n == 0).count();
    if real.len() >= 4 && empty * 10 >= real.len() * 9 {
        c.add(C::EmptyBox, S::Error, &r.drive.dir, None, None,
            format!("{empty} of {} imported boxes hold no point: the boxes are likely in another frame than the scans' (a vehicle frame: label --sensor-pose), or annotate other scans", real.len()));
    }
}
