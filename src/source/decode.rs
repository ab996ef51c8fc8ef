//! Decoding point records into a [`Scan`]: column by column (a loop per scalar type and byte
//! order), then the points to drop ([`DropRule`]: non-finite, beyond [`MAX_RANGE_M`], an
//! intensity the source's rule refuses) found branch-free, and the kept points gathered. The
//! commonest record, x, y, z, intensity as little-endian float32 (KITTI's), goes through one
//! branch-free pass instead, when none of its points is dropped.

use std::path::Path;

use super::fields::{FieldType, PointLayout};
use super::scan::{DropRule, Scan};
use crate::error::{Error, Result};
use crate::geom::{Point3, MAX_RANGE_M};

impl PointLayout {
    /// Decodes `n` records laid end to end in `data` (record `i` at `i * step`), as a scan of
    /// `path`, with [`DropRule::ANY`]: points with a non-finite value or beyond [`MAX_RANGE_M`]
    /// are dropped and counted (a non-dense cloud's NaN points).
    pub fn decode(&self, data: &[u8], n: usize, path: &Path) -> Result<Scan> {
        self.decode_with(data, n, path, &DropRule::ANY)
    }

    /// [`PointLayout::decode`] with the drop rule of the source.
    pub fn decode_with(&self, data: &[u8], n: usize, path: &Path, rule: &DropRule) -> Result<Scan> {
        let need = n.checked_mul(self.step).filter(|&b| b <= data.len());
        if need.is_none() {
            return Err(Error::Length {
                path: path.into(),
                what: format!("the data of {n} points of {} bytes", self.step),
                found: data.len(),
                expected: n.saturating_mul(self.step),
                unit: "bytes",
            });
        }
        let roles = self.roles(path)?;
        let recs = &data[..n * self.step];
        if self.is_xyzi_f32_le(&roles) {
            if let Some(scan) = xyzi_all_kept(recs, rule) {
                return Ok(scan);
            }
        }
        let be = self.big_endian;
        // Column by column, each a loop of one type (vectorisable), then one pass that keeps the
        // finite points within range.
        let points = xyz_points(recs, self.step, roles.xyz, be);
        let intensity = roles
            .intensity
            .map(|r| column(recs, self.step, r, be, |v| v as f32));
        let mut out = Scan::with_capacity(0, intensity.is_some(), false);
        (out.dropped, out.dropped_out_of_range) = dropped(&points, intensity.as_deref(), rule);
        out.points = keep(&out.dropped, points);
        out.intensity = keep(&out.dropped, intensity.unwrap_or_else(|| vec![0.0; n]));
        if let Some(r) = roles.ring {
            // u8 and u16 ids are beam ids as they are; other types are checked point by point.
            out.ring = Some(if matches!(r.1, FieldType::U8 | FieldType::U16) {
                keep(&out.dropped, column(recs, self.step, r, be, |v| v as u16))
            } else {
                let v = column(recs, self.step, r, be, |v| v);
                kept_rings(&v, &out.dropped, path)?
            });
        }
        out.file_len = n;
        Ok(out)
    }
}

impl Scan {
    /// A scan of points held in memory (a caller's arrays), each value as a file would store
    /// it: the readers' drop rule ([`DropRule::ANY`]) applied, as to a PCD's points.
    pub fn of_columns(points: Vec<Point3>, intensity: Vec<f32>, ring: Option<Vec<u16>>) -> Scan {
        debug_assert_eq!(points.len(), intensity.len());
        let n = points.len();
        let mut out = Scan::with_capacity(0, true, false);
        (out.dropped, out.dropped_out_of_range) =
            dropped(&points, Some(&intensity), &DropRule::ANY);
        out.points = keep(&out.dropped, points);
        out.intensity = keep(&out.dropped, intensity);
        out.ring = ring.map(|r| keep(&out.dropped, r));
        out.file_len = n;
        out
    }
}

impl PointLayout {
    /// Whether the records are x, y, z, intensity as packed little-endian float32 and nothing
    /// else (KITTI's `.bin`, and any declared layout of the same bytes).
    fn is_xyzi_f32_le(&self, roles: &super::fields::Roles) -> bool {
        let f = FieldType::F32;
        self.step == 16
            && !self.big_endian
            && roles.xyz == [(0, f), (4, f), (8, f)]
            && roles.intensity == Some((12, f))
            && roles.ring.is_none()
    }
}

/// The scan of x, y, z, intensity float32 records when none of them is dropped (the common
/// case): one branch-free pass over the points, each slot written once, that only notes a bad
/// point (pushing point by point with a branch each was a tenth of a SemanticKITTI frame's
/// conversion); `None` when one is, for the column decoder to drop it.
fn xyzi_all_kept(recs: &[u8], rule: &DropRule) -> Option<Scan> {
    let (records, rest) = recs.as_chunks::<16>();
    debug_assert!(rest.is_empty(), "whole points");
    let n = records.len();
    let max2 = (MAX_RANGE_M as f64).powi(2);
    let (points, intensity, bad) = crate::simd::with_simd(
        #[inline(always)]
        move || {
            let (mut points, mut intensity) = (Vec::with_capacity(n), Vec::with_capacity(n));
            let slots = (points.spare_capacity_mut()[..n].iter_mut())
                .zip(&mut intensity.spare_capacity_mut()[..n]);
            let mut bad = false;
            for ((p, v), b) in slots.zip(records) {
                let f = |k: usize| f32::from_le_bytes([b[k], b[k + 1], b[k + 2], b[k + 3]]);
                let (x, y, z, i) = (f(0), f(4), f(8), f(12));
                // The column decoder's tests, `&` for `&&`: no branch. In f64, so that a huge
                // coordinate cannot overflow the test itself (nor NaN pass it).
                let (xd, yd, zd) = (x as f64, y as f64, z as f64);
                let near = xd * xd + yd * yd + zd * zd <= max2;
                bad |= !(near & rule.holds(i));
                p.write(Point3::new(x, y, z));
                v.write(i);
            }
            // SAFETY: the loop wrote the first `n` slots of both.
            unsafe {
                points.set_len(n);
                intensity.set_len(n);
            }
            (points, intensity, bad)
        },
    );
    (!bad).then_some(Scan {
        points,
        intensity,
        has_intensity: true,
        file_len: n,
        ..Default::default()
    })
}

/// The points of the records: float32 coordinates read directly (the common case), others
/// column by column.
fn xyz_points(recs: &[u8], step: usize, xyz: [(usize, FieldType); 3], be: bool) -> Vec<Point3> {
    let [(ox, tx), (oy, ty), (oz, tz)] = xyz;
    if [tx, ty, tz] == [FieldType::F32; 3] {
        // The byte order decided once, not per value (it cost a select and a swap a value).
        return if be {
            xyz_f32::<true>(recs, step, [ox, oy, oz])
        } else {
            xyz_f32::<false>(recs, step, [ox, oy, oz])
        };
    }
    let [x, y, z] = xyz.map(|r| column(recs, step, r, be, |v| v as f32));
    (0..x.len())
        .map(|i| Point3::new(x[i], y[i], z[i]))
        .collect()
}

/// Float32 coordinates at byte offsets `off` of each record of `step` bytes, big-endian if `BE`.
fn xyz_f32<const BE: bool>(recs: &[u8], step: usize, off: [usize; 3]) -> Vec<Point3> {
    assert!(
        off.iter().all(|&o| o + 4 <= step),
        "coordinates inside the record"
    );
    let word = |b: &[u8]| -> f32 {
        let b: [u8; 4] = b.try_into().expect("four bytes");
        if BE {
            f32::from_be_bytes(b)
        } else {
            f32::from_le_bytes(b)
        }
    };
    let [ox, oy, oz] = off;
    if oy == ox + 4 && oz == ox + 8 {
        // x, y, z side by side (nearly every driver): one 12-byte read and one bounds test.
        return recs
            .chunks_exact(step)
            .map(|r| {
                let xyz: &[u8; 12] = r[ox..ox + 12].try_into().expect("inside the record");
                Point3::new(word(&xyz[..4]), word(&xyz[4..8]), word(&xyz[8..]))
            })
            .collect();
    }
    let f = |r: &[u8], o: usize| word(&r[o..o + 4]);
    recs.chunks_exact(step)
        .map(|r| Point3::new(f(r, ox), f(r, oy), f(r, oz)))
        .collect()
}

/// The file indices of the points to drop (a non-finite coordinate or intensity, beyond
/// [`MAX_RANGE_M`], or an intensity `rule` refuses), ascending, and how many of them are finite
/// but too far or refused.
fn dropped(points: &[Point3], intensity: Option<&[f32]>, rule: &DropRule) -> (Vec<u32>, usize) {
    if surely_none_dropped(points, intensity, rule) {
        return (Vec::new(), 0);
    }
    let far2 = (MAX_RANGE_M as f64).powi(2);
    let r2 = |p: &Point3| (p.x as f64).powi(2) + (p.y as f64).powi(2) + (p.z as f64).powi(2);
    let inten_ok = |i: usize| intensity.is_none_or(|v| v[i].is_finite());
    // Counted branch-free first (usually none is dropped): a NaN coordinate gives a NaN range,
    // an infinite one an infinite range, neither within MAX_RANGE_M.
    let bad = match intensity {
        Some(v) => points
            .iter()
            .zip(v)
            .map(|(p, &i)| (!((r2(p) <= far2) & rule.holds(i))) as usize)
            .sum::<usize>(),
        None => points
            .iter()
            .map(|p| (r2(p) > far2 || r2(p).is_nan()) as usize)
            .sum(),
    };
    let mut out = (Vec::with_capacity(bad), 0);
    if bad == 0 {
        return out;
    }
    for (i, p) in points.iter().enumerate() {
        let finite = p.x.is_finite() && p.y.is_finite() && p.z.is_finite() && inten_ok(i);
        let refused = intensity.is_some_and(|v| !rule.holds(v[i]));
        let far = finite && (r2(p) > far2 || refused);
        if !finite || far {
            out.0.push(i as u32);
            out.1 += far as usize;
        }
    }
    out
}

/// Whether every point is finite and surely within [`MAX_RANGE_M`] (and every intensity held by
/// `rule`, finite among it), decided in single precision: twice the lanes of the exact
/// double-precision test, which runs only when this one cannot tell. Its squared range is within a few units in the
/// last place of the exact one, far inside the 0.1% margin; a NaN, or a square that overflows to
/// infinity, fails the comparison.
fn surely_none_dropped(points: &[Point3], intensity: Option<&[f32]>, rule: &DropRule) -> bool {
    let near2 = MAX_RANGE_M * MAX_RANGE_M * 0.999;
    // Not "within": a NaN fails it.
    let near = |p: &Point3| (p.x * p.x + p.y * p.y + p.z * p.z <= near2) as usize;
    let held = |i: &f32| rule.holds(*i) as usize;
    let finite = |v: &[f32]| v.iter().map(held).sum::<usize>() == v.len();
    points.iter().map(near).sum::<usize>() == points.len() && intensity.is_none_or(finite)
}

/// One field of `n` records as `T`: a loop per scalar type and byte order; each value goes
/// through f64 (exact for every type but 64-bit integers, as the per-point reader does).
fn column<T>(
    recs: &[u8],
    step: usize,
    (off, ty): (usize, FieldType),
    big_endian: bool,
    to: impl Fn(f64) -> T,
) -> Vec<T> {
    macro_rules! col {
        ($t:ty) => {{
            const N: usize = std::mem::size_of::<$t>();
            let get = |r: &[u8]| -> [u8; N] { r[off..off + N].try_into().expect("in the record") };
            if big_endian {
                recs.chunks_exact(step)
                    .map(|r| to(<$t>::from_be_bytes(get(r)) as f64))
                    .collect()
            } else {
                recs.chunks_exact(step)
                    .map(|r| to(<$t>::from_le_bytes(get(r)) as f64))
                    .collect()
            }
        }};
    }
    match ty {
        FieldType::I8 => col!(i8),
        FieldType::U8 => col!(u8),
        FieldType::I16 => col!(i16),
        FieldType::U16 => col!(u16),
        FieldType::I32 => col!(i32),
        FieldType::U32 => col!(u32),
        FieldType::I64 => col!(i64),
        FieldType::U64 => col!(u64),
        FieldType::F32 => col!(f32),
        FieldType::F64 => col!(f64),
    }
}

/// The values of `v` but those at the ascending indices `dropped`: `v` itself when none is.
fn keep<T: Copy>(dropped: &[u32], v: Vec<T>) -> Vec<T> {
    if dropped.is_empty() {
        return v;
    }
    kept(dropped, v.len(), |i| v[i])
}

/// `f(i)` for every `i` in `0..n` but the ascending `dropped`.
fn kept<T>(dropped: &[u32], n: usize, f: impl Fn(usize) -> T) -> Vec<T> {
    if dropped.is_empty() {
        return (0..n).map(f).collect();
    }
    let mut out = Vec::with_capacity(n - dropped.len());
    let mut skip = dropped.iter().copied().peekable();
    for i in 0..n {
        if skip.next_if_eq(&(i as u32)).is_none() {
            out.push(f(i));
        }
    }
    out
}

/// The beam ids of the kept points (all but the ascending file indices `dropped`); a value that
/// is not a whole number in 0-65535 is an error naming `path` and the point.
fn kept_rings(ring: &[f64], dropped: &[u32], path: &Path) -> Result<Vec<u16>> {
    // A whole number in 0-65535, and only such a number, survives the (saturating) round trip
    // through u16; checked branch-free over all points, then the first bad one is looked for.
    let whole = |r: f64| (r as u16) as f64 == r;
    let out = kept(dropped, ring.len(), |i| ring[i]);
    if let Some(bad) = crate::simd::first_where(&out, |&r| !whole(r)) {
        let i = kept_index(dropped, bad);
        return Err(Error::format(
            path,
            format!(
                "point {i} has beam id (ring) {}, not a whole number in 0-65535",
                out[bad]
            ),
        ));
    }
    Ok(out.into_iter().map(|r| r as u16).collect())
}

/// The file index of the `k`-th kept point.
fn kept_index(dropped: &[u32], k: usize) -> usize {
    let mut i = k;
    for &d in dropped {
        if d as usize <= i {
            i += 1;
        } else {
            break;
        }
    }
    i
}

#[cfg(test)]
mod tests {
    #[test]
    fn points_in_memory_are_dropped_as_a_file_s_are() {
        let pts = vec![
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(f32::NAN, 0.0, 0.0),
            Point3::new(MAX_RANGE_M * 2.0, 0.0, 0.0),
            Point3::new(0.0, 2.0, 0.0),
        ];
        let s = Scan::of_columns(
            pts,
            vec![0.5, 0.5, 0.5, f32::INFINITY],
            Some(vec![3, 4, 5, 6]),
        );
        assert_eq!(s.points, [Point3::new(1.0, 0.0, 0.0)]);
        assert_eq!(s.intensity, [0.5]);
        assert_eq!(s.ring.as_deref(), Some(&[3u16][..]));
        assert_eq!((s.file_len, s.dropped.as_slice()), (4, &[1u32, 2, 3][..]));
        assert_eq!(s.dropped_out_of_range, 1);
    }

    use super::*;

    fn records(points: &[[f32; 4]]) -> Vec<u8> {
        points
            .iter()
            .flatten()
            .flat_map(|v| v.to_le_bytes())
            .collect()
    }

    #[test]
    fn drops_bad_points_and_names_a_bad_ring_by_its_file_index() {
        let layout = PointLayout::declared("x,y,z,ring:f32").unwrap();
        let p = Path::new("scan.bin");
        let data = records(&[
            [f32::NAN, 0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0, 1.0],
            [1e6, 0.0, 0.0, 3.0],
            [2.0, 0.0, 0.0, 2.0],
        ]);
        let c = layout.decode(&data, 4, p).unwrap();
        assert_eq!(c.dropped, [0, 2]);
        assert_eq!(c.dropped_out_of_range, 1);
        assert_eq!(c.ring, Some(vec![1, 2]));
        assert_eq!(
            c.points,
            [Point3::new(1.0, 0.0, 0.0), Point3::new(2.0, 0.0, 0.0)]
        );
        let data = records(&[
            [f32::NAN, 0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0, 1.0],
            [2.0, 0.0, 0.0, 2.5],
        ]);
        let e = layout.decode(&data, 3, p).unwrap_err().to_string();
        assert!(e.contains("point 2 has beam id (ring) 2.5"), "{e}");
        let data = records(&[[1.0, 0.0, 0.0, -1.0]]);
        assert!(layout.decode(&data, 1, p).is_err());
        let data = records(&[[1.0, 0.0, 0.0, 65536.0]]);
        assert!(layout.decode(&data, 1, p).is_err());
    }

    #[test]
    fn the_single_precision_pretest_never_decides_otherwise_than_the_exact_one() {
        let p = |x: f32, y: f32, z: f32| Point3::new(x, y, z);
        let cases = [
            (vec![p(1.0, 2.0, 3.0), p(-300.0, 350.0, 20.0)], true),
            // Within 0.1% of the limit the exact test decides: kept at 500 m exactly.
            (vec![p(500.0, 0.0, 0.0), p(0.0, -499.9, 0.0)], false),
            (vec![p(500.001, 0.0, 0.0)], false),
            (vec![p(f32::INFINITY, 0.0, 0.0)], false),
            (vec![p(1e30, 0.0, 0.0)], false),
            (vec![p(0.0, f32::NAN, 0.0)], false),
        ];
        for (points, surely) in cases {
            assert_eq!(
                surely_none_dropped(&points, None, &DropRule::ANY),
                surely,
                "{points:?}"
            );
            let exact = dropped(&points, None, &DropRule::ANY).0.is_empty();
            assert!(!surely || exact, "{points:?}");
        }
        let at_limit = [p(500.0, 0.0, 0.0), p(300.0, 400.0, 0.0)];
        assert_eq!(dropped(&at_limit, None, &DropRule::ANY), (vec![], 0));
        let far = [p(1.0, 0.0, 0.0), p(300.0, 400.001, 0.0)];
        assert_eq!(dropped(&far, None, &DropRule::ANY), (vec![1], 1));
        let fine = [p(1.0, 0.0, 0.0)];
        assert!(surely_none_dropped(&fine, Some(&[7.0]), &DropRule::ANY));
        assert!(!surely_none_dropped(
            &fine,
            Some(&[f32::NAN]),
            &DropRule::ANY
        ));
        assert_eq!(
            dropped(&fine, Some(&[f32::INFINITY]), &DropRule::ANY),
            (vec![0], 0)
        );
    }

    /// The one-pass kernel and the column decoder give the same scan when none is dropped (a
    /// real scan; the limits themselves), and a rule's refused intensity sends the scan to the
    /// column decoder.
    #[test]
    fn the_one_pass_kernel_equals_the_column_decoder() {
        let real = std::fs::read(
            Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("fixtures/semantickitti/sequences/00/velodyne/000000.bin"),
        )
        .unwrap();
        let edge = records(&[[MAX_RANGE_M, 0.0, 0.0, 1.0], [0.0, 0.0, -MAX_RANGE_M, 0.0]]);
        // The same bytes as a layout the kernel does not take (a ring field of padding order).
        let other = PointLayout::declared("y,x,z,intensity:f32").unwrap();
        let kitti = DropRule {
            intensity: Some(0.0..=1.0),
        };
        for b in [&real, &edge] {
            let fast = xyzi_all_kept(b, &kitti).expect("all kept");
            let n = b.len() / 16;
            let slow = other.decode_with(b, n, Path::new("x.bin"), &kitti).unwrap();
            let swapped: Vec<Point3> = slow
                .points
                .iter()
                .map(|p| Point3::new(p.y, p.x, p.z))
                .collect();
            assert_eq!((fast.points, &fast.intensity), (swapped, &slow.intensity));
            assert!(slow.dropped.is_empty() && fast.file_len == slow.file_len);
        }
        let mut b = real.clone();
        b[12..16].copy_from_slice(&1.5f32.to_le_bytes());
        assert!(xyzi_all_kept(&b, &kitti).is_none());
        assert!(xyzi_all_kept(&b, &DropRule::ANY).is_some());
    }

    #[test]
    fn kept_index_skips_the_dropped() {
        assert_eq!(kept_index(&[], 3), 3);
        assert_eq!(kept_index(&[0, 1, 5], 0), 2);
        assert_eq!(kept_index(&[0, 1, 5], 3), 6);
        assert_eq!(kept_index(&[4], 3), 3);
    }
}
