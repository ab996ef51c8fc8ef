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

/// Scalar of point data and labelling (scans store float32).
pub type Real = f32;
/// A position in a scan's frame (the sensor's, or KITTI's velodyne frame), metres.
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

/// Points farther than this from the sensor are dropped, metres (four times the HDL-64E's
/// 120 m reach; beyond every spinning LiDAR's).
pub const MAX_RANGE_M: f32 = 500.0;

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

/// How far from orthonormal a rotation matrix may be: the largest entry of `RᵀR - I`. KITTI's
/// matrices are orthonormal to about 1e-6; 1e-3 still rejects any typo in a digit that matters.
pub const ROTATION_TOLERANCE: f64 = 1e-3;

/// Checks that `m` is a rotation: finite, orthonormal within [`ROTATION_TOLERANCE`], determinant
/// +1 (not a reflection). The error says which test failed, with the value.
pub fn check_rotation(m: &na::Matrix3<f64>) -> Result<(), String> {
    if let Some(v) = m.iter().find(|v| !v.is_finite()) {
        return Err(format!("holds a non-finite value {v}"));
    }
    let off = (m.transpose() * m - na::Matrix3::identity()).amax();
    if off.is_nan() || off > ROTATION_TOLERANCE {
        return Err(format!(
            "is not a rotation: RᵀR differs from the identity by {off:.3e} (tolerance {ROTATION_TOLERANCE:e})"
        ));
    }
    let det = m.determinant();
    if det <= 0.0 {
        return Err(format!(
            "is a reflection, not a rotation (determinant {det:.6})"
        ));
    }
    Ok(())
}

/// The largest extent a box may have along any axis, metres: three times the longest box of
/// KITTI's tracklets (a tram, 35.2 m), far below what would label a strip of the scene.
pub const MAX_BOX_EXTENT_M: f64 = 100.0;

/// Checks a box's extents (any order; metres): finite in single precision (the labeller's),
/// positive, at most [`MAX_BOX_EXTENT_M`]. The rule of every box source (tracklets, `label_2`,
/// the Python module); the error names the bad value.
pub fn check_box_extents(extents: &[f64; 3], names: [&str; 3]) -> Result<(), String> {
    for (&x, name) in extents.iter().zip(names) {
        let v = crate::error::shown(x);
        if !(x as Real).is_finite() {
            return Err(format!(
                "box size {name}={v} is not finite in single precision"
            ));
        }
        if x <= 0.0 {
            return Err(format!("box size must be positive, found {name}={v}"));
        }
        if x > MAX_BOX_EXTENT_M {
            return Err(format!(
                "box size {name}={v} m is implausible (at most {MAX_BOX_EXTENT_M} m)"
            ));
        }
    }
    Ok(())
}

/// The rotation nearest to `m`, found in a bounded number of iterations (nalgebra's
/// `from_matrix` iterates until it converges, which a wild matrix never does).
pub fn nearest_rotation<T: na::RealField + Copy>(m: &na::Matrix3<T>) -> na::Rotation3<T> {
    na::Rotation3::from_matrix_eps(m, T::default_epsilon(), 64, na::Rotation3::identity())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rotations_checked_and_bounded() {
        let r = na::Rotation3::from_euler_angles(0.1, 0.2, 0.3).into_inner();
        assert!(check_rotation(&r).is_ok());
        let mut typo = r;
        typo[(0, 1)] += 0.1;
        assert!(check_rotation(&typo)
            .unwrap_err()
            .contains("not a rotation"));
        let reflect = -na::Matrix3::<f64>::identity();
        assert!(check_rotation(&reflect).unwrap_err().contains("reflection"));
        let wild = na::Matrix3::<f64>::repeat(1e155);
        assert!(check_rotation(&wild).is_err());
        // Bounded: returns (something) on matrices nalgebra's from_matrix spins on.
        let _ = nearest_rotation(&wild);
        let _ = nearest_rotation(&na::Matrix3::<f64>::repeat(f64::NAN));
        assert!((nearest_rotation(&r).into_inner() - r).amax() < 1e-9);
    }

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
