//! PROJECT: 3D augmentation of a scan before it is projected (training on the fly).
//!
//! Range-image networks since RangeNet++ augment the point cloud, not the picture: points are
//! dropped, jittered, mirrored, rotated about z and scaled, then projected. Here the rows stay
//! the laser rings found in the *original* scan order (a point never changes row), and the
//! rotation is applied to the azimuth itself (`yaw + rotate`, [`super::PgmSpec::column_rotated`]),
//! so that a rotation by k column angles shifts the map by exactly k columns.
//!
//! Order, per point, with one seeded [`SplitMix`] stream: drop (probability `drop`), jitter
//! (independent bell-shaped, bounded noise of standard deviation `jitter` metres on x, y, z:
//! [`SplitMix::bell`], within +-3.46 `jitter`), mirror
//! (`y -> -y`), then rotate by `rotate` about z and scale by `scale`. The range is
//! `scale * |p|` of the jittered, mirrored point, so that a rotation leaves it unchanged to the
//! bit. With no drop, no jitter, no mirror, no rotation and unit scale the map is the
//! unaugmented one, byte for byte.

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::geom::Point3;
use crate::rng::SplitMix;

/// One sample's augmentation (the trainer draws one per sample).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Augment {
    /// Rotation about z, radians (counter-clockwise seen from above; any value, wrapped).
    pub rotate: f64,
    /// Scale of the coordinates and the range (1 = none).
    pub scale: f32,
    /// Mirror left and right (`y -> -y`), before the rotation.
    pub flip: bool,
    /// Standard deviation of the noise added to x, y and z, metres (0 = none); the noise is
    /// bell-shaped and bounded at 3.46 times this ([`SplitMix::bell`]).
    pub jitter: f32,
    /// Probability that a point is dropped, in [0, 1).
    pub drop: f32,
    /// Seed of the per-point draws (drop and jitter).
    pub seed: u64,
}

impl Default for Augment {
    /// The identity.
    fn default() -> Self {
        Augment {
            rotate: 0.0,
            scale: 1.0,
            flip: false,
            jitter: 0.0,
            drop: 0.0,
            seed: 0,
        }
    }
}

/// The points of an augmented cloud.
#[derive(Debug, Clone)]
pub struct Augmented {
    /// Index, in the input cloud, of each kept point (ascending).
    pub kept: Vec<u32>,
    /// Kept points after jitter and mirror, before rotation and scale: their azimuth plus
    /// [`Augmented::rotate`] gives the column.
    pub base: Vec<Point3>,
    /// Kept points as the map stores them (rotated and scaled).
    pub points: Vec<Point3>,
    /// The rotation, wrapped into [-pi, pi].
    pub rotate: f64,
    /// The scale.
    pub scale: f32,
}

/// The largest scale an augmentation takes (training uses about 0.9 to 1.1; far beyond,
/// ranges stop being those of a scanner).
pub const MAX_SCALE: f32 = 10.0;

/// The largest jitter (standard deviation) an augmentation takes, metres.
pub const MAX_JITTER_M: f32 = 10.0;

impl Augment {
    /// Checks the numbers.
    pub fn validate(&self) -> Result<()> {
        let bad = |what: String| Err(Error::Config(what));
        if !self.rotate.is_finite() {
            return bad(format!("rotation {} is not finite", self.rotate));
        }
        if !(self.scale > 0.0 && self.scale <= MAX_SCALE) {
            return bad(format!(
                "scale {:?} must be in (0, {MAX_SCALE}]",
                self.scale
            ));
        }
        if !(self.jitter >= 0.0 && self.jitter <= MAX_JITTER_M) {
            return bad(format!(
                "jitter {:?} must be in [0, {MAX_JITTER_M}] metres",
                self.jitter
            ));
        }
        if !(0.0..1.0).contains(&self.drop) {
            return bad(format!("drop {} must be in [0, 1)", self.drop));
        }
        Ok(())
    }

    /// Applies the augmentation to `points` (in scan order).
    pub fn apply(&self, points: &[Point3]) -> Augmented {
        self.apply_in_view(points, None)
    }

    /// [`Augment::apply`], keeping only the points that can end up in a view narrower than 180
    /// degrees: `view` is the tangent of its half-angle (with the projection's own margin). A
    /// point whose unjittered final position lies farther outside that wedge than the jitter can
    /// move it is left out, and its random draws are skipped over, so that every other point
    /// gets the same draws as without the view: the map is the same either way (tested).
    pub fn apply_in_view(&self, points: &[Point3], view: Option<f32>) -> Augmented {
        let rotate = wrap_pi(self.rotate);
        let (sin, cos) = (rotate.sin() as f32, rotate.cos() as f32);
        let scale = self.scale;
        let mut rng = SplitMix::new(self.seed);
        let cap = view.map_or(points.len(), |_| points.len() / 2);
        let mut kept = Vec::with_capacity(cap);
        let mut base = Vec::with_capacity(cap);
        let mut out = Vec::with_capacity(cap);
        let drop = self.drop as f64;
        let sigma = self.jitter;
        let sign = if self.flip { -1.0f32 } else { 1.0 };
        let draws = (drop > 0.0) as u64 + 3 * (sigma > 0.0) as u64;
        // How far the jitter can move a point across a wedge side (3 bounded draws, each at
        // most 2 sqrt(3) sigma), plus a millimetre for rounding.
        let reach = sigma * 2.0 * 3f32.sqrt() * 3f32.sqrt() + 1e-3;
        for (i, p) in points.iter().enumerate() {
            if let Some(t) = view {
                let (x, y) = (p.x, p.y * sign);
                let (xr, yr) = (x * cos - y * sin, x * sin + y * cos);
                // Distance outside the wedge |y| <= x t (positive outside), per unit of scale.
                if (yr.abs() - xr * t) / (1.0 + t * t).sqrt() > reach {
                    rng.skip(draws);
                    continue;
                }
            }
            if drop > 0.0 && rng.chance(drop) {
                rng.skip(draws - 1);
                continue;
            }
            let mut q = *p;
            if sigma > 0.0 {
                q.x += sigma * rng.bell();
                q.y += sigma * rng.bell();
                q.z += sigma * rng.bell();
            }
            q.y *= sign;
            out.push(Point3::new(
                scale * (q.x * cos - q.y * sin),
                scale * (q.x * sin + q.y * cos),
                q.z * scale,
            ));
            base.push(q);
            kept.push(i as u32);
        }
        Augmented {
            kept,
            base,
            points: out,
            rotate,
            scale,
        }
    }
}

/// `a` wrapped into [-pi, pi].
fn wrap_pi(a: f64) -> f64 {
    use std::f64::consts::{PI, TAU};
    if (-PI..=PI).contains(&a) {
        a
    } else {
        (a + PI).rem_euclid(TAU) - PI
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn identity_keeps_every_point_unchanged() {
        let pts = vec![Point3::new(1.5, -2.25, 0.1), Point3::new(-3.0, 4.0, -1.0)];
        let a = Augment::default().apply(&pts);
        assert_eq!(a.points, pts);
        assert_eq!(a.base, pts);
        assert_eq!(a.kept, [0, 1]);
    }

    #[test]
    fn quarter_turn_mirror_and_scale() {
        let pts = vec![Point3::new(1.0, 0.0, 1.0)];
        let a = Augment {
            rotate: std::f64::consts::FRAC_PI_2,
            scale: 2.0,
            flip: true,
            ..Default::default()
        }
        .apply(&pts);
        let p = a.points[0];
        assert!(
            p.x.abs() < 1e-6 && (p.y - 2.0).abs() < 1e-6 && p.z == 2.0,
            "{p:?}"
        );
        let w = wrap_pi(3.0 * std::f64::consts::PI);
        assert!((w.abs() - std::f64::consts::PI).abs() < 1e-12, "{w}");
    }

    #[test]
    fn drop_and_jitter_are_seeded() {
        let pts: Vec<Point3> = (0..10_000)
            .map(|i| Point3::new(i as f32, 1.0, 0.0))
            .collect();
        let aug = Augment {
            drop: 0.25,
            jitter: 0.01,
            seed: 9,
            ..Default::default()
        };
        let (a, b) = (aug.apply(&pts), aug.apply(&pts));
        assert_eq!(a.kept, b.kept);
        assert_eq!(a.points, b.points);
        let share = a.kept.len() as f64 / pts.len() as f64;
        assert!((share - 0.75).abs() < 0.02, "{share}");
        let c = Augment { seed: 10, ..aug }.apply(&pts);
        assert_ne!(a.kept, c.kept);
        assert!(Augment { drop: 1.0, ..aug }.validate().is_err());
        assert!(Augment { scale: 0.0, ..aug }.validate().is_err());
    }
}
