//! WRITE and read back per-point `.label` files.
//!
//! One little-endian u32 per point of the scan, in the scan's file order: the class id in the low
//! 16 bits, the instance id in the high 16 bits (SemanticKITTI's layout).

//!
//! Per-point predictions use the same files: SemanticKITTI's hold the dataset's raw ids (the
//! class map's `learning_map_inv`; 0, `unlabeled`, where a point has no prediction), KITTI raw's
//! and the object set's hold class ids ([`NOT_PREDICTED`] where a point has none).

use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::format::Durability;
use crate::label::{ClassId, ClassMap};
use crate::source::kitti::{DatasetKind, FrameId};

/// The class written (low 16 bits of a `.label` entry) for a point without a prediction (outside
/// the map), in the class-id layout of KITTI raw and object predictions.
pub const NOT_PREDICTED: u32 = 0xFFFF;

/// The entries of frame `id`'s per-point prediction file for `per_point` (file order; `None`:
/// no prediction): raw ids for SemanticKITTI, class ids otherwise; and how many points have no
/// prediction.
pub fn encode_predictions(
    id: &FrameId,
    per_point: &[Option<ClassId>],
    map: &ClassMap,
) -> (Vec<u32>, u64) {
    let missing = per_point.iter().filter(|c| c.is_none()).count() as u64;
    let entries = if id.dataset == DatasetKind::Sequence {
        (per_point.iter())
            .map(|c| c.map_or(0, |c| map.raw_of_class(c).unwrap_or(0)))
            .collect()
    } else {
        encode_class_predictions(per_point)
    };
    (entries, missing)
}

/// The entries of a per-point prediction file of class ids: [`NOT_PREDICTED`] for a point
/// without a prediction.
pub fn encode_class_predictions(per_point: &[Option<ClassId>]) -> Vec<u32> {
    (per_point.iter())
        .map(|c| c.map_or(NOT_PREDICTED, u32::from))
        .collect()
}

/// Writes frame `id`'s per-point predictions under `out` ([`point_prediction_path`], atomically,
/// its folder made): returns the file and how many points have no prediction.
///
/// [`point_prediction_path`]: crate::format::layout::point_prediction_path
pub fn write_predictions(
    out: &Path,
    id: &FrameId,
    per_point: &[Option<ClassId>],
    map: &ClassMap,
    durability: Durability,
) -> Result<(PathBuf, u64)> {
    let (entries, missing) = encode_predictions(id, per_point, map);
    let path = crate::format::layout::point_prediction_path(out, id);
    crate::format::create_dir(path.parent().expect("a file in a folder"))?;
    crate::format::atomic_write(&path, &encode_raw(&entries), durability)?;
    Ok((path, missing))
}

/// A sequence frame's per-point labels for the kept points of its `scan` (read from
/// `scan_path`): the `.label` file at `path`, its raw ids (low 16 bits) through `map`'s
/// `learning_map`, its instances (high 16 bits). A file of another point count than the scan
/// file's is an error naming both; an id the map does not list, one naming the point.
pub fn read_point_labels(
    path: &Path,
    scan: &crate::source::Scan,
    scan_path: &Path,
    map: &ClassMap,
) -> Result<crate::label::PointLabels> {
    let raw = read_raw(path)?;
    if raw.len() != scan.file_len {
        return Err(Error::LabelCount {
            path: path.into(),
            labels: raw.len(),
            scan: scan_path.into(),
            points: scan.file_len,
            note: None,
        });
    }
    let class = map.classes_of_raw(&raw, path)?;
    let instance: Vec<u16> = raw.iter().map(|v| (v >> 16) as u16).collect();
    if scan.dropped.is_empty() {
        return Ok(crate::label::PointLabels { class, instance });
    }
    let kept = scan.file_indices();
    Ok(crate::label::PointLabels {
        class: kept.iter().map(|&i| class[i as usize]).collect(),
        instance: kept.iter().map(|&i| instance[i as usize]).collect(),
    })
}

/// The bytes of a `.label` file for `class` and `instance` (same length).
pub fn encode(class: &[ClassId], instance: &[u16]) -> Vec<u8> {
    debug_assert_eq!(class.len(), instance.len());
    let mut out = Vec::with_capacity(class.len() * 4);
    for (c, i) in class.iter().zip(instance) {
        out.extend_from_slice(&((*i as u32) << 16 | *c as u32).to_le_bytes());
    }
    out
}

/// The bytes of a `.label` file of raw u32 entries.
pub fn encode_raw(entries: &[u32]) -> Vec<u8> {
    entries.iter().flat_map(|v| v.to_le_bytes()).collect()
}

/// The raw u32 entries of a `.label` file.
pub fn read_raw(path: &Path) -> Result<Vec<u32>> {
    let bytes = crate::fs::read(path, crate::fs::Limit::Data)?;
    if bytes.len() % 4 != 0 {
        return Err(Error::Truncated {
            path: path.into(),
            bytes: bytes.len(),
            record: 4,
            what: "label",
        });
    }
    Ok(bytes
        .chunks_exact(4)
        .map(|w| u32::from_le_bytes([w[0], w[1], w[2], w[3]]))
        .collect())
}

/// The class of every point (low 16 bits), each checked to be a class of `map`.
pub fn read_classes(path: &Path, map: &ClassMap) -> Result<Vec<ClassId>> {
    read_raw(path)?
        .into_iter()
        .enumerate()
        .map(|(i, v)| map.check((v & 0xffff) as u64, path, || format!("point {i}")))
        .collect()
}

/// The class of every point of a per-point prediction file (class ids): `None` where it says
/// none was predicted ([`NOT_PREDICTED`], what `infer` and `unproject` write outside the map);
/// any other value must be a class of `map`.
pub fn read_predicted_classes(path: &Path, map: &ClassMap) -> Result<Vec<Option<ClassId>>> {
    read_raw(path)?
        .into_iter()
        .enumerate()
        .map(|(i, v)| match v & 0xffff {
            NOT_PREDICTED => Ok(None),
            c => map.check(c as u64, path, || format!("point {i}")).map(Some),
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn not_predicted_points_read_as_none_and_other_ids_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.label");
        let map = ClassMap::kitti_paper();
        std::fs::write(&p, encode_raw(&[1, NOT_PREDICTED, 3])).unwrap();
        assert_eq!(
            read_predicted_classes(&p, &map).unwrap(),
            [Some(1), None, Some(3)]
        );
        std::fs::write(&p, encode_raw(&[1, 9])).unwrap();
        let e = read_predicted_classes(&p, &map).unwrap_err().to_string();
        assert!(e.contains("point 1 has label 9"), "{e}");
    }

    #[test]
    fn round_trip() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.label");
        std::fs::write(&p, encode(&[1, 0, 3], &[7, 0, 65535])).unwrap();
        assert_eq!(read_raw(&p).unwrap(), [7 << 16 | 1, 0, 65535 << 16 | 3]);
        let map = ClassMap::kitti_paper();
        assert_eq!(read_classes(&p, &map).unwrap(), [1, 0, 3]);
        std::fs::write(&p, encode(&[9], &[0])).unwrap();
        let e = read_classes(&p, &map).unwrap_err().to_string();
        assert!(e.contains("point 0 has label 9"), "{e}");
        std::fs::write(&p, [0u8; 5]).unwrap();
        assert!(read_raw(&p)
            .unwrap_err()
            .to_string()
            .contains("not a multiple of 4"));
    }
}
