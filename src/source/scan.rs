//! The scan every reader gives, whatever the dataset or sensor: [`Scan`], and the rule by which
//! a reader drops the points that cannot be real returns ([`DropRule`]).
//!
//! A scan keeps its points in file order; the original index of every dropped point is kept,
//! so that per-point outputs (`.label` files, predictions) still line up with the file.

use std::ops::RangeInclusive;
use std::path::Path;

use crate::error::Result;
use crate::geom::{Point3, MAX_RANGE_M};

/// Which points a reader drops (and counts): always a non-finite coordinate or intensity and a
/// range beyond [`MAX_RANGE_M`] (a point at 1e30 m would make an infinite range and poison every
/// statistic); and, for a source whose intensity has a known range, a value outside it.
#[derive(Debug, Clone, PartialEq)]
pub struct DropRule {
    /// The intensities a real return has (`None`: any finite value, as stored).
    pub intensity: Option<RangeInclusive<f32>>,
}

impl DropRule {
    /// Any finite intensity (PCD, bags, nuScenes, a declared `.bin` layout: as stored).
    pub const ANY: DropRule = DropRule { intensity: None };

    /// Whether an intensity value is one a real return of this source has: finite (always), and
    /// in the range where there is one.
    #[inline(always)]
    pub fn holds(&self, intensity: f32) -> bool {
        let finite = intensity.is_finite();
        match &self.intensity {
            Some(r) => finite & (intensity >= *r.start()) & (intensity <= *r.end()),
            None => finite,
        }
    }
}

/// One scan as read: the kept points in file order, their intensity as stored, the beam id of
/// every kept point where the data has one, and the file indices of the dropped points.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Scan {
    /// Kept points (finite, within [`MAX_RANGE_M`]) in file order, the file's frame, metres.
    pub points: Vec<Point3>,
    /// Intensity of each kept point as stored (KITTI's reflectance 0-1; 0 where the data has
    /// none).
    pub intensity: Vec<f32>,
    /// Whether the data has an intensity field.
    pub has_intensity: bool,
    /// Beam id of each kept point (the ring / channel / laser id field), where the data has one.
    pub ring: Option<Vec<u16>>,
    /// Points in the file, kept or not.
    pub file_len: usize,
    /// File indices of the dropped points ([`DropRule`]), ascending.
    pub dropped: Vec<u32>,
    /// How many of `dropped` were finite but beyond [`MAX_RANGE_M`] or with an intensity the
    /// rule refuses.
    pub dropped_out_of_range: usize,
    /// Bytes after the declared points, left unread (a `binary` PCD some exporters pad).
    pub trailing_bytes: usize,
}

impl Scan {
    pub(crate) fn with_capacity(n: usize, intensity: bool, ring: bool) -> Scan {
        Scan {
            points: Vec::with_capacity(n),
            intensity: Vec::with_capacity(n),
            has_intensity: intensity,
            ring: ring.then(|| Vec::with_capacity(n)),
            ..Default::default()
        }
    }

    /// Reads a scan file by its name (KITTI's `.bin`, a `.pcd`, nuScenes' `.pcd.bin`:
    /// [`super::read_file`] without a declared layout).
    pub fn read(path: &Path) -> Result<Scan> {
        super::read_file(path, None)
    }

    /// Number of kept points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Whether no point was kept.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Drops the points now beyond [`MAX_RANGE_M`] (after a move into the sensor's frame: a
    /// `--sensor-pose` far from the points carries them past the limit), with their intensity
    /// and ring values, counting them in `dropped_out_of_range`; returns how many. In f64, as
    /// the readers' test.
    pub fn drop_beyond_range(&mut self) -> usize {
        let max2 = (MAX_RANGE_M as f64).powi(2);
        let far = |p: &Point3| {
            let (x, y, z) = (p.x as f64, p.y as f64, p.z as f64);
            // A point made non-finite by the move is dropped too.
            let r2 = x * x + y * y + z * z;
            r2.is_nan() || r2 > max2
        };
        if !self.points.iter().any(far) {
            return 0;
        }
        let keep: Vec<bool> = self.points.iter().map(|p| !far(p)).collect();
        let gone: Vec<u32> = (self.file_indices().into_iter().zip(&keep))
            .filter(|(_, k)| !**k)
            .map(|(i, _)| i)
            .collect();
        retain_flagged(&mut self.points, &keep);
        retain_flagged(&mut self.intensity, &keep);
        if let Some(r) = &mut self.ring {
            retain_flagged(r, &keep);
        }
        self.dropped.extend_from_slice(&gone);
        self.dropped.sort_unstable();
        self.dropped_out_of_range += gone.len();
        gone.len()
    }

    /// The file index of each kept point.
    pub fn file_indices(&self) -> Vec<u32> {
        let mut dropped = self.dropped.iter().peekable();
        (0..self.file_len as u32)
            .filter(|i| {
                let is_dropped = dropped.peek() == Some(&i);
                if is_dropped {
                    dropped.next();
                }
                !is_dropped
            })
            .collect()
    }

    /// Spreads a per-point value over the file's order, putting `fill` at dropped points.
    pub fn to_file_order<T: Copy>(&self, values: &[T], fill: T) -> Vec<T> {
        debug_assert_eq!(values.len(), self.points.len());
        if self.dropped.is_empty() {
            return values.to_vec();
        }
        let mut out = Vec::with_capacity(self.file_len);
        let mut kept = values.iter();
        let mut dropped = self.dropped.iter().peekable();
        for i in 0..self.file_len as u32 {
            if dropped.peek() == Some(&&i) {
                dropped.next();
                out.push(fill);
            } else {
                out.push(*kept.next().expect("kept + dropped = file_len"));
            }
        }
        out
    }
}

/// Keeps the values of `v` whose flag in `keep` is set.
fn retain_flagged<T>(v: &mut Vec<T>, keep: &[bool]) {
    let mut k = keep.iter();
    v.retain(|_| *k.next().expect("one flag a value"));
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn file_order_and_indices_skip_the_dropped() {
        let s = Scan {
            points: vec![Point3::new(1.0, 2.0, 3.0), Point3::new(4.0, 5.0, 6.0)],
            intensity: vec![0.5, 0.25],
            file_len: 3,
            dropped: vec![1],
            ..Default::default()
        };
        assert_eq!(s.to_file_order(&[7u32, 8], 0), vec![7, 0, 8]);
        assert_eq!(s.file_indices(), vec![0, 2]);
    }

    #[test]
    fn points_moved_beyond_the_range_go_with_their_values() {
        let mut s = Scan {
            points: vec![Point3::new(1.0, 0.0, 0.0), Point3::new(600.0, 0.0, 0.0)],
            intensity: vec![0.5, 0.25],
            ring: Some(vec![3, 4]),
            file_len: 3,
            dropped: vec![0],
            ..Default::default()
        };
        assert_eq!(s.drop_beyond_range(), 1);
        assert_eq!(
            (s.dropped.as_slice(), s.dropped_out_of_range),
            ([0, 2].as_slice(), 1)
        );
        assert_eq!((s.intensity, s.ring), (vec![0.5], Some(vec![3])));
    }

    #[test]
    fn a_rule_with_a_range_refuses_what_lies_outside_and_any_refuses_only_non_finite() {
        let kitti = DropRule {
            intensity: Some(0.0..=1.0),
        };
        for (v, k, any) in [
            (0.0, true, true),
            (1.0, true, true),
            (1.5, false, true),
            (-0.1, false, true),
            (f32::NAN, false, false),
            (f32::INFINITY, false, false),
        ] {
            assert_eq!((kitti.holds(v), DropRule::ANY.holds(v)), (k, any), "{v}");
        }
        // A range that reaches infinity still refuses what is not finite.
        let open = DropRule {
            intensity: Some(f32::NEG_INFINITY..=f32::INFINITY),
        };
        assert!(!open.holds(f32::INFINITY) && !open.holds(f32::NAN) && open.holds(-1e30));
    }
}
