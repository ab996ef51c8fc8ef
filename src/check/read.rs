//! A drive's files read once for every check ([`DriveRead`]: what each layout has, as
//! [`LayoutRead`]), the boxes of a frame, and the small helpers that read file lists and note
//! what is missing.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use super::{frame_ranges, CheckName as C, Collector, DriveInventory, ObjectRef, Severity as S};
use crate::error::Result;
use crate::geom::Matrix3x4;
use crate::label::{ClassMap, LabelBox};
use crate::source::annotations::FrameBoxes;
use crate::source::boxes::AnnotatedBox;
use crate::source::kitti::calib::{Calibration, FrameCalib};
use crate::source::kitti::object::ObjectLabel;
use crate::source::kitti::timestamps::Timestamp;
use crate::source::kitti::tracklets::{Occlusion, Pose, Tracklet, Tracklets};
use crate::source::kitti::{DatasetKind, Drive};

/// A drive's annotations, calibration and file lists, read once.
#[derive(Debug)]
pub(crate) struct DriveRead {
    pub drive: Drive,
    pub inventory: DriveInventory,
    /// Frames with a scan, ascending, and each scan's point count (from its size).
    pub scans: BTreeMap<u32, usize>,
    /// Camera number -> frames with an image.
    pub images: BTreeMap<u8, Vec<u32>>,
    /// The layout's own files.
    pub layout: LayoutRead,
    /// The boxes a sequence labelled by `kitti2pgm label` was made from.
    pub imported: Option<Imported>,
}

/// The files of a drive that its layout has, as read (`None` where one could not be).
#[derive(Debug)]
pub(crate) enum LayoutRead {
    /// A raw drive.
    Raw {
        /// The tracklets.
        tracklets: Option<Tracklets>,
        /// The velodyne timestamps.
        timestamps: Option<Vec<Option<Timestamp>>>,
        /// The day's calibration.
        calib: Option<Box<Calibration>>,
    },
    /// A sequence.
    Sequence {
        /// `calib.txt`.
        calib: Option<Box<FrameCalib>>,
        /// `poses.txt`.
        poses: Option<Vec<Matrix3x4>>,
        /// Frames with a label file.
        label_frames: Vec<u32>,
    },
    /// The object set: each frame's boxes and calibration, where both could be read.
    Object {
        /// Frame -> its boxes and calibration.
        objects: BTreeMap<u32, (Vec<ObjectLabel>, FrameCalib)>,
    },
}

impl LayoutRead {
    /// Nothing read yet, for `layout`.
    fn empty(layout: DatasetKind) -> LayoutRead {
        match layout {
            DatasetKind::Raw => LayoutRead::Raw {
                tracklets: None,
                timestamps: None,
                calib: None,
            },
            DatasetKind::Sequence => LayoutRead::Sequence {
                calib: None,
                poses: None,
                label_frames: Vec::new(),
            },
            DatasetKind::Object => LayoutRead::Object {
                objects: BTreeMap::new(),
            },
        }
    }
}

impl DriveRead {
    /// Nothing read yet of `drive`.
    pub(crate) fn new(drive: &Drive) -> DriveRead {
        DriveRead {
            drive: drive.clone(),
            inventory: DriveInventory {
                drive: drive.name(),
                ..Default::default()
            },
            scans: BTreeMap::new(),
            images: BTreeMap::new(),
            layout: LayoutRead::empty(drive.dataset),
            imported: None,
        }
    }

    /// A raw drive's tracklets, when read.
    pub(crate) fn tracklets(&self) -> Option<&Tracklets> {
        match &self.layout {
            LayoutRead::Raw { tracklets, .. } => tracklets.as_ref(),
            _ => None,
        }
    }

    /// A raw drive's velodyne timestamps, when read.
    pub(crate) fn timestamps(&self) -> Option<&Vec<Option<Timestamp>>> {
        match &self.layout {
            LayoutRead::Raw { timestamps, .. } => timestamps.as_ref(),
            _ => None,
        }
    }

    /// A raw drive's day calibration, when read.
    pub(crate) fn calib(&self) -> Option<&Calibration> {
        match &self.layout {
            LayoutRead::Raw { calib, .. } => calib.as_deref(),
            _ => None,
        }
    }

    /// A sequence's `calib.txt`, when read.
    pub(crate) fn frame_calib(&self) -> Option<&FrameCalib> {
        match &self.layout {
            LayoutRead::Sequence { calib, .. } => calib.as_deref(),
            _ => None,
        }
    }

    /// A sequence's poses, when read.
    pub(crate) fn poses(&self) -> Option<&[Matrix3x4]> {
        match &self.layout {
            LayoutRead::Sequence { poses, .. } => poses.as_deref(),
            _ => None,
        }
    }

    /// A sequence's frames with a label file (none elsewhere).
    pub(crate) fn label_frames(&self) -> &[u32] {
        match &self.layout {
            LayoutRead::Sequence { label_frames, .. } => label_frames,
            _ => &[],
        }
    }

    /// An object frame's boxes and calibration, when both were read.
    pub(crate) fn object(&self, frame: u32) -> Option<&(Vec<ObjectLabel>, FrameCalib)> {
        match &self.layout {
            LayoutRead::Object { objects } => objects.get(&frame),
            _ => None,
        }
    }

    /// Every object frame's boxes and calibration (none elsewhere).
    pub(crate) fn objects(&self) -> impl Iterator<Item = (&u32, &(Vec<ObjectLabel>, FrameCalib))> {
        match &self.layout {
            LayoutRead::Object { objects } => Some(objects.iter()),
            _ => None,
        }
        .into_iter()
        .flatten()
    }
}

/// A box of one frame: a tracklet's or a `label_2` object's, or a tracklet's carried one frame
/// past its end (a ghost).
pub(crate) struct FrameBox {
    pub object: ObjectRef,
    pub label_box: LabelBox,
    /// Carried one frame past the end of its annotation.
    pub ghost: bool,
    /// Fully visible by the annotation (tracklet occlusion 0).
    pub visible: bool,
}

impl DriveRead {
    /// The boxes at `frame` (`DontCare` regions left out; a labelled sequence's imported
    /// boxes), and the ghosts of the tracklets or tracks that ended just before
    /// ([`FrameBox::ghost`]).
    pub(crate) fn boxes_at(&self, frame: u32) -> Vec<FrameBox> {
        let mut out = Vec::new();
        if let Some(i) = &self.imported {
            out.extend(i.boxes_at(frame));
        }
        if let Some(t) = self.tracklets() {
            for (i, tr, p) in t.at(frame) {
                out.push(FrameBox {
                    object: ObjectRef {
                        index: i as u32,
                        kind: tr.object_type.as_str().into(),
                    },
                    label_box: LabelBox::of(&tr.box_at(p), 0, crate::label::instance_of(i)),
                    ghost: false,
                    visible: p.occlusion == Occlusion::Visible,
                });
            }
            for (i, tr) in t.tracklets.iter().enumerate() {
                if let Some(pose) = carried_on(tr, frame) {
                    out.push(FrameBox {
                        object: ObjectRef {
                            index: i as u32,
                            kind: tr.object_type.as_str().into(),
                        },
                        label_box: LabelBox::of(&tr.box_at(&pose), 0, crate::label::instance_of(i)),
                        ghost: true,
                        visible: false,
                    });
                }
            }
        }
        if let Some((objects, calib)) = self.object(frame) {
            let rect_to_velo = calib.velo_to_rect().try_inverse().unwrap_or_default();
            for (i, o) in objects
                .iter()
                .enumerate()
                .filter(|(_, o)| o.kind != "DontCare")
            {
                out.push(FrameBox {
                    object: ObjectRef {
                        index: i as u32,
                        kind: o.kind.clone(),
                    },
                    label_box: LabelBox::of(
                        &o.box_in_velodyne(&rect_to_velo),
                        0,
                        crate::label::instance_of(i),
                    ),
                    ghost: false,
                    visible: false,
                });
            }
        }
        out
    }
}

/// A labelled sequence's imported boxes, as the checks read them.
#[derive(Debug)]
pub(crate) struct Imported {
    /// The boxes by frame, their tracks numbered as the label files' instances (id - 1).
    pub boxes: FrameBoxes,
    /// The class map the labels were written with.
    pub map: ClassMap,
}

impl Imported {
    /// The object a box is, as findings name it.
    pub(crate) fn object(&self, b: &AnnotatedBox) -> ObjectRef {
        let id = self.boxes.tool_ids.get(&b.track).map_or("", String::as_str);
        ObjectRef {
            index: b.track as u32,
            kind: format!("{} ({id})", b.class_name),
        }
    }

    /// The annotation file of `frame` (the export, for a frame without one).
    pub(crate) fn file(&self, frame: u32) -> PathBuf {
        (self.boxes.files.get(&frame).cloned()).unwrap_or_else(|| self.boxes.file.clone())
    }

    /// The boxes at `frame`, and the ghosts of the tracks that ended just before (carried one
    /// frame on by their last displacement: a track seen in the two frames before `frame`, not
    /// at it); imported boxes count as visible.
    pub(crate) fn boxes_at(&self, frame: u32) -> Vec<FrameBox> {
        let at = |f: u32| self.boxes.frames.get(&f);
        let mut out: Vec<FrameBox> = (at(frame).into_iter().flatten())
            .map(|b| FrameBox {
                object: self.object(b),
                label_box: LabelBox::of(&b.geometry, 0, crate::label::instance_of(b.track)),
                ghost: false,
                visible: true,
            })
            .collect();
        let (Some(before), Some(last)) = (
            frame.checked_sub(2).and_then(at),
            frame.checked_sub(1).and_then(at),
        ) else {
            return out;
        };
        let now: Vec<usize> = at(frame).into_iter().flatten().map(|b| b.track).collect();
        for b in last.iter().filter(|b| !now.contains(&b.track)) {
            let Some(p) = before.iter().find(|p| p.track == b.track) else {
                continue;
            };
            let step = b.geometry.pose.translation.vector - p.geometry.pose.translation.vector;
            let mut moved = b.geometry.clone();
            moved.pose.translation.vector += step;
            out.push(FrameBox {
                object: self.object(b),
                label_box: LabelBox::of(&moved, 0, crate::label::instance_of(b.track)),
                ghost: true,
                visible: false,
            });
        }
        out
    }
}

/// A tracklet's box one frame past its last pose, at `frame`: moved on by its last
/// displacement, same heading. `None` unless the tracklet ends just before `frame` with two
/// poses or more.
pub(crate) fn carried_on(tr: &Tracklet, frame: u32) -> Option<Pose> {
    let n = tr.poses.len();
    if tr.end_frame() != frame || n < 2 {
        return None;
    }
    let (prev, last) = (&tr.poses[n - 2], &tr.poses[n - 1]);
    Some(Pose {
        t: std::array::from_fn(|d| 2.0 * last.t[d] - prev.t[d]),
        ..last.clone()
    })
}

/// The frames of the files `<frame><ext>` in `dir` with a `width`-digit number, ascending.
pub(crate) fn frames_in(dir: &Path, width: usize, ext: &str) -> Vec<u32> {
    let Ok(entries) = crate::fs::sorted_dir(dir) else {
        return Vec::new();
    };
    let mut v: Vec<u32> = entries
        .iter()
        .filter_map(|p| {
            let name = p.file_name()?.to_str()?;
            let stem = name.strip_suffix(ext)?;
            (stem.len() == width).then(|| stem.parse().ok())?
        })
        .collect();
    v.sort_unstable();
    v
}

/// `r`'s value, or `None` with an error finding of `check` naming `path`.
pub(crate) fn read_or_note<T>(c: &mut Collector, check: C, path: &Path, r: Result<T>) -> Option<T> {
    match r {
        Ok(v) => Some(v),
        Err(e) => {
            c.add(check, S::Error, path, None, None, e.to_string());
            None
        }
    }
}

/// Names the frames of `expected` that `have` lacks, as one finding.
pub(crate) fn missing(
    c: &mut Collector,
    check: C,
    sev: S,
    file: &Path,
    expected: &[u32],
    have: &[u32],
    what: &str,
) {
    let lacking: Vec<u32> = expected
        .iter()
        .copied()
        .filter(|f| have.binary_search(f).is_err())
        .collect();
    if let Some(&first) = lacking.first() {
        c.add(
            check,
            sev,
            file,
            Some(first),
            None,
            format!(
                "{} {what}: frames {}",
                lacking.len(),
                frame_ranges(&lacking)
            ),
        );
    }
}
