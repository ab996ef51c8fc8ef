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
        // Saturates past 255 rings; such a scan is rejected below anyway.
        ring[i] = current.min(u8::MAX as usize) as u8;
        prev = Some(p);
    }
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
