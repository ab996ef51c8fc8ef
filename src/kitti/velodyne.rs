//! READ: velodyne scans (`velodyne_points/data/<frame10>.bin`).
//!
//! A scan is a flat array of little-endian float32 quadruples x, y, z, reflectance in the
//! velodyne frame (x forward, y left, z up, metres; reflectance in [0, 1]). The order of the
//! points matters: they are stored laser by laser, which is how [`crate::project`] recovers the
//! rows. Points that cannot be real returns are dropped here and counted: a non-finite
//! coordinate or reflectance, a range beyond [`MAX_RANGE_M`] (the HDL-64E reaches 120 m; a
//! point at 1e30 m would make an infinite range and poison every statistic), or a reflectance
//! outside [`REFLECTANCE_RANGE`] (0..1, as every KITTI scan stores it). Their original
//! indices are kept so that per-point outputs (`.label` files) still line up with the `.bin`.

use std::path::Path;

use crate::error::{Error, Result};
use crate::geom::Point3;

/// Bytes of one point in a `.bin`.
pub const POINT_BYTES: usize = 16;

pub use crate::geom::MAX_RANGE_M;

/// The reflectance a real return has; a point outside it (1e30, -5) is a corrupt record and is
/// dropped with the far ones (counted in `dropped_out_of_range`).
pub const REFLECTANCE_RANGE: std::ops::RangeInclusive<f32> = 0.0..=1.0;

/// One velodyne scan with its non-finite points removed.
#[derive(Debug, Clone, Default)]
pub struct Scan {
    /// Finite points in file order, velodyne frame, metres.
    pub points: Vec<Point3>,
    /// Reflectance of each point of `points`, as stored (0..1).
    pub reflectance: Vec<f32>,
    /// Number of points in the file, finite or not.
    pub file_len: usize,
    /// File indices of the dropped points (non-finite, or beyond [`MAX_RANGE_M`]), ascending.
    pub dropped: Vec<u32>,
    /// How many of `dropped` were finite but beyond [`MAX_RANGE_M`] or with a reflectance
    /// outside [`REFLECTANCE_RANGE`].
    pub dropped_out_of_range: usize,
}

impl Scan {
    /// Decodes a scan from the bytes of a `.bin`; `path` only names the file in errors.
    pub fn from_bytes(bytes: &[u8], path: &Path) -> Result<Scan> {
        if bytes.is_empty() {
            return Err(Error::format(path, "empty velodyne scan (0 bytes)"));
        }
        if !bytes.len().is_multiple_of(POINT_BYTES) {
            return Err(Error::Truncated {
                path: path.into(),
                bytes: bytes.len(),
                record: POINT_BYTES,
                what: "point",
            });
        }
        Ok(Scan::all_valid(bytes).unwrap_or_else(|| Scan::dropping_bad(bytes)))
    }

    /// The scan of `bytes` (whole points), its bad points dropped and counted, a point at a time.
    fn dropping_bad(bytes: &[u8]) -> Scan {
        let n = bytes.len() / POINT_BYTES;
        let mut points = Vec::with_capacity(n);
        let mut reflectance = Vec::with_capacity(n);
        let mut dropped = Vec::new();
        let mut out_of_range = 0;
        for (i, chunk) in bytes.chunks_exact(POINT_BYTES).enumerate() {
            let f =
                |k: usize| f32::from_le_bytes([chunk[k], chunk[k + 1], chunk[k + 2], chunk[k + 3]]);
            let (x, y, z, r) = (f(0), f(4), f(8), f(12));
            let finite = x.is_finite() && y.is_finite() && z.is_finite() && r.is_finite();
            // In f64, so that a huge coordinate cannot overflow the test itself.
            let far = finite
                && ((x as f64).powi(2) + (y as f64).powi(2) + (z as f64).powi(2)
                    > (MAX_RANGE_M as f64).powi(2)
                    || !REFLECTANCE_RANGE.contains(&r));
            if finite && !far {
                points.push(Point3::new(x, y, z));
                reflectance.push(r);
            } else {
                out_of_range += far as usize;
                dropped.push(i as u32);
            }
        }
        Scan {
            points,
            reflectance,
            file_len: n,
            dropped,
            dropped_out_of_range: out_of_range,
        }
    }

    /// The scan of `bytes` (whole points) when every point is valid (the common case): one
    /// branch-free pass over the points, each slot written once, that only notes a bad point
    /// (pushing point by point with a branch each was a tenth of a SemanticKITTI frame's
    /// conversion); `None` when one is bad, for [`Scan::from_bytes`]'s loop to drop it.
    fn all_valid(bytes: &[u8]) -> Option<Scan> {
        let (records, rest) = bytes.as_chunks::<POINT_BYTES>();
        debug_assert!(rest.is_empty(), "whole points");
        let n = records.len();
        let max2 = (MAX_RANGE_M as f64).powi(2);
        let (points, reflectance, bad) = crate::simd::with_simd(
            #[inline(always)]
            move || {
                let (mut points, mut reflectance) = (Vec::with_capacity(n), Vec::with_capacity(n));
                let slots = (points.spare_capacity_mut()[..n].iter_mut())
                    .zip(&mut reflectance.spare_capacity_mut()[..n]);
                let mut bad = false;
                for ((p, r), b) in slots.zip(records) {
                    let f = |k: usize| f32::from_le_bytes([b[k], b[k + 1], b[k + 2], b[k + 3]]);
                    let (x, y, z, i) = (f(0), f(4), f(8), f(12));
                    // The same tests as the loop's, `&` for `&&`: no branch. In f64, so that
                    // a huge coordinate cannot overflow the test itself (nor NaN pass it).
                    let (xd, yd, zd) = (x as f64, y as f64, z as f64);
                    let near = xd * xd + yd * yd + zd * zd <= max2;
                    let reflect =
                        (i >= *REFLECTANCE_RANGE.start()) & (i <= *REFLECTANCE_RANGE.end());
                    bad |= !(near & reflect);
                    p.write(Point3::new(x, y, z));
                    r.write(i);
                }
                // SAFETY: the loop wrote the first `n` slots of both.
                unsafe {
                    points.set_len(n);
                    reflectance.set_len(n);
                }
                (points, reflectance, bad)
            },
        );
        (!bad).then_some(Scan {
            points,
            reflectance,
            file_len: n,
            dropped: Vec::new(),
            dropped_out_of_range: 0,
        })
    }

    /// Reads and decodes a scan file: KITTI's `.bin`, or another sensor's cloud by its name
    /// (`.pcd`, nuScenes' `.pcd.bin`: [`crate::source::read_cloud`]; its ring field is left
    /// out: [`Scan::read_with_rings`] keeps it).
    pub fn read(path: &Path) -> Result<Scan> {
        Ok(Scan::read_with_rings(path, None)?.0)
    }

    /// Reads a scan file with the ring of every kept point, where the file has a ring field:
    /// KITTI's `.bin` (no rings), a `.pcd`, nuScenes' `.pcd.bin`, or a `.bin` of `layout`.
    pub fn read_with_rings(
        path: &Path,
        layout: Option<&crate::source::PointLayout>,
    ) -> Result<(Scan, Option<Vec<u16>>)> {
        if crate::source::is_kitti_bin(path) && layout.is_none() {
            let bytes = crate::fs::read(path, crate::fs::Limit::Data)?;
            return Ok((Scan::from_bytes(&bytes, path)?, None));
        }
        let cloud = crate::source::read_cloud(path, layout)?;
        Ok(Scan::from_cloud(cloud))
    }

    /// A cloud of another sensor as a scan (its intensity as stored in `reflectance`), and its
    /// rings.
    pub fn from_cloud(c: crate::source::LidarCloud) -> (Scan, Option<Vec<u16>>) {
        (
            Scan {
                points: c.points,
                reflectance: c.intensity,
                file_len: c.file_len,
                dropped: c.dropped,
                dropped_out_of_range: c.dropped_out_of_range,
            },
            c.ring,
        )
    }

    /// Drops the points now beyond [`MAX_RANGE_M`] (after a move into the sensor's frame: a
    /// `--sensor-pose` far from the points carries them past the limit), with their ring values,
    /// counting them in `dropped_out_of_range`; returns how many. In f64, as the readers' test.
    pub fn drop_beyond_range(&mut self, rings: Option<&mut Vec<u16>>) -> usize {
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
        retain_flagged(&mut self.reflectance, &keep);
        if let Some(r) = rings {
            retain_flagged(r, &keep);
        }
        self.dropped.extend_from_slice(&gone);
        self.dropped.sort_unstable();
        self.dropped_out_of_range += gone.len();
        gone.len()
    }

    /// Number of finite points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// True when the scan holds no finite point.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
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

    fn bytes(points: &[[f32; 4]]) -> Vec<u8> {
        points
            .iter()
            .flatten()
            .flat_map(|v| v.to_le_bytes())
            .collect()
    }

    #[test]
    fn decodes_and_drops_non_finite() {
        let b = bytes(&[
            [1.0, 2.0, 3.0, 0.5],
            [f32::NAN, 0.0, 0.0, 0.0],
            [4.0, 5.0, 6.0, 0.25],
        ]);
        let s = Scan::from_bytes(&b, Path::new("x.bin")).unwrap();
        assert_eq!(s.len(), 2);
        assert_eq!(s.file_len, 3);
        assert_eq!(s.dropped, vec![1]);
        assert_eq!(s.points[1], Point3::new(4.0, 5.0, 6.0));
        assert_eq!(s.to_file_order(&[7u32, 8], 0), vec![7, 0, 8]);
        assert_eq!(s.file_indices(), vec![0, 2]);
    }

    /// The branch-free pass and the loop that drops bad points give the same scan when all are
    /// valid (a real scan; the limits themselves); each kind of bad value sends the scan to the
    /// loop, which drops that point alone.
    #[test]
    fn the_fast_pass_equals_the_loop() {
        let real = std::fs::read(
            Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("fixtures/semantickitti/sequences/00/velodyne/000000.bin"),
        )
        .unwrap();
        let edge = bytes(&[[MAX_RANGE_M, 0.0, 0.0, 1.0], [0.0, 0.0, -MAX_RANGE_M, 0.0]]);
        for b in [&real, &edge] {
            let fast = Scan::all_valid(b).expect("all valid");
            let slow = Scan::dropping_bad(b);
            assert_eq!(fast.points, slow.points);
            assert_eq!(fast.reflectance, slow.reflectance);
            assert!(slow.dropped.is_empty() && fast.file_len == slow.file_len);
        }
        let bad = [
            [f32::NAN, 0.0, 0.0, 0.5],
            [0.0, f32::INFINITY, 0.0, 0.5],
            [0.0, 0.0, f32::NEG_INFINITY, 0.5],
            [1e30, 0.0, 0.0, 0.5],
            [MAX_RANGE_M, 1.0, 0.0, 0.5],
            [1.0, 0.0, 0.0, f32::NAN],
            [1.0, 0.0, 0.0, -0.1],
            [1.0, 0.0, 0.0, 1.5],
        ];
        for (k, p) in bad.iter().enumerate() {
            let mut b = real.clone();
            let at = 1000 + 37 * k;
            b[at * POINT_BYTES..(at + 1) * POINT_BYTES].copy_from_slice(&bytes(&[*p]));
            assert!(Scan::all_valid(&b).is_none(), "{p:?}");
            let s = Scan::from_bytes(&b, Path::new("x.bin")).unwrap();
            assert_eq!(s.dropped, [at as u32], "{p:?}");
            assert_eq!(
                s.dropped_out_of_range,
                usize::from(p.iter().all(|v| v.is_finite()))
            );
            assert_eq!(s.points.len(), real.len() / POINT_BYTES - 1);
        }
    }

    #[test]
    fn rejects_truncated_and_empty() {
        let mut b = bytes(&[[1.0, 2.0, 3.0, 0.5]]);
        b.pop();
        let e = Scan::from_bytes(&b, Path::new("000042.bin"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("000042.bin") && e.contains("15 bytes"), "{e}");
        let e = Scan::from_bytes(&[], Path::new("e.bin"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("empty"), "{e}");
    }
}
