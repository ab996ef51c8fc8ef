//! Where the rows of the map come from: laser rings recovered from the scan order, given, or
//! elevation bins.

use std::borrow::Cow;

use super::{PgmSpec, RowMode, LASERS};
use crate::geom::Point3;

/// Ring index of every point from the scan order, or `None` when the scan does not show exactly
/// [`LASERS`] rings. Returns also the number of rings seen.
///
/// A new ring starts at point `i` when point `i - 1` has `y < 0` and point `i` has `y >= 0`, both
/// in front (`x > 0`): the azimuth crossed the forward direction from negative to non-negative in
/// a small step (a wrap-around at the back is a step of about 360 degrees and never matches).
/// The ring must also have reached the rear half (`x < 0`) since it started, so that jitter of
/// the azimuth around zero does not split a ring.
pub fn rings(points: &[Point3]) -> (Option<Vec<u8>>, usize) {
    crate::simd::with_simd(
        #[inline(always)]
        move || rings_by_flags(points),
    )
}

/// Points per block of [`rings_by_flags`].
const RING_BLOCK: usize = 512;
/// [`rings_by_flags`]'s flag of a point in the rear half.
const REAR: u8 = 1;
/// [`rings_by_flags`]'s flag of a point that crosses the forward direction from its predecessor.
const CROSSING: u8 = 2;

/// [`rings`] in two passes per block of points: the flags of every point (rear half; crossing
/// from its predecessor), vectorised; then the rule, eight points at a time where none of them
/// crosses (the common case: a ring holds thousands of points and starts once).
#[inline(always)]
fn rings_by_flags(points: &[Point3]) -> (Option<Vec<u8>>, usize) {
    let n = points.len();
    let mut ring = Vec::with_capacity(n);
    let mut current = 0usize;
    let mut seen_rear = false;
    let mut flags = [0u8; RING_BLOCK];
    let flag = |q: &Point3, p: &Point3| {
        let crossing = (q.y < 0.0) & (p.y >= 0.0) & (q.x > 0.0) & (p.x > 0.0);
        (p.x < 0.0) as u8 | (crossing as u8 * CROSSING)
    };
    for start in (0..n).step_by(RING_BLOCK) {
        let end = (start + RING_BLOCK).min(n);
        let flags = &mut flags[..end - start];
        // Point 0 has no predecessor: compared with itself, it never crosses.
        let from = start.max(1);
        if start == 0 {
            flags[0] = flag(&points[0], &points[0]);
        }
        let (now, prev) = (&points[from..end], &points[from - 1..end - 1]);
        for ((f, p), q) in flags[from - start..].iter_mut().zip(now).zip(prev) {
            *f = flag(q, p);
        }
        for (k8, eight) in flags.chunks(8).enumerate() {
            let word = eight.iter().fold(0u64, |w, &f| (w << 8) | u64::from(f));
            if word & (0x0101_0101_0101_0101 * u64::from(CROSSING)) == 0 {
                seen_rear |= word != 0;
                continue;
            }
            for (j, &f) in eight.iter().enumerate() {
                if f & CROSSING != 0 && seen_rear {
                    let i = start + k8 * 8 + j;
                    // Saturates past 255 rings; such a scan is rejected below anyway.
                    ring.resize(i, current.min(u8::MAX as usize) as u8);
                    current += 1;
                    seen_rear = false;
                }
                seen_rear |= f & REAR != 0;
            }
        }
    }
    ring.resize(n, current.min(u8::MAX as usize) as u8);
    let found = if points.is_empty() { 0 } else { current + 1 };
    ((found == LASERS).then_some(ring), found)
}

/// Where the rows of a projection come from.
#[derive(Debug, Clone, Copy)]
pub enum Rows<'a> {
    /// The spec's rule: rings recovered from the scan order (elevation binning when the scan does
    /// not show [`LASERS`] rings), or elevation binning.
    FromSpec,
    /// The beam row of every point (0 = the highest beam) of a sensor with this many beams:
    /// KITTI's rings recovered before the points were augmented (with [`LASERS`]), or another
    /// sensor's ([`crate::sensor`]: a ring field or the beam table); elevation binning if the
    /// spec asks for it.
    Beams(&'a [u8], usize),
    /// Elevation binning, counted as a ring fallback (the rings were not recoverable).
    Fallback,
}

/// Where each point's row comes from: its laser ring, or its elevation when `rings` is `None`.
pub(crate) struct RowSource<'a> {
    /// The ring of every point, when rows are rings and the rings are known.
    pub(crate) rings: Option<Cow<'a, [u8]>>,
    /// Rings recovered from the scan order (64 when given; the beams of a sensor model).
    pub(crate) found: usize,
    /// The beams the rings count (rows of the ring map before scaling to the spec's rows).
    pub(crate) beams: usize,
    /// Rows by rings were asked for, and elevation bins stand in.
    pub(crate) fallback: bool,
}

/// Resolves [`Rows`] for `spec`: rings recovered from the scan order, given, or none.
pub(crate) fn row_source<'a>(points: &[Point3], spec: &PgmSpec, rows: Rows<'a>) -> RowSource<'a> {
    let (rings, found, beams, fallback) = match rows {
        _ if spec.row_mode != RowMode::Rings => (None, 0, LASERS, false),
        Rows::FromSpec => {
            let (r, found) = rings(points);
            let fallback = r.is_none();
            (r.map(Cow::Owned), found, LASERS, fallback)
        }
        Rows::Beams(r, beams) => (Some(Cow::Borrowed(r)), beams, beams, false),
        Rows::Fallback => (None, 0, LASERS, true),
    };
    RowSource {
        rings,
        found,
        beams,
        fallback,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::SplitMix;
    use crate::source::Scan;

    /// The rule of [`rings`] point by point, as first written: the reference.
    fn rings_one_by_one(points: &[Point3]) -> (Option<Vec<u8>>, usize) {
        let mut ring = vec![0u8; points.len()];
        let mut current = 0usize;
        let mut seen_rear = false;
        let mut prev: Option<&Point3> = None;
        for (i, p) in points.iter().enumerate() {
            if let Some(q) = prev {
                if seen_rear && q.y < 0.0 && p.y >= 0.0 && q.x > 0.0 && p.x > 0.0 {
                    current += 1;
                    seen_rear = false;
                }
            }
            seen_rear |= p.x < 0.0;
            ring[i] = current.min(u8::MAX as usize) as u8;
            prev = Some(p);
        }
        let found = if points.is_empty() { 0 } else { current + 1 };
        ((found == LASERS).then_some(ring), found)
    }

    /// Every path (AVX-512, AVX2 and baseline, where the CPU has them) equals the reference on
    /// `points` and on every prefix length around the block and chunk edges.
    fn check(points: &[Point3], what: &str) {
        let mut lens: Vec<usize> = vec![0, 1, 2, 7, 8, 9, 511, 512, 513, 1025, points.len()];
        lens.retain(|&l| l <= points.len());
        for l in lens {
            let want = rings_one_by_one(&points[..l]);
            for level in crate::simd::Level::available() {
                let got = crate::simd::at_most(level, || rings(&points[..l]));
                assert_eq!(got, want, "{what}, {l} points, {level:?} path");
            }
        }
    }

    #[test]
    fn flags_equal_the_rule_point_by_point() {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures");
        let raw = "raw/2011_09_26/2011_09_26_drive_0001_sync/velodyne_points/data/0000000000.bin";
        for file in [raw, "semantickitti/sequences/00/velodyne/000000.bin"] {
            let scan = Scan::read(&root.join(file)).unwrap();
            assert_eq!(rings(&scan.points).1, LASERS, "{file}");
            check(&scan.points, file);
            // Reversed: crossings the other way round, no ring structure.
            let reversed: Vec<Point3> = scan.points.iter().rev().copied().collect();
            check(&reversed, &format!("{file} reversed"));
        }
        // Random points in every quadrant (a crossing every few points, many saturating past
        // 255 rings), and points jittering about the forward direction with rare rear ones.
        let mut rng = SplitMix::new(7);
        let mut unit = move || (rng.next_u64() >> 40) as f32 / (1u64 << 24) as f32 - 0.5;
        let random: Vec<Point3> = (0..5000)
            .map(|_| Point3::new(unit(), unit(), unit()))
            .collect();
        check(&random, "random");
        let jitter: Vec<Point3> = (0..5000)
            .map(|i| {
                let x = if i % 97 == 0 { -1.0 } else { 1.0 };
                Point3::new(x, unit() * 0.01, 0.0)
            })
            .collect();
        check(&jitter, "jitter");
    }
}
