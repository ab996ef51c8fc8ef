//! LABEL FROM BOXES: a sequence of any sensor's scans labelled point by point from the 3D boxes
//! an annotation tool exported (`kitti2pgm label`), into `labels/<frame6>.label` (class raw id |
//! instance << 16, SemanticKITTI's layout), with the record of what they were made from
//! ([`crate::format::box_labels`]).
//!
//! - each annotated frame's scan is found by name ([`scans`]), never by position; frames
//!   without a scan and scans without boxes are named in the [`LabelReport`];
//! - each box takes the class its object type has in the class map (an unknown type is an
//!   error listing them, unless the user names the class such boxes become), and the instance
//!   id of its track, stable across the sequence and across runs (the record's instance table);
//! - a label file already there that `label` did not write (another tool's, a hand-edited one)
//!   is refused unless `overwrite`; the labels a dataset ships (SemanticKITTI's, nuScenes') are
//!   never written over;
//! - a re-run rewrites exactly the frames whose labels change, removes the labels of frames no
//!   longer annotated, and keeps the rest byte for byte;
//! - a frame whose scan cannot be read fails alone; the others are written.

mod existing;
pub mod frame;
pub mod scans;

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use rayon::prelude::*;
use serde::Serialize;

use crate::error::{Error, Result};
use crate::format::box_labels::{self as record, BoxLabelParams, BoxLabelRecord};
use crate::format::Durability;
use crate::fs::Fingerprint;
use crate::label::{ClassCounts, ClassId, ClassMap, LabelBox, TypeRule};
use crate::source::annotations::{AnnotatedFrame, Annotations};
use crate::source::kitti::Drive;
use frame::{FrameDone, FrameJob};
use scans::{Match, ScanNames};

/// How to label.
#[derive(Debug, Clone)]
pub struct LabelOptions {
    /// What the labels are made with (recorded).
    pub params: BoxLabelParams,
    /// The box export read, resolved (recorded).
    pub boxes: PathBuf,
    /// The box files read, with their digests (recorded).
    pub box_files: BTreeMap<PathBuf, Fingerprint>,
    /// Write over label files that `label` did not write, or that were edited since.
    pub overwrite: bool,
    /// How far each file is taken before it counts as written.
    pub durability: Durability,
}

/// A frame that could not be labelled.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct LabelFailure {
    /// The scan's name as the annotations give it.
    pub annotation: String,
    /// The annotation file.
    pub box_file: PathBuf,
    /// What was wrong.
    pub error: String,
}

/// What a label run did.
#[derive(Debug, Clone, Default, Serialize)]
pub struct LabelReport {
    /// The sequence folder.
    pub sequence: PathBuf,
    /// The class map's name.
    pub class_map: String,
    /// Annotated frames.
    pub frames_annotated: usize,
    /// Label files written (new or changed).
    pub frames_written: usize,
    /// Label files that already held these labels.
    pub frames_unchanged: usize,
    /// Frames whose scan is not in the sequence (or whose scan could not be read).
    pub failures: Vec<LabelFailure>,
    /// Scans of the sequence without annotations (no label file written), by frame name.
    pub scans_without_boxes: Vec<String>,
    /// Label files of an earlier run whose frames are no longer annotated, removed.
    pub removed: Vec<String>,
    /// Boxes read.
    pub boxes: usize,
    /// Boxes of types the class map does not know, labelled as the unknown class.
    pub unknown_type_boxes: BTreeMap<String, usize>,
    /// Tracks (instance ids).
    pub instances: usize,
    /// Points in the labelled scans.
    pub points: u64,
    /// Points per class, in the map's order.
    pub class_points: Vec<ClassPoints>,
}

/// One class's points in the labelled scans.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct ClassPoints {
    /// The class's name.
    pub class: String,
    /// Its points.
    pub points: u64,
}

/// Labels the sequence folder `seq` from `annotations` ([module docs](self)).
pub fn label_sequence(
    seq: &Path,
    annotations: &Annotations,
    opts: &LabelOptions,
    progress: &(dyn Fn() + Sync),
) -> Result<LabelReport> {
    let drive = Drive::sequence(seq).ok_or_else(|| Error::Input {
        path: seq.into(),
        message: "not a sequence folder (sequences/<NN>/ with velodyne/)".into(),
    })?;
    refuse_unfinished_unpack(seq)?;
    let _lock = crate::convert::resume::lock_dir(seq)?;
    let map = opts.params.class_map.clone();
    let old = if opts.overwrite {
        record::read(seq).ok().flatten()
    } else {
        record::read(seq)?
    };
    let classes = resolve_classes(annotations, &opts.params)?;
    let instances = assign_instances(annotations, &classes, &map, old.as_ref())?;
    let names = ScanNames::of(&drive)?;
    let mut report = LabelReport {
        sequence: seq.into(),
        class_map: map.name.clone(),
        frames_annotated: annotations.frames.len(),
        boxes: annotations.boxes(),
        instances: instances.len(),
        ..Default::default()
    };
    let (jobs, failures) = plan_jobs(&drive, &names, annotations, &classes, &instances, opts)?;
    report.failures = failures;
    let matched: BTreeMap<u32, ()> = jobs.iter().map(|j| (j.frame, ())).collect();
    report.scans_without_boxes = (names.without(&matched).into_iter())
        .map(|f| format!("{f:06}"))
        .collect();
    let old_frames = old.as_ref().map(|r| r.frames.clone()).unwrap_or_default();
    let planned: BTreeSet<String> = jobs.iter().map(|j| format!("{:06}", j.frame)).collect();
    let stale: Vec<String> = (old_frames.keys())
        .filter(|name| !planned.contains(*name))
        .cloned()
        .collect();
    // Label files an interrupted run may have written: its record lists them as pending.
    let pending: BTreeSet<String> = (old.iter())
        .filter(|r| !r.complete)
        .flat_map(|r| r.pending.iter().cloned())
        .collect();
    let theirs = existing::Previous {
        frames: &old_frames,
        pending: &pending,
    };
    let jobs = existing::refuse_foreign(&drive, jobs, &stale, &theirs, opts.overwrite)?;
    let mut rec = BoxLabelRecord {
        version: record::VERSION,
        complete: false,
        params: opts.params.clone(),
        boxes: opts.boxes.clone(),
        box_files: opts.box_files.clone(),
        instances: instances.values().cloned().collect(),
        frames: old_frames,
        pending: planned.into_iter().collect(),
    };
    record::write(seq, &rec, opts.durability)?;
    for name in &stale {
        let label = seq
            .join(crate::source::kitti::sequence::LABELS)
            .join(format!("{name}.label"));
        if crate::fs::remove_if_there(&label)? {
            report.removed.push(name.clone());
        }
        rec.frames.remove(name);
    }
    run_jobs(jobs, &map, opts, progress, &mut rec, &mut report)?;
    report.unknown_type_boxes = classes.unknown_used;
    rec.complete = true;
    rec.pending.clear();
    record::write(seq, &rec, opts.durability)?;
    Ok(report)
}

/// Labels every frame of `jobs` in parallel, into `rec` and `report` in frame order.
fn run_jobs(
    jobs: Vec<FrameJob>,
    map: &ClassMap,
    opts: &LabelOptions,
    progress: &(dyn Fn() + Sync),
    rec: &mut BoxLabelRecord,
    report: &mut LabelReport,
) -> Result<()> {
    let key = opts.params.key();
    let done: Vec<(FrameJob, Result<FrameDone>)> = jobs
        .into_par_iter()
        .map(|job| {
            let r = frame::label_frame(&job, map, &key, opts.durability);
            progress();
            (job, r)
        })
        .collect();
    let mut counts = ClassCounts::count(map.len(), std::iter::empty());
    for (job, r) in done {
        let name = format!("{:06}", job.frame);
        match r {
            Ok(d) => {
                report.frames_written += d.written as usize;
                report.frames_unchanged += !d.written as usize;
                report.points += d.points;
                counts += &d.counts;
                rec.frames.insert(name, d.record);
            }
            Err(e) => {
                // Its earlier labels (made from other boxes or another scan) go with it.
                if rec.frames.remove(&name).is_some() {
                    crate::fs::remove_if_there(&job.label)?;
                }
                report.failures.push(LabelFailure {
                    annotation: job.annotation,
                    box_file: job.box_file,
                    error: e.to_string(),
                });
            }
        }
    }
    report.class_points = (map.names().into_iter().zip(&counts.0))
        .map(|(class, &points)| ClassPoints {
            class: class.into(),
            points,
        })
        .collect();
    Ok(())
}

/// An unpack of the sequence that did not finish is refused (a `label` run that did not is
/// what this run finishes).
fn refuse_unfinished_unpack(seq: &Path) -> Result<()> {
    match crate::source::unpacked::refuse_unfinished(seq) {
        Err(Error::UnfinishedUnpack { marker, .. })
            if marker.ends_with(record::BOX_LABELS_MARKER) =>
        {
            Ok(())
        }
        r => r,
    }
}

/// The class of every object type the annotations use.
#[derive(Debug, Default)]
struct Classes {
    by_type: BTreeMap<String, ClassId>,
    unknown_used: BTreeMap<String, usize>,
}

/// Each object type's class; types the map does not know take the unknown class, or are an
/// error that lists them with the map's types and classes.
fn resolve_classes(a: &Annotations, params: &BoxLabelParams) -> Result<Classes> {
    let map = &params.class_map;
    let rule = TypeRule::new(map, params.unknown_class.as_deref())?;
    let mut out = Classes::default();
    let mut missing: BTreeMap<&str, (usize, &Path)> = BTreeMap::new();
    for f in a.frames.values() {
        for (t, _) in f.objects() {
            match rule.class_of(t) {
                Some((c, unknown)) => {
                    out.by_type.insert(t.into(), c);
                    if unknown {
                        *out.unknown_used.entry(t.into()).or_default() += 1;
                    }
                }
                None => missing.entry(t).or_insert((0, &f.file)).0 += 1,
            }
        }
    }
    if missing.is_empty() {
        return Ok(out);
    }
    let list: Vec<String> = (missing.iter())
        .map(|(t, (n, file))| format!("{t:?} ({n} objects, first in {})", file.display()))
        .collect();
    let types: Vec<&str> = map.object_types.keys().map(String::as_str).collect();
    Err(Error::Config(format!(
        "objects of types the class map {} does not know: {}; it knows {}, its classes are {}: add --alias TYPE=CLASS, or say what such boxes become with --unknown-class CLASS",
        map.name,
        list.join(", "),
        types.join(", "),
        map.names().join(", ")
    )))
}

/// Instance ids by track: a track the previous run's record lists keeps its id, a new one takes
/// the next free id.
fn assign_instances(
    a: &Annotations,
    classes: &Classes,
    map: &ClassMap,
    old: Option<&BoxLabelRecord>,
) -> Result<BTreeMap<usize, record::InstanceEntry>> {
    let mut first_type: BTreeMap<usize, &str> = BTreeMap::new();
    for f in a.frames.values() {
        for (class_name, track) in f.objects() {
            first_type.entry(track).or_insert(class_name);
        }
    }
    let previous: BTreeMap<&str, u16> = (old.iter())
        .flat_map(|r| r.instances.iter())
        .map(|e| (e.track.as_str(), e.instance))
        .collect();
    let mut taken: BTreeSet<u16> = BTreeSet::new();
    let mut out = BTreeMap::new();
    let mut fresh = Vec::new();
    for (&track, &object_type) in &first_type {
        let tool_id = a.tracks.get(track).map_or(String::new(), Clone::clone);
        let entry = record::InstanceEntry {
            instance: 0,
            class: map.name(classes.by_type[object_type]).to_string(),
            object_type: object_type.to_string(),
            track: tool_id,
        };
        match previous.get(entry.track.as_str()) {
            Some(&i) if taken.insert(i) => {
                out.insert(
                    track,
                    record::InstanceEntry {
                        instance: i,
                        ..entry
                    },
                );
            }
            _ => fresh.push((track, entry)),
        }
    }
    let mut next = 1u32;
    for (track, entry) in fresh {
        while taken.contains(&(next as u16)) && next <= u32::from(u16::MAX) {
            next += 1;
        }
        let instance = u16::try_from(next).map_err(|_| {
            Error::Config(format!(
                "more than {} tracks: a .label file's instance id has 16 bits",
                u16::MAX
            ))
        })?;
        taken.insert(instance);
        out.insert(track, record::InstanceEntry { instance, ..entry });
    }
    Ok(out)
}

/// The job of every annotated frame whose scan is in the sequence; the others as failures.
fn plan_jobs(
    drive: &Drive,
    names: &ScanNames,
    a: &Annotations,
    classes: &Classes,
    instances: &BTreeMap<usize, record::InstanceEntry>,
    opts: &LabelOptions,
) -> Result<(Vec<FrameJob>, Vec<LabelFailure>)> {
    let mut jobs: BTreeMap<u32, FrameJob> = BTreeMap::new();
    let mut failures = Vec::new();
    for (name, f) in &a.frames {
        let fail = |error: String| LabelFailure {
            annotation: name.clone(),
            box_file: f.file.clone(),
            error,
        };
        let frame = match names.find(name) {
            Match::Frame(frame) => frame,
            Match::Missing => {
                failures.push(fail(format!(
                    "no scan called {name:?} in {} (by file name, a scan link's target, or frame number)",
                    drive.dir.join(crate::source::kitti::sequence::SCANS).display()
                )));
                continue;
            }
            Match::Ambiguous => {
                failures.push(fail(format!(
                    "two scans of {} are called {name:?}",
                    drive.dir.display()
                )));
                continue;
            }
        };
        if let Some(other) = jobs.get(&frame) {
            failures.push(fail(format!(
                "scan {frame:06} is annotated twice: as {:?} and as {name:?}",
                other.annotation
            )));
            continue;
        }
        let boxes = frame_boxes(f, classes, instances, opts.params.margin_m);
        let points = f.points.as_ref().map(|p| frame::FramePoints {
            objects: p.objects.clone(),
            by_object: (p.classes.iter())
                .map(|(&id, (t, track))| (id, (classes.by_type[t], instances[track].instance)))
                .collect(),
        });
        jobs.insert(
            frame,
            FrameJob {
                frame,
                scan: drive.scan_path(frame),
                label: drive.point_labels_path(frame),
                annotation: name.clone(),
                box_file: f.file.clone(),
                boxes,
                points,
                previous: None,
            },
        );
    }
    Ok((jobs.into_values().collect(), failures))
}

/// A frame's boxes with their classes and instances, grown by `margin_m` on every side.
fn frame_boxes(
    f: &AnnotatedFrame,
    classes: &Classes,
    instances: &BTreeMap<usize, record::InstanceEntry>,
    margin_m: f64,
) -> Vec<LabelBox> {
    (f.boxes.iter())
        .map(|b| {
            let mut g = b.geometry.clone();
            g.half_extents.add_scalar_mut(margin_m as crate::geom::Real);
            LabelBox::of(
                &g,
                classes.by_type[&b.class_name],
                instances[&b.track].instance,
            )
        })
        .collect()
}
