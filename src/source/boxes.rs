//! The seam between box annotations and labelling: one typed box ([`Box3`], with its class name
//! and track as an [`AnnotatedBox`]), one typed convention for how a format writes its boxes
//! ([`BoxConvention`]: origin, size order, frame; [`BoxRotation`]: the rotation's form, in
//! radians), and a [`BoxSource`]: what the plan holds for a folder of frames.
//!
//! Every box reader (KITTI's tracklets and object labels, the Python module's boxes, and next the
//! annotation tools' exports) says what its file says through a convention and gives boxes in
//! the scan's frame; turning a box into a class is [`crate::label`]'s rule, which reads no file.

use std::path::Path;

use crate::geom::{na, nearest_rotation, Iso3, Point3, Real, Vector3};

/// A box in a scan's frame: its centre, its half extents along its own axes and its rotation
/// (box axes to the scan's).
#[derive(Debug, Clone, PartialEq)]
pub struct Box3 {
    /// The box's pose: its centre and axes in the scan's frame.
    pub pose: Iso3,
    /// Half extents along the box's own x, y, z.
    pub half_extents: Vector3,
}

impl Box3 {
    /// The centre, in the scan's frame.
    pub fn centre(&self) -> Point3 {
        Point3::from(self.pose.translation.vector)
    }

    /// The box carried by the rigid motion `motion` (a box given in a vehicle frame, into the
    /// sensor's: the inverse of the sensor's pose), composed in double precision.
    pub fn moved(&self, motion: &na::Isometry3<f64>) -> Box3 {
        let pose = motion * self.pose.cast::<f64>();
        Box3 {
            pose: pose.cast::<Real>(),
            half_extents: self.half_extents,
        }
    }
}

/// A box as an annotation holds it: its geometry, its class name as the file writes it (a
/// tracklet's `objectType`, a label's type; the class map decides its class) and its track.
#[derive(Debug, Clone, PartialEq)]
pub struct AnnotatedBox {
    /// The box, in the scan's frame.
    pub geometry: Box3,
    /// The class name as the file writes it (`Car`, `Pedestrian`, ...).
    pub class_name: String,
    /// The box's track in its source (a tracklet's index, a label line's), from 0: the same
    /// object keeps its track across the frames of a sequence.
    pub track: usize,
}

/// Where a format's box position sits on the box.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BoxOrigin {
    /// The box's centre.
    Centre,
    /// The centre of its bottom face (KITTI's tracklets and object labels).
    BottomCentre,
}

crate::named_enum!(BoxOrigin, "box origin", [
    Centre => "centre" ["center"] "the box's centre",
    BottomCentre => "bottom" ["bottom-centre", "bottom-center"] "the centre of its bottom face (KITTI's)",
]);

/// The order in which a format lists the box's sizes (full extents): length along the box's
/// own x (its heading), width along its y, height along its z.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SizeOrder {
    /// Length, width, height: the x, y, z extents.
    Lwh,
    /// Height, width, length (KITTI's `h w l`): the z, y, x extents.
    Hwl,
    /// KITTI's fields `h w l` as Datumaro's exporter fills them (Datumaro issue #1578): the y,
    /// x, z extents.
    HwlSwapped,
}

/// The frame a format's boxes are given in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BoxFrame {
    /// The scan's own frame (x forward, z up): tracklets, the annotation tools' exports.
    Scan,
    /// KITTI's rectified camera 0 frame (x right, y down, z forward; `label_2`), carried into
    /// the scan's frame by a transform the reader gives. The box's own axes there: length
    /// along x, height along y, width along z.
    RectifiedCamera,
}

/// A box's rotation as a format writes it, in radians.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum BoxRotation {
    /// Roll, pitch, yaw about the frame's x, y, z (applied as nalgebra's `from_euler_angles`:
    /// yaw, then pitch, then roll about the fixed axes); KITTI's tracklets.
    Euler([f64; 3]),
    /// A yaw about the frame's vertical axis alone (the scan's z; the camera's y).
    Yaw(f64),
    /// A rotation matrix (box axes to the frame's), orthonormal within the tolerance of
    /// [`crate::geom::check_rotation`]; the nearest rotation is taken.
    Matrix(na::Matrix3<f64>),
}

/// How a format writes its boxes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BoxConvention {
    /// Where the position sits.
    pub origin: BoxOrigin,
    /// The order of the sizes.
    pub sizes: SizeOrder,
    /// The frame of the position and rotation.
    pub frame: BoxFrame,
}

impl BoxConvention {
    /// KITTI raw's `tracklet_labels.xml`: the bottom centre, `h w l`, Euler angles, the
    /// velodyne (scan) frame.
    pub const KITTI_TRACKLET: BoxConvention = BoxConvention {
        origin: BoxOrigin::BottomCentre,
        sizes: SizeOrder::Hwl,
        frame: BoxFrame::Scan,
    };
    /// KITTI object's `label_2`: the bottom centre, `h w l`, a yaw about the camera's y, the
    /// rectified camera 0 frame.
    pub const KITTI_OBJECT: BoxConvention = BoxConvention {
        origin: BoxOrigin::BottomCentre,
        sizes: SizeOrder::Hwl,
        frame: BoxFrame::RectifiedCamera,
    };
    /// The centre, `l w h`, the scan's frame: the Python module's boxes, and the form most box
    /// annotation tools export.
    pub const CENTRED_LWH: BoxConvention = BoxConvention {
        origin: BoxOrigin::Centre,
        sizes: SizeOrder::Lwh,
        frame: BoxFrame::Scan,
    };

    /// The box a file writes as `position`, `sizes` (in this convention's order) and
    /// `rotation`, in the scan's frame. `to_scan` carries a box of another frame into the scan's
    /// (a homogeneous transform, [`BoxFrame::RectifiedCamera`]'s `(R0_rect * Tr_velo_to_cam)^-1`);
    /// it is the identity when `None`.
    pub fn place(
        &self,
        position: [f64; 3],
        sizes: [f64; 3],
        rotation: &BoxRotation,
        to_scan: Option<&na::Matrix4<f64>>,
    ) -> Box3 {
        let [l, w, h] = match self.sizes {
            SizeOrder::Lwh => sizes,
            SizeOrder::Hwl => [sizes[2], sizes[1], sizes[0]],
            SizeOrder::HwlSwapped => [sizes[1], sizes[0], sizes[2]],
        };
        match self.frame {
            BoxFrame::Scan => self.place_in_scan(position, [l, w, h], rotation, to_scan),
            BoxFrame::RectifiedCamera => {
                self.place_from_camera(position, [l, w, h], rotation, to_scan)
            }
        }
    }

    /// A box given in the scan's frame, in single precision (the labeller's).
    fn place_in_scan(
        &self,
        p: [f64; 3],
        [l, w, h]: [f64; 3],
        rotation: &BoxRotation,
        to_scan: Option<&na::Matrix4<f64>>,
    ) -> Box3 {
        let half = Vector3::new(l as Real / 2.0, w as Real / 2.0, h as Real / 2.0);
        let rot = match rotation {
            BoxRotation::Euler([r, p, y]) => {
                na::UnitQuaternion::from_euler_angles(*r as Real, *p as Real, *y as Real)
            }
            BoxRotation::Yaw(y) => na::UnitQuaternion::from_euler_angles(0.0, 0.0, *y as Real),
            BoxRotation::Matrix(m) => {
                na::UnitQuaternion::from_rotation_matrix(&nearest_rotation(m)).cast::<Real>()
            }
        };
        let at = na::Translation3::new(p[0] as Real, p[1] as Real, p[2] as Real);
        let mut pose = match self.origin {
            BoxOrigin::Centre => Iso3::from_parts(at, rot),
            // Lifted by h/2 along the box's own z.
            BoxOrigin::BottomCentre => {
                Iso3::from_parts(at, rot) * na::Translation3::new(0.0, 0.0, half.z)
            }
        };
        if let Some(m) = to_scan {
            pose = rigid(&(m * pose.cast::<f64>().to_homogeneous()));
        }
        Box3 {
            pose,
            half_extents: half,
        }
    }

    /// A box given in KITTI's rectified camera frame (y down), carried into the scan's by
    /// `to_scan`, in double precision, then the nearest rotation.
    fn place_from_camera(
        &self,
        p: [f64; 3],
        [l, w, h]: [f64; 3],
        rotation: &BoxRotation,
        to_scan: Option<&na::Matrix4<f64>>,
    ) -> Box3 {
        let lift = match self.origin {
            BoxOrigin::Centre => 0.0,
            // Up is -y in the camera's frame.
            BoxOrigin::BottomCentre => -h / 2.0,
        };
        let centre = na::Point3::new(p[0], p[1], p[2]) + na::Vector3::new(0.0, lift, 0.0);
        let rot = match rotation {
            BoxRotation::Yaw(y) => na::UnitQuaternion::from_axis_angle(&na::Vector3::y_axis(), *y),
            BoxRotation::Euler([r, p, y]) => na::UnitQuaternion::from_euler_angles(*r, *p, *y),
            BoxRotation::Matrix(m) => {
                na::UnitQuaternion::from_rotation_matrix(&nearest_rotation(m))
            }
        };
        let rect_pose = na::Isometry3::from_parts(na::Translation3::from(centre.coords), rot);
        let m = match to_scan {
            Some(t) => t * rect_pose.to_homogeneous(),
            None => rect_pose.to_homogeneous(),
        };
        Box3 {
            pose: rigid(&m),
            half_extents: Vector3::new((l / 2.0) as Real, (h / 2.0) as Real, (w / 2.0) as Real),
        }
    }
}

/// The rigid motion nearest a homogeneous transform (KITTI's `R0_rect` is orthonormal to about
/// 1e-6, checked when read: the nearest rotation, in a bounded number of steps).
fn rigid(m: &na::Matrix4<f64>) -> Iso3 {
    let rot = nearest_rotation(&m.fixed_view::<3, 3>(0, 0).into_owned());
    let t = m.fixed_view::<3, 1>(0, 3);
    Iso3::from_parts(
        na::Translation3::new(t[0] as Real, t[1] as Real, t[2] as Real),
        na::UnitQuaternion::from_rotation_matrix(&rot).cast::<Real>(),
    )
}

/// Where a folder of frames' boxes come from: what the plan holds for each drive. KITTI's
/// tracklets are one; the box annotation formats plug in here.
pub trait BoxSource: std::fmt::Debug + Send + Sync {
    /// The boxes present at `frame`, in the source's order, in the scan's frame.
    fn boxes_at(&self, frame: u32) -> Vec<AnnotatedBox>;
    /// How many boxes `frame` has.
    fn count_at(&self, frame: u32) -> usize;
    /// One past the last frame any box is at (0 without boxes).
    fn end_frame(&self) -> u32;
    /// The class name of every track whose type the source's format does not define (KITTI's
    /// tracklets: not one of its eight types), one entry a track.
    fn unknown_types(&self) -> Vec<String>;
    /// The file the boxes were read from, if any.
    fn file(&self) -> Option<&Path>;
}

/// No boxes (a drive without an annotation file).
#[derive(Debug, Clone, Copy, Default)]
pub struct NoBoxes;

impl BoxSource for NoBoxes {
    fn boxes_at(&self, _: u32) -> Vec<AnnotatedBox> {
        Vec::new()
    }
    fn count_at(&self, _: u32) -> usize {
        0
    }
    fn end_frame(&self) -> u32 {
        0
    }
    fn unknown_types(&self) -> Vec<String> {
        Vec::new()
    }
    fn file(&self) -> Option<&Path> {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The conventions state the same box three ways: KITTI's tracklet form (bottom centre,
    /// h w l), the centred form (l w h) and a matrix rotation give one box.
    #[test]
    fn one_box_in_three_conventions() {
        let yaw = 0.7f64;
        let t = BoxConvention::KITTI_TRACKLET.place(
            [1.0, 2.0, -1.0],
            [1.5, 1.8, 4.0],
            &BoxRotation::Euler([0.0, 0.0, yaw]),
            None,
        );
        let c = BoxConvention::CENTRED_LWH.place(
            [1.0, 2.0, -0.25],
            [4.0, 1.8, 1.5],
            &BoxRotation::Yaw(yaw),
            None,
        );
        let m = BoxConvention::CENTRED_LWH.place(
            [1.0, 2.0, -0.25],
            [4.0, 1.8, 1.5],
            &BoxRotation::Matrix(*na::Rotation3::from_euler_angles(0.0, 0.0, yaw).matrix()),
            None,
        );
        for b in [&c, &m] {
            assert_eq!(b.half_extents, t.half_extents);
            assert!((b.centre() - t.centre()).norm() < 1e-6, "{b:?}");
            assert!(b.pose.rotation.angle_to(&t.pose.rotation) < 1e-6);
        }
        assert_eq!(t.half_extents, Vector3::new(2.0, 0.9, 0.75));
    }

    /// A camera-frame box: its bottom centre lifted along -y, its height along the camera's y.
    #[test]
    fn a_camera_box_lifts_along_minus_y() {
        let b = BoxConvention::KITTI_OBJECT.place(
            [1.0, 1.6, 10.0],
            [1.5, 1.8, 4.0],
            &BoxRotation::Yaw(0.0),
            None,
        );
        assert_eq!(b.centre(), Point3::new(1.0, 0.85, 10.0));
        assert_eq!(b.half_extents, Vector3::new(2.0, 0.75, 0.9));
    }
}
