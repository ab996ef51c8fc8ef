//! The geometric vocabulary of the crate.
//!
//! parry3d 0.26 and later moved to glam; we pin parry3d 0.25, the last release that speaks
//! nalgebra, so that calibration, labelling and projection share one set of types with no
//! conversion at the labelling boundary. `na` is the nalgebra that parry3d re-exports: using it
//! guarantees that the types we hand to parry are parry's own.
//!
//! Frames: `velo` (x forward, y left, z up, metres), `cam` (camera 0: x right, y down, z forward),
//! `rect` (camera 0 after rectification), `imu` (OXTS). A transform is named `a_to_b`: it takes
//! coordinates in frame a to frame b. Positions are points, displacements are vectors. Angles are
//! radians inside the code; degrees only at the CLI and config boundary, with a `_deg` suffix.

pub use parry3d::na;

/// Scalar of point data and labelling (the velodyne stores float32).
pub type Real = f32;
/// A position in the velodyne frame, metres.
pub type Point3 = na::Point3<Real>;
/// A displacement or extent, metres.
pub type Vector3 = na::Vector3<Real>;
/// A rigid motion in single precision (box poses).
pub type Iso3 = na::Isometry3<Real>;
/// A rigid motion in double precision that keeps the calibration's rotation matrix exactly as
/// written in the file (KITTI's matrices are orthonormal only to about 1e-6).
pub type RigidF64 = na::IsometryMatrix3<f64>;
/// A 3x4 projection matrix (rectified camera), pixels.
pub type Matrix3x4 = na::Matrix3x4<f64>;

/// An angle in degrees, only used at configuration boundaries.
#[derive(Debug, Clone, Copy, PartialEq, PartialOrd, serde::Serialize, serde::Deserialize)]
pub struct Degrees(pub f64);

impl Degrees {
    /// The same angle in radians.
    #[must_use]
    pub fn to_radians(self) -> f64 {
        self.0.to_radians()
    }
}

/// `x.floor()` as an integer, for finite `x` well inside the i64 range.
///
/// `f64::floor` is a libm call on x86-64 without SSE4.1; this inlines to a truncation and a
/// compare, which matters in the per-point loops.
#[inline(always)]
#[must_use]
pub fn floor_i64(x: f64) -> i64 {
    let t = x as i64;
    t - ((t as f64) > x) as i64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn floor_matches_std() {
        for x in [
            -2.5,
            -2.0,
            -1e-12,
            -0.0,
            0.0,
            1e-12,
            0.5,
            1.0,
            255.999,
            511.0000001,
            -511.5,
        ] {
            assert_eq!(floor_i64(x), x.floor() as i64, "{x}");
        }
    }
}
