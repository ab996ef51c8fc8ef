//! PROJECT: the column of a point, by definition and fast.
//!
//! The definition: `column = floor((fov/2 - yaw) / (fov/cols))` with `yaw = atan2(y, x)` in
//! double precision ([`PgmSpec::column`]; plus a rotation about z for augmentation,
//! [`PgmSpec::column_rotated`]). The fast rule ([`Columns`]) computes it in single precision
//! with a polynomial `atan2` ([`atan2_fast`]), branch-free so that loops vectorise, and defers
//! to the definition for points within [`PgmSpec::border_margin`] of a column border, where the
//! two could disagree: its result is always the definition's (tested).

use super::PgmSpec;
use crate::geom::{floor_i64, Point3};

impl PgmSpec {
    /// Column of a point, if it lies in the field of view: `floor((fov/2 - yaw) / (fov/cols))`
    /// with `yaw = atan2(y, x)` in double precision (the definition).
    #[inline]
    pub fn column(&self, p: &Point3) -> Option<usize> {
        self.column_rotated(p, 0.0)
    }

    /// The column `p` takes once the cloud is rotated by `rotate` radians about z (in
    /// `[-pi, pi]`): the definition with `yaw = atan2(y, x) + rotate`, wrapped into
    /// `(-pi, pi]`. A rotation by a multiple of the column angle is then an exact shift of the
    /// columns, which rotating the coordinates in float32 first would not be.
    #[inline]
    pub fn column_rotated(&self, p: &Point3, rotate: f64) -> Option<usize> {
        let half = self.fov.to_radians() / 2.0;
        let yaw = rotated_yaw((p.y as f64).atan2(p.x as f64), rotate);
        let c = floor_i64((half - yaw) / (2.0 * half / self.cols as f64));
        (c >= 0 && c < self.cols as i64).then_some(c as usize)
    }

    /// [`PgmSpec::column`], computed with a fast single-precision `atan2` ([`atan2_fast`],
    /// several times cheaper than libm's) and checked: when the point lies within
    /// [`PgmSpec::border_margin`] of a column border, where the two could disagree, the
    /// double-precision definition decides. The result is always the definition's (tested on
    /// random points, on every border, and on every point of the shared scans).
    #[inline]
    pub fn column_fast(&self, p: &Point3) -> Option<usize> {
        self.columns().fast(p, 0.0)
    }

    /// The column rule with its constants computed once, for per-point loops.
    #[inline]
    pub fn columns(&self) -> Columns<'_> {
        let half = self.fov.to_radians() / 2.0;
        Columns {
            spec: self,
            half: half as f32,
            inv_step: (self.cols as f64 / (2.0 * half)) as f32,
            cols_f: self.cols as f32,
            cols_i: self.cols as i32,
            margin: self.border_margin() as f32,
        }
    }

    /// How close to a column border (in columns) the fast column defers to the definition: a
    /// bound on the error of the single-precision column, at least a thousandth of a column
    /// (at 0.5, every point takes the definition). The error, each term with room to spare:
    /// [`ATAN2_FAST_MAX_ERROR`] (five times the error measured) plus 1e-6 rad for the
    /// single-precision rotation, wrap and subtraction (at most 8e-7: five roundings of values
    /// below 2 pi, and pi and tau in float32), times the columns per radian; plus
    /// `8 cols eps` for the rounding of the column step and of the product (at most
    /// `1.5 cols eps`). (Twice this bound, as before, sent twice as many points to the
    /// definition's libm `atan2`: 1.2% of a 2048-column scan's points, a thirtieth of a call.)
    #[inline]
    pub fn border_margin(&self) -> f64 {
        let per_rad = self.cols as f64 / self.fov.to_radians();
        let err =
            (ATAN2_FAST_MAX_ERROR + 1e-6) * per_rad + 8.0 * self.cols as f64 * f32::EPSILON as f64;
        err.clamp(1e-3, 0.5)
    }
}

/// Where the columns and ranges of a projection come from: the points as the map stores them,
/// or (augmentation) points before a rotation about z and a scale.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Geometry<'a> {
    /// The points whose azimuth (plus `rotate`) gives the column and whose range (times
    /// `scale`) is stored, one per projected point.
    pub base: &'a [Point3],
    /// Rotation about z, radians, in [-pi, pi].
    pub rotate: f64,
    /// Range scale.
    pub scale: f32,
    /// The column of every point, given (the sensor's own: Ouster's), instead of by azimuth.
    pub columns: Option<&'a [u16]>,
}

impl<'a> Geometry<'a> {
    /// The points themselves: no rotation, unit scale.
    pub fn plain(points: &'a [Point3]) -> Geometry<'a> {
        Geometry::moved(points, 0.0, 1.0)
    }

    /// Points before a rotation about z by `rotate` and a scale of their range by `scale`.
    pub fn moved(base: &'a [Point3], rotate: f64, scale: f32) -> Geometry<'a> {
        Geometry {
            base,
            rotate,
            scale,
            columns: None,
        }
    }

    /// The geometry of the points `range` alone.
    pub fn part(&self, range: std::ops::Range<usize>) -> Geometry<'a> {
        Geometry {
            base: &self.base[range.clone()],
            columns: self.columns.map(|c| &c[range]),
            ..*self
        }
    }

    /// The column of point `i`, whose column code ([`Columns::code`]) is `code`: the given one
    /// where columns are given, else by azimuth; `None` outside the map.
    #[inline(always)]
    pub fn column(&self, i: usize, code: i32, spec: &PgmSpec) -> Option<usize> {
        match (self.columns, code) {
            (Some(given), _) => Some(given[i] as usize).filter(|&c| c < spec.cols),
            (None, OUTSIDE) => None,
            (None, BORDER) => spec.column_rotated(&self.base[i], self.rotate),
            (None, c) => Some(c as usize),
        }
    }
}

/// [`PgmSpec`]'s column rule with its constants computed once.
#[derive(Debug, Clone, Copy)]
pub struct Columns<'a> {
    spec: &'a PgmSpec,
    half: f32,
    inv_step: f32,
    cols_f: f32,
    cols_i: i32,
    margin: f32,
}

/// Column code of a point outside the map ([`Columns::code`]).
pub const OUTSIDE: i32 = -1;
/// Column code of a point near a column border, whose column the definition decides.
pub const BORDER: i32 = -2;

impl Columns<'_> {
    /// The column of `p` rotated by `rotate` ([`PgmSpec::column_rotated`]), computed in single
    /// precision with [`atan2_fast`]; within [`PgmSpec::border_margin`] of a column border,
    /// where that could disagree with the definition, the double-precision definition decides.
    /// The result is always the definition's.
    #[inline(always)]
    pub fn fast(&self, p: &Point3, rotate: f64) -> Option<usize> {
        match self.code(p, rotate as f32) {
            OUTSIDE => None,
            BORDER => self.spec.column_rotated(p, rotate),
            c => Some(c as usize),
        }
    }

    /// [`Columns::fast`] without its fallback, branch-free so that the compiler vectorises a
    /// loop of it: the column, or [`OUTSIDE`], or [`BORDER`] where the definition must decide
    /// (`rotate` is the rotation in single precision).
    #[inline(always)]
    pub fn code(&self, p: &Point3, rotate: f32) -> i32 {
        use std::f32::consts::{PI, TAU};
        let y = atan2_fast(p.y, p.x) + rotate;
        // Wrapped into (-pi, pi]; the wrap falls on a column border of a full map (checked).
        let y = y - TAU * ((y > PI) as i32 as f32) + TAU * ((y <= -PI) as i32 as f32);
        // Clamped a few columns beyond the map (max/min also turn a NaN into -4), so that the
        // conversion below is in range.
        let t = ((self.half - y) * self.inv_step)
            .max(-4.0)
            .min(self.cols_f + 4.0);
        // SAFETY: `t` is finite and within [-4, cols + 4], cols <= 65536: it fits an i32.
        let ti: i32 = unsafe { t.to_int_unchecked() };
        let c = ti - ((ti as f32) > t) as i32;
        let frac = t - c as f32;
        // `|`, not `||`: no branch, so the loop vectorises.
        let border = (frac < self.margin) | (frac > 1.0 - self.margin);
        let outside = (c < 0) | (c >= self.cols_i);
        let c = if outside { OUTSIDE } else { c };
        if border {
            BORDER
        } else {
            c
        }
    }
}

/// The largest difference between [`atan2_fast`] and the double-precision `atan2` of the same
/// (finite) arguments, radians; a bound with a margin over what the test measures (about 4e-7).
pub const ATAN2_FAST_MAX_ERROR: f64 = 2e-6;

/// `atan2(y, x)` in single precision, several times cheaper than libm's: Cephes' `atanf`
/// (reduction to |z| <= tan(pi/8), a degree-9 odd polynomial), then the quadrant. Within
/// [`ATAN2_FAST_MAX_ERROR`] of the true angle (tested on a million points and on the axes);
/// 0 at the origin, like `atan2(0, 0)`.
#[inline(always)]
pub fn atan2_fast(y: f32, x: f32) -> f32 {
    use std::f32::consts::{FRAC_PI_2, FRAC_PI_4, PI};
    // Written as selects, not branches: the octant of a scan's points is random, and branches
    // on it would be mispredicted half of the time.
    let (ax, ay) = (x.abs(), y.abs());
    let (num, den) = (ax.min(ay), ax.max(ay));
    // 0 at the origin (and pi for x = -0.0 exactly, where the column check defers to the
    // definition anyway: such a point lies on a column border).
    // Above tan(pi/8), the argument moves to (z - 1) / (z + 1) about pi/4: one division for
    // either, `(num - den) / (num + den)`.
    let big = num > 0.414_213_56 * den;
    let (n, d) = if big {
        (num - den, num + den)
    } else {
        (num, den)
    };
    let z = if d > 0.0 { n / d } else { 0.0 }; // in [-0.42, 0.42]
    let base = if big { FRAC_PI_4 } else { 0.0 };
    let zz = z * z;
    let a = base
        + ((((8.053_744_5e-2 * zz - 1.387_768_6e-1) * zz + 1.997_771_1e-1) * zz - 3.333_295e-1)
            * zz
            * z
            + z);
    let a = if ay > ax { FRAC_PI_2 - a } else { a };
    let a = if x < 0.0 { PI - a } else { a };
    a.copysign(y)
}

/// `yaw + rotate` wrapped into `(-pi, pi]`; `yaw` itself when `rotate` is 0 (so that the
/// unrotated column is the definition, bit for bit).
#[inline(always)]
fn rotated_yaw(yaw: f64, rotate: f64) -> f64 {
    use std::f64::consts::{PI, TAU};
    if rotate == 0.0 {
        return yaw;
    }
    let y = yaw + rotate;
    if y > PI {
        y - TAU
    } else if y <= -PI {
        y + TAU
    } else {
        y
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::Degrees;

    #[test]
    fn fast_column_is_the_definition() {
        let mut state = 12345u64;
        for spec in [
            PgmSpec::default(),
            PgmSpec {
                fov: Degrees(360.0),
                cols: 2048,
                ..Default::default()
            },
            // Narrow columns: a wide border margin, many points take the definition.
            PgmSpec {
                fov: Degrees(360.0),
                cols: 65536,
                ..Default::default()
            },
            PgmSpec {
                fov: Degrees(1.0),
                cols: 4096,
                ..Default::default()
            },
        ] {
            for _ in 0..200_000 {
                let mut r = || {
                    (crate::plan::split::splitmix64(&mut state) as f64 / u64::MAX as f64 - 0.5)
                        as f32
                };
                let p = Point3::new(r() * 160.0, r() * 160.0, r());
                assert_eq!(spec.column_fast(&p), spec.column(&p), "{p:?}");
            }
            // Exactly on borders and axes.
            for k in 0..=spec.cols {
                let a = spec.fov.to_radians() / 2.0
                    - k as f64 * spec.fov.to_radians() / spec.cols as f64;
                let p = Point3::new((10.0 * a.cos()) as f32, (10.0 * a.sin()) as f32, 0.0);
                assert_eq!(spec.column_fast(&p), spec.column(&p), "border {k}");
                // Just inside and outside the margin, on both sides, at several ranges:
                // where the fast rule decides alone, it is closest to being wrong.
                let step = spec.fov.to_radians() / spec.cols as f64;
                for off in [0.9, 1.1, 1.5, 3.0] {
                    for side in [-1.0, 1.0] {
                        let b = a + side * off * spec.border_margin() * step;
                        for r in [0.5, 10.0, 120.0] {
                            let p = Point3::new((r * b.cos()) as f32, (r * b.sin()) as f32, 0.0);
                            assert_eq!(spec.column_fast(&p), spec.column(&p), "near {k}: {p:?}");
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn fast_atan2_is_within_its_bound() {
        let mut state = 99u64;
        let mut worst = 0.0f64;
        let mut check = |y: f32, x: f32| {
            let e = (atan2_fast(y, x) as f64 - (y as f64).atan2(x as f64)).abs();
            assert!(e <= ATAN2_FAST_MAX_ERROR, "atan2({y}, {x}): error {e}");
            worst = worst.max(e);
        };
        for _ in 0..1_000_000 {
            let mut r = || {
                (crate::plan::split::splitmix64(&mut state) as f64 / u64::MAX as f64 - 0.5) as f32
            };
            let scale = 10f32.powi((r() * 8.0) as i32);
            check(r() * scale, r() * scale);
        }
        for (y, x) in [
            (0.0, 1.0),
            (1.0, 0.0),
            (0.0, -1.0),
            (-1.0, 0.0),
            (1.0, 1.0),
            (-1.0, -1.0),
        ] {
            check(y, x);
        }
        assert!(worst < ATAN2_FAST_MAX_ERROR / 2.0, "{worst}");
        assert_eq!(atan2_fast(0.0, 0.0), 0.0);
        assert_eq!(atan2_fast(0.0, -2.0), std::f32::consts::PI);
    }
}
