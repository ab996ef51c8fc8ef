//! READ: KITTI's velodyne scans (`velodyne_points/data/<frame10>.bin`; SemanticKITTI's and the
//! object set's `velodyne/<frame>.bin`).
//!
//! A scan is a flat array of little-endian float32 quadruples x, y, z, reflectance in the
//! velodyne frame (x forward, y left, z up, metres; reflectance in [0, 1]): the record
//! [`layout`], decoded by the point layout's own decoder ([`PointLayout::decode_with`]) into the
//! neutral [`Scan`]. The order of the points matters: they are stored laser by laser, which is
//! how [`crate::project`] recovers the rows. KITTI's drop rule ([`DROP`]) adds a reflectance
//! outside [`REFLECTANCE_RANGE`] (0..1, as every KITTI scan stores it: 1e30 or -5 is a corrupt
//! record) to what every reader drops.

use std::path::Path;

use crate::error::Result;
use crate::source::scan::{DropRule, Scan};
use crate::source::{bin, FieldType, PointLayout};

/// Bytes of one point in a `.bin` (the step of [`layout`]).
pub const POINT_BYTES: usize = 16;

pub use crate::geom::MAX_RANGE_M;

/// The reflectance a real return has; a point outside it is a corrupt record and is dropped
/// with the far ones (counted in `dropped_out_of_range`).
pub const REFLECTANCE_RANGE: std::ops::RangeInclusive<f32> = 0.0..=1.0;

/// KITTI's drop rule: finite, within [`MAX_RANGE_M`], reflectance in [`REFLECTANCE_RANGE`].
pub const DROP: DropRule = DropRule {
    intensity: Some(REFLECTANCE_RANGE),
};

/// KITTI's record: `x,y,z,intensity:f32`, little-endian ([`POINT_BYTES`] bytes).
pub fn layout() -> PointLayout {
    PointLayout::packed(&[
        ("x", FieldType::F32),
        ("y", FieldType::F32),
        ("z", FieldType::F32),
        ("intensity", FieldType::F32),
    ])
}

/// Decodes a scan from the bytes of a `.bin`; `path` only names the file in errors.
pub fn decode(bytes: &[u8], path: &Path) -> Result<Scan> {
    bin::decode_with(bytes, &layout(), path, &DROP)
}

/// Reads and decodes a KITTI `.bin`.
pub fn read(path: &Path) -> Result<Scan> {
    let bytes = crate::fs::read(path, crate::fs::Limit::Data)?;
    decode(&bytes, path)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::Point3;

    fn bytes(points: &[[f32; 4]]) -> Vec<u8> {
        points
            .iter()
            .flatten()
            .flat_map(|v| v.to_le_bytes())
            .collect()
    }

    /// The record's size stated as a constant is the layout's own.
    #[test]
    fn the_record_is_its_layout() {
        assert_eq!(layout().step, POINT_BYTES);
    }

    #[test]
    fn decodes_and_drops_non_finite() {
        let b = bytes(&[
            [1.0, 2.0, 3.0, 0.5],
            [f32::NAN, 0.0, 0.0, 0.0],
            [4.0, 5.0, 6.0, 0.25],
        ]);
        let s = decode(&b, Path::new("x.bin")).unwrap();
        assert_eq!(s.len(), 2);
        assert_eq!(s.file_len, 3);
        assert_eq!(s.dropped, vec![1]);
        assert_eq!(s.points[1], Point3::new(4.0, 5.0, 6.0));
        assert_eq!(s.to_file_order(&[7u32, 8], 0), vec![7, 0, 8]);
        assert_eq!(s.file_indices(), vec![0, 2]);
    }

    /// Each kind of bad value drops that point alone (a real scan, one record replaced), counted
    /// as out of range when finite; the limits themselves are kept.
    #[test]
    fn each_bad_value_drops_its_point() {
        let real = std::fs::read(
            Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("fixtures/semantickitti/sequences/00/velodyne/000000.bin"),
        )
        .unwrap();
        let edge = bytes(&[[MAX_RANGE_M, 0.0, 0.0, 1.0], [0.0, 0.0, -MAX_RANGE_M, 0.0]]);
        let s = decode(&edge, Path::new("x.bin")).unwrap();
        assert_eq!((s.len(), s.has_intensity), (2, true));
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
            let s = decode(&b, Path::new("x.bin")).unwrap();
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
        let e = decode(&b, Path::new("000042.bin")).unwrap_err().to_string();
        assert!(e.contains("000042.bin") && e.contains("15 bytes"), "{e}");
        let e = decode(&[], Path::new("e.bin")).unwrap_err().to_string();
        assert!(e.contains("empty"), "{e}");
    }
}
