//! `kitti2pgm label`: a sequence's scans labelled point by point from an annotation tool's 3D
//! boxes ([`kitti2pgm::convert::box_labels`]).

use std::path::{Path, PathBuf};

use kitti2pgm::convert::box_labels::{label_sequence, LabelOptions, LabelReport};
use kitti2pgm::format::box_labels::BoxLabelParams;
use kitti2pgm::label::ClassMap;
use kitti2pgm::source::annotations::{self, BoxFormat};
use kitti2pgm::source::kitti::sequence;
use kitti2pgm::Error;

use super::{progress, Global};
use crate::cli::LabelArgs;
use crate::Outcome;

pub fn run(a: LabelArgs, g: &Global) -> anyhow::Result<Outcome> {
    let seq = sequence_folder(&a.root, a.sequence)?;
    // The label files go into sequences/<NN>/labels/: never over an input.
    let labels = seq.join(sequence::LABELS);
    kitti2pgm::fs::refuse_overlap(&labels, &[(kitti2pgm::fs::Role::Dataset, &a.boxes)])?;
    if let Some(file) = a.class_map.as_deref().filter(|p| p.is_file()) {
        kitti2pgm::fs::refuse_overlap(&labels, &[(kitti2pgm::fs::Role::ClassMap, file)])?;
    }
    let format =
        match a.box_format {
            Some(f) => f,
            None => {
                annotations::detect(&a.boxes).ok_or_else(|| Error::Input {
                    path: a.boxes.clone(),
                    message: format!(
                "not an export kitti2pgm recognises: name its format with --box-format ({})",
                BoxFormat::ALL.iter().map(|f| f.as_str()).collect::<Vec<_>>().join(", ")
            ),
                })?
            }
        };
    let sensor_pose = (a.sensor_pose.as_deref())
        .map(kitti2pgm::sensor::SensorPose::parse)
        .transpose()?;
    let read_options =
        kitti2pgm::format::box_labels::read_options(a.origin, a.sizes, a.angles, sensor_pose);
    let (read, inputs) =
        kitti2pgm::fs::inputs::recording(|| annotations::read(&a.boxes, format, &read_options));
    let annotations = read?;
    let params = params(&a, format, sensor_pose)?;
    let box_files = (inputs.records().iter())
        .filter_map(|r| Some((r.path.clone(), r.file?)))
        .collect();
    let opts = LabelOptions {
        params,
        boxes: kitti2pgm::fs::resolved(&a.boxes),
        box_files,
        overwrite: a.overwrite,
        durability: super::durability(a.sync),
    };
    let pb = progress::bar(annotations.frames.len() as u64, g.progress, "labelling");
    let report = g
        .pool()?
        .install(|| label_sequence(&seq, &annotations, &opts, &|| pb.inc(1)))?;
    pb.finish_and_clear();
    if a.json {
        let mut v = serde_json::to_value(&report)?;
        v["format"] = serde_json::json!(format.as_str());
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        print_report(&report, format, a.box_format.is_none());
    }
    Ok(outcome(&report))
}

/// The sequence folder to label: ROOT itself when it holds scans, else ROOT/sequences/<NN>
/// (`--sequence`, or the only one).
fn sequence_folder(root: &Path, number: Option<u32>) -> anyhow::Result<PathBuf> {
    if root.join(sequence::SCANS).is_dir() {
        return Ok(root.into());
    }
    if let Some(n) = number {
        let dir = sequence::sequence_dir(root, n);
        if !dir.join(sequence::SCANS).is_dir() {
            return Err(Error::Input {
                path: dir,
                message: "no such sequence (no velodyne/ folder of scans)".into(),
            }
            .into());
        }
        return Ok(dir);
    }
    let all: Vec<PathBuf> = kitti2pgm::fs::sorted_dir(&root.join(sequence::SEQUENCES))
        .unwrap_or_default()
        .into_iter()
        .filter(|d| d.join(sequence::SCANS).is_dir())
        .collect();
    match all.as_slice() {
        [one] => Ok(one.clone()),
        [] => Err(Error::Input {
            path: root.into(),
            message: "no sequence of scans (expected sequences/<NN>/velodyne/)".into(),
        }
        .into()),
        many => Err(Error::Input {
            path: root.into(),
            message: format!(
                "holds {} sequences: name the one the boxes annotate with --sequence ({})",
                many.len(),
                many.iter()
                    .filter_map(|d| d.file_name().map(|n| n.to_string_lossy().into_owned()))
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        }
        .into()),
    }
}

/// The run's parameters from the options.
fn params(
    a: &LabelArgs,
    format: BoxFormat,
    sensor_pose: Option<kitti2pgm::sensor::SensorPose>,
) -> anyhow::Result<BoxLabelParams> {
    let mut map = match (&a.class_map, format) {
        (Some(m), _) => ClassMap::named_or_file(m)?,
        (None, BoxFormat::SusTechPoints) => ClassMap::sustechpoints(),
        (None, BoxFormat::CvatKittiRaw) => ClassMap::kitti_boxes(),
        (None, other) => {
            return Err(Error::Config(format!(
                "{other} exports name their own classes: say which is which with --class-map \
                 (a built-in map: {}; or a YAML file, docs/label.md)",
                ClassMap::BUILTIN.join(", ")
            ))
            .into())
        }
    };
    for alias in &a.aliases {
        let (t, class) = alias
            .split_once('=')
            .ok_or_else(|| Error::Config(format!("--alias {alias}: expected TYPE=CLASS")))?;
        let id = map.id_of(class).ok_or_else(|| {
            Error::Config(format!(
                "--alias {alias}: {class:?} is not a class of {} ({})",
                map.name,
                map.names().join(", ")
            ))
        })?;
        map.object_types.insert(t.to_string(), id);
    }
    if !(0.0..=1.0).contains(&a.margin) {
        return Err(Error::Config(format!("--margin {}: expected 0 to 1 metre", a.margin)).into());
    }
    Ok(BoxLabelParams {
        format,
        origin: a.origin,
        sizes: a.sizes,
        angles: a.angles,
        sensor_pose,
        margin_m: a.margin,
        unknown_class: a.unknown_class.clone(),
        class_map: map.for_point_labels(),
    })
}

fn print_report(r: &LabelReport, format: BoxFormat, detected: bool) {
    let how = if detected { " (recognised)" } else { "" };
    println!(
        "{} <- {format}{how} boxes, class map {}",
        r.sequence.display(),
        r.class_map
    );
    println!("frames annotated   {:>10}", r.frames_annotated);
    println!("labels written     {:>10}", r.frames_written);
    println!("labels unchanged   {:>10}", r.frames_unchanged);
    println!("boxes              {:>10}", r.boxes);
    println!("instances          {:>10}", r.instances);
    println!("points             {:>10}", r.points);
    let total = r.points.max(1) as f64;
    for c in &r.class_points {
        let share = 100.0 * c.points as f64 / total;
        println!("  {:<16} {:>10}  {share:>6.2}%", c.class, c.points);
    }
    for (t, n) in &r.unknown_type_boxes {
        println!("unknown type {t:?}: {n} boxes labelled as --unknown-class");
    }
    if !r.removed.is_empty() {
        println!("removed (no longer annotated): {}", r.removed.join(" "));
    }
    if !r.scans_without_boxes.is_empty() {
        println!(
            "scans without boxes ({}, no label file): {}",
            r.scans_without_boxes.len(),
            shortened(&r.scans_without_boxes)
        );
    }
    for f in &r.failures {
        eprintln!(
            "kitti2pgm: {} ({}): {}",
            f.annotation,
            f.box_file.display(),
            f.error
        );
    }
}

/// At most 12 names, then how many more.
fn shortened(names: &[String]) -> String {
    let mut s = names.iter().take(12).cloned().collect::<Vec<_>>().join(" ");
    if names.len() > 12 {
        s += &format!(" ... ({} more)", names.len() - 12);
    }
    s
}

fn outcome(r: &LabelReport) -> Outcome {
    match (r.failures.len(), r.frames_written + r.frames_unchanged) {
        (0, _) => Outcome::Ok,
        (n, 0) => Outcome::Failed(format!(
            "none of the {n} annotated frame(s) could be labelled"
        )),
        _ => Outcome::Partial,
    }
}
