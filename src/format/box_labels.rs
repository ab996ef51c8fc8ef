//! The record `kitti2pgm label` leaves in a sequence folder it labels from boxes,
//! `sequences/<NN>/box_labels.json`, both directions: where the boxes came from (format, files
//! and their digests, reading options), the class map (typed, in full), the instance table
//! (instance id -> the tool's track id and class), and every label file written with the key of
//! what it was made from and its own digest.
//!
//! It is written with `complete: false` before the first label file and again with `complete:
//! true` after the last, so that a run killed partway says so and the readers refuse the
//! sequence (`source::unpacked::refuse_unfinished`, [`BOX_LABELS_MARKER`]). `convert`, `check`
//! and Python's `Dataset` take the class map recorded here unless told another
//! ([`recorded_class_map`]).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::fs::Fingerprint;
use crate::label::ClassMap;
use crate::sensor::SensorPose;
use crate::source::annotations::{AngleUnit, BoxFormat, CvatSizes};
use crate::source::boxes::BoxOrigin;
pub use crate::source::unpacked::BOX_LABELS_MARKER;

/// Version of the record's layout.
pub const VERSION: u32 = 1;

/// What a label run was made with: every parameter that changes a label file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BoxLabelParams {
    /// The box format.
    pub format: BoxFormat,
    /// Where a box's position sits, as given (`None`: the format's default).
    pub origin: Option<BoxOrigin>,
    /// The order of CVAT's sizes, as given (`None`: the format's default).
    pub sizes: Option<CvatSizes>,
    /// The unit of the angles, as given (`None`: the format's default).
    pub angles: Option<AngleUnit>,
    /// The sensor's pose in the frame the boxes are drawn in (`None`: the boxes are in the
    /// scan's frame).
    pub sensor_pose: Option<SensorPose>,
    /// Metres added to every side of every box.
    pub margin_m: f64,
    /// The class that boxes of a type the map does not know become (`None`: such boxes are an
    /// error).
    pub unknown_class: Option<String>,
    /// The class map, aliases included, with its per-point ids (`learning_map`).
    pub class_map: ClassMap,
}

/// How to read a box export whose boxes sit at `origin`, list their sizes in `sizes` and their
/// angles in `angles` (each `None`: the format's default), drawn in a frame where the sensor
/// has `sensor_pose` (`None`: the scan's own frame): the boxes are carried into the scan's frame
/// by the pose's inverse.
pub fn read_options(
    origin: Option<BoxOrigin>,
    sizes: Option<CvatSizes>,
    angles: Option<AngleUnit>,
    sensor_pose: Option<SensorPose>,
) -> crate::source::annotations::ReadOptions {
    crate::source::annotations::ReadOptions {
        origin,
        sizes,
        angles,
        to_scan: sensor_pose.map(|s| s.isometry().inverse()),
    }
}

impl BoxLabelParams {
    /// The reading options of the box export these parameters hold ([`read_options`]).
    pub fn read_options(&self) -> crate::source::annotations::ReadOptions {
        read_options(self.origin, self.sizes, self.angles, self.sensor_pose)
    }

    /// The parameters as one canonical string (part of every frame's key).
    pub fn key(&self) -> String {
        serde_json::to_string(self).expect("parameters serialise")
    }
}

/// One instance id of the sequence.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct InstanceEntry {
    /// The id in the high 16 bits of a `.label` entry.
    pub instance: u16,
    /// The annotation tool's id of the object (its track).
    pub track: String,
    /// The object type its first box was annotated as.
    pub object_type: String,
    /// The class that type became.
    pub class: String,
}

/// One label file written.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct LabelledFrame {
    /// The scan's name as the annotations give it.
    pub annotation: String,
    /// The annotation file its boxes came from, as given.
    pub box_file: PathBuf,
    /// Boxes of the frame (all, including those that label nothing).
    pub boxes: usize,
    /// XXH3-64 of what the file was made from (parameters, the scan's bytes, the boxes as
    /// labelled), 16 hex digits.
    pub key: String,
    /// The label file as written: a file that differs was edited since.
    pub label: Fingerprint,
}

/// `box_labels.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BoxLabelRecord {
    /// [`VERSION`].
    pub version: u32,
    /// Whether the run finished (`false` while it writes).
    pub complete: bool,
    /// What the labels were made with.
    pub params: BoxLabelParams,
    /// The box export read (`label --boxes`), resolved: `check` reads its boxes again.
    pub boxes: PathBuf,
    /// The box files read, as given, with their digests.
    pub box_files: BTreeMap<PathBuf, Fingerprint>,
    /// The instance table, by instance id.
    pub instances: Vec<InstanceEntry>,
    /// The label files written, by frame name (`000042`).
    pub frames: BTreeMap<String, LabelledFrame>,
    /// While the run writes (`complete: false`): the frames whose label files it may write, so
    /// that the run after an interruption knows them for its own.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub pending: Vec<String>,
}

/// The record's path in sequence folder `seq`.
pub fn path(seq: &Path) -> PathBuf {
    seq.join(BOX_LABELS_MARKER)
}

/// The record of sequence folder `seq`, if it has one.
pub fn read(seq: &Path) -> Result<Option<BoxLabelRecord>> {
    super::read_versioned(
        &path(seq),
        "a kitti2pgm box label record",
        VERSION,
        |r: &BoxLabelRecord| r.version,
    )
}

/// Writes `record` into sequence folder `seq`, atomically.
pub fn write(seq: &Path, record: &BoxLabelRecord, d: super::Durability) -> Result<()> {
    super::write_json(&path(seq), record, d)
}

/// The class map the box labels of `seqs` were written with: `None` when none of them was
/// labelled by `kitti2pgm label`; an error when two were labelled with different maps, or when
/// some were and others hold label files of their own (one map cannot read both).
pub fn recorded_class_map<'a>(
    seqs: impl IntoIterator<Item = &'a Path>,
) -> Result<Option<ClassMap>> {
    let mut found: Option<(PathBuf, ClassMap)> = None;
    let mut unrecorded: Option<PathBuf> = None;
    for seq in seqs {
        match recorded_map_of(seq)? {
            Some(recorded) => {
                if let Some((first, map)) = &found {
                    if *map != recorded {
                        return Err(Error::Config(format!(
                            "{} and {} were labelled with different class maps ({} and {}): convert them apart, or name one with --class-map",
                            first.display(),
                            seq.display(),
                            map.name,
                            recorded.name
                        )));
                    }
                } else {
                    found = Some((seq.to_path_buf(), recorded));
                }
            }
            None if has_label_files(seq) => unrecorded = Some(seq.to_path_buf()),
            None => {}
        }
    }
    match (found, unrecorded) {
        (Some((labelled, map)), Some(other)) => Err(Error::Config(format!(
            "{} was labelled from boxes with class map {}, {} holds labels of its own: convert them apart, or name the map with --class-map",
            labelled.display(),
            map.name,
            other.display()
        ))),
        (found, _) => Ok(found.map(|(_, m)| m)),
    }
}

/// The class map of the labels of sequence folder `seq` as recorded beside them: by `kitti2pgm
/// label` (`box_labels.json`), else by `kitti2pgm infer --as-labels` (`model_labels.json`).
pub fn recorded_map_of(seq: &Path) -> Result<Option<ClassMap>> {
    if let Some(r) = read(seq)? {
        return Ok(Some(r.params.class_map));
    }
    Ok(super::model_labels::read(seq)?.map(|r| r.class_map))
}

/// Whether sequence folder `seq` holds `.label` files.
pub fn has_label_files(seq: &Path) -> bool {
    std::fs::read_dir(seq.join(crate::source::kitti::sequence::LABELS)).is_ok_and(|d| {
        d.flatten()
            .any(|e| e.path().extension().is_some_and(|x| x == "label"))
    })
}

/// The class map a conversion of `plan` takes when none is named: the one its sequences were
/// labelled from boxes with ([`recorded_class_map`]), else the layout's default
/// ([`ClassMap::default_for`]).
pub fn default_class_map(plan: &crate::plan::Plan) -> Result<ClassMap> {
    let seqs = (plan.drives.iter())
        .filter(|d| d.drive.dataset == crate::source::DatasetKind::Sequence)
        .map(|d| d.drive.dir.as_path());
    Ok(recorded_class_map(seqs)?.unwrap_or_else(|| ClassMap::default_for(plan.layout())))
}

impl BoxLabelRecord {
    /// The boxes the labels were made from, read again from the export the record names with
    /// its options, by frame number, each box's track such that [`crate::label::instance_of`]
    /// gives the instance id the label files hold.
    pub fn imported_boxes(&self) -> Result<crate::source::annotations::FrameBoxes> {
        use crate::source::annotations;
        let a = annotations::read(&self.boxes, self.params.format, &self.params.read_options())?;
        let instance: BTreeMap<&str, u16> = (self.instances.iter())
            .map(|e| (e.track.as_str(), e.instance))
            .collect();
        let mut out = annotations::FrameBoxes {
            file: self.boxes.clone(),
            ..Default::default()
        };
        for (name, f) in &self.frames {
            let (Ok(frame), Some(af)) = (name.parse::<u32>(), a.frames.get(&f.annotation)) else {
                continue;
            };
            let boxes = (af.boxes.iter())
                .map(|b| {
                    let id = a.tracks.get(b.track).map_or("", String::as_str);
                    let track = instance.get(id).map_or(b.track, |&i| usize::from(i) - 1);
                    out.tool_ids.insert(track, id.to_string());
                    crate::source::boxes::AnnotatedBox { track, ..b.clone() }
                })
                .collect();
            out.frames.insert(frame, boxes);
            out.files.insert(frame, af.file.clone());
        }
        Ok(out)
    }
}

/// Gives every labelled sequence of `plan` the boxes its labels were made from
/// ([`BoxLabelRecord::imported_boxes`]; `--viz` draws them), their files among the drive's inputs (a changed
/// export reconverts its frames). A sequence whose export cannot be read keeps no boxes: the
/// errors are returned, for the caller to say.
pub fn attach_imported_boxes(plan: &mut crate::plan::Plan) -> Vec<crate::Error> {
    let mut errors = Vec::new();
    for dp in &mut plan.drives {
        if dp.drive.dataset != crate::source::DatasetKind::Sequence {
            continue;
        }
        let (boxes, inputs) = crate::fs::recording(|| {
            read(&dp.drive.dir)?
                .map(|rec| rec.imported_boxes())
                .transpose()
        });
        match boxes {
            Ok(Some(b)) => {
                dp.boxes = std::sync::Arc::new(b);
                dp.inputs.extend(inputs.records().iter().cloned());
            }
            Ok(None) => {}
            Err(e) => errors.push(e),
        }
    }
    errors
}
