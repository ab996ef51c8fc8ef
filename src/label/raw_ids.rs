//! LABEL: a per-point source's raw label ids (SemanticKITTI's `.label` entries) to classes and
//! back, through the class map's `learning_map` and `learning_map_inv`.

use std::path::Path;

use super::{ClassId, ClassMap};
use crate::error::{Error, Result};

impl ClassMap {
    /// The raw id class `c` is written back as (`learning_map_inv`), for per-point maps.
    pub fn raw_of_class(&self, c: ClassId) -> Option<u32> {
        self.learning_map_inv.get(c as usize).copied()
    }

    /// The class of a raw per-point label (through `learning_map`); `None` for an id the map
    /// does not list.
    pub fn class_of_raw(&self, raw: u32) -> Option<ClassId> {
        self.learning_map.get(&raw).copied()
    }

    /// The class of every entry of a per-point `.label` file of raw ids (low 16 bits through
    /// `learning_map`); an id the map does not list is an error naming `path` and the point.
    pub fn classes_of_raw(&self, raw: &[u32], path: &Path) -> Result<Vec<ClassId>> {
        // A table over all 2^16 raw ids: one lookup a point (a tree lookup per point was most
        // of a SemanticKITTI frame's time), a class below 256 or UNLISTED; one pass that only
        // notes an unlisted id (a `Result` a point cost a sixth of the frame), the first
        // looked for after it.
        const UNLISTED: u16 = u16::MAX;
        let mut lut = vec![UNLISTED; 1 << 16];
        for (&r, &c) in &self.learning_map {
            if let Some(slot) = lut.get_mut(r as usize) {
                *slot = u16::from(c);
            }
        }
        let lut: &[u16; 1 << 16] = lut.as_slice().try_into().expect("2^16 entries");
        let mut unlisted = false;
        let classes = raw
            .iter()
            .map(|&v| {
                let c = lut[(v & 0xffff) as usize];
                unlisted |= c == UNLISTED;
                c as ClassId
            })
            .collect();
        if !unlisted {
            return Ok(classes);
        }
        let i = (raw.iter())
            .position(|&v| lut[(v & 0xffff) as usize] == UNLISTED)
            .expect("an unlisted id");
        Err(Error::format(
            path,
            format!(
                "point {i} has label id {}, which the learning_map of {} does not list",
                raw[i] & 0xffff,
                self.name
            ),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Raw ids through the learning map: the instance bits above 16 ignored; an unlisted id
    /// is an error naming the first such point, wherever it is.
    #[test]
    fn raw_ids_through_the_learning_map() {
        let m = ClassMap::semantic_kitti();
        let path = Path::new("000000.label");
        let car = m.class_of_raw(10).unwrap();
        let raw = [0, 10, (7 << 16) | 10, 40, 252];
        let got = m.classes_of_raw(&raw, path).unwrap();
        assert_eq!(got[..3], [0, car, car]);
        assert_eq!(got[3], m.class_of_raw(40).unwrap());
        assert_eq!(got[4], m.class_of_raw(252).unwrap());
        for at in [0, 3, 999] {
            let mut raw = vec![10u32; 1000];
            raw[at] = 12345;
            raw[999] = 12345;
            let e = m.classes_of_raw(&raw, path).unwrap_err().to_string();
            assert!(e.contains(&format!("point {at} has label id 12345")), "{e}");
            assert!(e.contains("000000.label"), "{e}");
        }
    }
}
