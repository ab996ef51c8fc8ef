//! One annotated frame: its scan read, every point labelled by the frame's boxes (the rule of
//! [`crate::label`]: parry containment, smallest box wins), and `labels/<frame6>.label` written
//! unless the file there already holds exactly these labels and was written by `label`.

use std::path::{Path, PathBuf};

use crate::error::Result;
use crate::format::box_labels::LabelledFrame;
use crate::format::{label_file, Durability};
use crate::fs::Fingerprint;
use crate::label::{ClassCounts, ClassMap, LabelBox, Labeller};

/// One frame's work.
#[derive(Debug, Clone)]
pub struct FrameJob {
    /// The frame number in its sequence.
    pub frame: u32,
    /// Its scan.
    pub scan: PathBuf,
    /// Its label file.
    pub label: PathBuf,
    /// The scan's name as the annotations give it.
    pub annotation: String,
    /// The file the boxes came from.
    pub box_file: PathBuf,
    /// Every box of the frame with its class and instance (margin applied), in file order.
    pub boxes: Vec<LabelBox>,
    /// The frame's per-point annotations, where it has them: they decide the points they
    /// label, the boxes the rest.
    pub points: Option<FramePoints>,
    /// The frame's entry in the previous run's record, when the label file there is still the
    /// one it wrote.
    pub previous: Option<LabelledFrame>,
}

/// A frame's per-point annotations, resolved.
#[derive(Debug, Clone)]
pub struct FramePoints {
    /// Each point's object id (0: none), in the scan file's order.
    pub objects: Vec<u32>,
    /// Each object's class and instance.
    pub by_object: std::collections::BTreeMap<u32, (crate::label::ClassId, u16)>,
}

/// What became of a frame.
#[derive(Debug, Clone)]
pub struct FrameDone {
    /// The frame's entry in the record.
    pub record: LabelledFrame,
    /// Whether the label file was written (`false`: it already held these labels).
    pub written: bool,
    /// Points per class (dropped points are the background).
    pub counts: ClassCounts,
    /// Points in the scan file.
    pub points: u64,
}

/// Labels one frame with `map` (a per-point map: [`ClassMap::for_point_labels`]); `params_key`
/// is the run's parameters ([`crate::format::box_labels::BoxLabelParams::key`]).
pub fn label_frame(
    job: &FrameJob,
    map: &ClassMap,
    params_key: &str,
    d: Durability,
) -> Result<FrameDone> {
    let (scan, inputs) = crate::fs::inputs::recording(|| crate::source::read_file(&job.scan, None));
    let scan = scan?;
    let labels = Labeller::new(&job.boxes, map.background).label(&scan.points);
    let mut class = scan.to_file_order(&labels.class, map.background);
    let mut instance = scan.to_file_order(&labels.instance, 0);
    if let Some(p) = &job.points {
        apply_points(
            p,
            map.background,
            (&mut class, &mut instance),
            &job.box_file,
        )?;
    }
    let entries: Vec<u32> = (class.iter().zip(&instance))
        .map(|(&c, &i)| map.raw_of_class(c).unwrap_or(u32::from(c)) | u32::from(i) << 16)
        .collect();
    let bytes = label_file::encode_raw(&entries);
    let mut h = xxhash_rust::xxh3::Xxh3::new();
    h.update(params_key.as_bytes());
    for r in inputs.records() {
        if let Some(f) = &r.file {
            h.update(&f.xxh3.to_le_bytes());
        }
    }
    hash_boxes(&mut h, &job.boxes);
    if let Some(p) = &job.points {
        h.update(&[1]);
        for (id, (c, i)) in &p.by_object {
            h.update(&id.to_le_bytes());
            h.update(&[*c]);
            h.update(&i.to_le_bytes());
        }
        h.update(bytemuck::cast_slice(&p.objects));
    }
    let xxh3 = xxhash_rust::xxh3::xxh3_64(&bytes);
    let unchanged = (job.previous.as_ref())
        .is_some_and(|p| p.label.size == bytes.len() as u64 && p.label.xxh3 == xxh3);
    if !unchanged {
        crate::format::create_dir(job.label.parent().expect("a file in a folder"))?;
        crate::format::atomic_write(&job.label, &bytes, d)?;
    }
    let label = match (unchanged, &job.previous) {
        (true, Some(p)) => p.label,
        _ => Fingerprint::of_written(&job.label, bytes.len() as u64, xxh3)?,
    };
    Ok(FrameDone {
        record: LabelledFrame {
            annotation: job.annotation.clone(),
            box_file: job.box_file.clone(),
            boxes: job.boxes.len(),
            key: format!("{:016x}", h.digest()),
            label,
        },
        written: !unchanged,
        counts: ClassCounts::count(map.len(), class.iter().copied()),
        points: scan.file_len as u64,
    })
}

/// Gives the points that the per-point annotations label their object's class and instance (the
/// background's with instance 0); a
/// count that is not the scan's is an error naming the annotation file.
fn apply_points(
    p: &FramePoints,
    background: crate::label::ClassId,
    (class, instance): (&mut [crate::label::ClassId], &mut [u16]),
    file: &Path,
) -> Result<()> {
    if p.objects.len() != class.len() {
        return Err(crate::error::Error::format(
            file,
            format!(
                "{} point annotations, but the scan has {} points",
                p.objects.len(),
                class.len()
            ),
        ));
    }
    for (k, &id) in p.objects.iter().enumerate().filter(|(_, &id)| id != 0) {
        let (c, i) = p.by_object[&id];
        class[k] = c;
        // An object of the background class labels nothing, as a box of it does.
        instance[k] = if c == background { 0 } else { i };
    }
    Ok(())
}

/// Every number that places and names a box, in order.
fn hash_boxes(h: &mut xxhash_rust::xxh3::Xxh3, boxes: &[LabelBox]) {
    for b in boxes {
        h.update(&[b.class]);
        h.update(&b.instance.to_le_bytes());
        let t = b.pose.translation.vector;
        let q = b.pose.rotation.coords;
        let e = b.cuboid.half_extents;
        for v in t.iter().chain(q.iter()).chain(e.iter()) {
            h.update(&v.to_le_bytes());
        }
    }
}
