//! CONVERT: the labels of one frame's points, from whichever source its layout has.
//!
//! - KITTI raw: the tracklet boxes present at the frame, through the [`Labeller`];
//! - KITTI object: the `label_2` boxes, carried into the velodyne frame with the frame's
//!   calibration, through the same [`Labeller`] (same containment and overlap rule);
//!   instance = object line + 1;
//! - SemanticKITTI: each point's own label, its low 16 bits through the class map's
//!   `learning_map`, its high 16 bits the instance.
//!
//! A frame without labels (SemanticKITTI test sequences, object `testing/`) gets the class
//! map's background (SemanticKITTI's `unlabeled`) everywhere, and says so (`annotated: false`).

use crate::error::{Error, Result};
use crate::format::label_file;
use crate::label::{ClassMap, LabelBox, Labeller, PointLabels};
use crate::plan::DrivePlan;
use crate::source::boxes::AnnotatedBox;
use crate::source::kitti::calib::FrameCalib;
use crate::source::kitti::object;
use crate::source::kitti::DatasetKind;
use crate::source::Scan;

/// The labels of one frame.
#[derive(Debug, Clone)]
pub struct FrameLabels {
    /// Class and instance of each point of the scan, in the scan's order.
    pub points: PointLabels,
    /// The boxes that took part (box sources), for reports and visualisation.
    pub boxes: Vec<LabelBox>,
    /// Whether the frame has labels at all.
    pub annotated: bool,
    /// Object types of the frame's boxes that KITTI does not define, as written (labelled as
    /// the class map says: background unless it lists them).
    pub unknown_types: Vec<String>,
}

impl FrameLabels {
    /// The labels `boxes` give the scan's points.
    pub fn from_boxes(boxes: Vec<LabelBox>, scan: &Scan, map: &ClassMap) -> FrameLabels {
        let labeller = Labeller::new(&boxes, map.background);
        let kept: Vec<LabelBox> = boxes
            .into_iter()
            .filter(|b| b.class != map.background)
            .collect();
        FrameLabels {
            points: labeller.label(&scan.points),
            boxes: kept,
            annotated: true,
            unknown_types: Vec::new(),
        }
    }

    fn unlabelled(scan: &Scan, map: &ClassMap) -> FrameLabels {
        FrameLabels {
            points: PointLabels {
                class: vec![map.background; scan.len()],
                instance: vec![0; scan.len()],
            },
            boxes: Vec::new(),
            annotated: false,
            unknown_types: Vec::new(),
        }
    }
}

/// The labels of frame `frame` of `dp` for its `scan`, classed by `map`.
pub fn frame_labels(
    dp: &DrivePlan,
    frame: u32,
    scan: &Scan,
    map: &ClassMap,
) -> Result<FrameLabels> {
    let drive = &dp.drive;
    match drive.dataset {
        DatasetKind::Raw => Ok(FrameLabels::from_boxes(
            dp.label_boxes(frame, map),
            scan,
            map,
        )),
        DatasetKind::Object => object_labels(dp, frame, scan, map),
        DatasetKind::Sequence => {
            let path = drive.point_labels_path(frame);
            if !crate::fs::present(&path) {
                return Ok(FrameLabels::unlabelled(scan, map));
            }
            if map.learning_map.is_empty() {
                return Err(Error::Config(format!(
                    "{}: per-point labels need a class map with a learning_map (a semantic-kitti.yaml); {} has none",
                    path.display(),
                    map.name
                )));
            }
            let scan_path = drive.scan_path(frame);
            let points = label_file::read_point_labels(&path, scan, &scan_path, map)?;
            // A sequence labelled from boxes has them ([`crate::format::box_labels`]): for the
            // pictures, never for the labels, which are the file's.
            let boxes = (dp.label_boxes(frame, map).into_iter())
                .filter(|b| b.class != map.background)
                .collect();
            Ok(FrameLabels {
                points,
                boxes,
                annotated: true,
                unknown_types: Vec::new(),
            })
        }
    }
}

/// The labels of object frame `frame` of `dp`: its `label_2` boxes, carried into the velodyne
/// frame by the frame's calibration, classed by `map`.
fn object_labels(dp: &DrivePlan, frame: u32, scan: &Scan, map: &ClassMap) -> Result<FrameLabels> {
    let drive = &dp.drive;
    let path = drive.object_labels_path(frame);
    if !crate::fs::present(&path) {
        return Ok(FrameLabels::unlabelled(scan, map));
    }
    let objects = object::read(&path)?;
    let calib_path = drive.calib_path(frame);
    let rect_to_velo = FrameCalib::read(&calib_path)?
        .velo_to_rect()
        .try_inverse()
        .ok_or_else(|| Error::format(&calib_path, "R0_rect * Tr_velo_to_cam is not invertible"))?;
    let boxes: Vec<AnnotatedBox> = (objects.iter().enumerate())
        .map(|(i, o)| o.annotated(i, &rect_to_velo))
        .collect();
    let boxes = crate::label::label_boxes(&boxes, map);
    Ok(FrameLabels {
        unknown_types: objects
            .iter()
            .filter(|o| !o.is_known_type())
            .map(|o| o.kind.clone())
            .collect(),
        ..FrameLabels::from_boxes(boxes, scan, map)
    })
}
