//! WRITE and read back per-point `.label` files.
//!
//! One little-endian u32 per point of the scan, in the scan's file order: the class id in the low
//! 16 bits, the instance id in the high 16 bits (SemanticKITTI's layout).

use std::path::Path;

use crate::error::{Error, Result};
use crate::label::{ClassId, ClassMap};

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

#[cfg(test)]
mod tests {
    use super::*;

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
