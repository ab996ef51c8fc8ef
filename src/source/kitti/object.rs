//! READ: the boxes of a KITTI 3D object frame (`label_2/<frame6>.txt`).
//!
//! One object a line, 15 fields separated by spaces: type, truncated, occluded, alpha, the 2D
//! box (left, top, right, bottom, pixels), the 3D box's height, width, length (metres), the
//! location x, y, z of its bottom-face centre in the rectified camera 0 frame (x right, y down,
//! z forward) and rotation_y (radians, around that frame's y axis). Blank lines are skipped.
//! What the lines say, nothing more: which type is which class is the class map's business.

use std::path::Path;

use crate::error::{Error, Result};
use crate::geom::na;
use crate::source::boxes::{AnnotatedBox, Box3, BoxConvention, BoxRotation};

/// One line of `label_2`.
#[derive(Debug, Clone, PartialEq)]
pub struct ObjectLabel {
    /// Type as written (`Car`, `Person_sitting`, `DontCare`, ...).
    pub kind: String,
    /// Height, width, length of the 3D box, metres.
    pub hwl: [f64; 3],
    /// Bottom-face centre in the rectified camera 0 frame, metres.
    pub location: na::Point3<f64>,
    /// Rotation around the rectified camera's y axis, radians.
    pub rotation_y: f64,
}

/// The object types of KITTI's object benchmark (`DontCare` marks regions left unlabelled).
pub const KNOWN_TYPES: [&str; 9] = [
    "Car",
    "Van",
    "Truck",
    "Pedestrian",
    "Person_sitting",
    "Cyclist",
    "Tram",
    "Misc",
    "DontCare",
];

impl ObjectLabel {
    /// The box in the velodyne frame ([`BoxConvention::KITTI_OBJECT`]), carried there by
    /// `rect_to_velo`, the inverse of `R0_rect * Tr_velo_to_cam`.
    pub fn box_in_velodyne(&self, rect_to_velo: &na::Matrix4<f64>) -> Box3 {
        BoxConvention::KITTI_OBJECT.place(
            self.location.coords.into(),
            self.hwl,
            &BoxRotation::Yaw(self.rotation_y),
            Some(rect_to_velo),
        )
    }

    /// The label as an annotated box of track `line` (its line in the file, from 0).
    pub fn annotated(&self, line: usize, rect_to_velo: &na::Matrix4<f64>) -> AnnotatedBox {
        AnnotatedBox {
            geometry: self.box_in_velodyne(rect_to_velo),
            class_name: self.kind.clone(),
            track: line,
        }
    }

    /// Whether the type is one KITTI defines ([`KNOWN_TYPES`]; spelling and case exact).
    pub fn is_known_type(&self) -> bool {
        KNOWN_TYPES.contains(&self.kind.as_str())
    }
}

/// Parses a `label_2` file's text; `path` names it in errors (with the line). A UTF-8 byte
/// order mark is skipped. Every box but a `DontCare` region (whose sizes KITTI writes as -1)
/// must have positive sizes.
pub fn parse(text: &str, path: &Path) -> Result<Vec<ObjectLabel>> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let fields: Vec<&str> = line.split_whitespace().collect();
        if fields.is_empty() {
            continue;
        }
        let bad = |message: String| Error::Format {
            path: path.into(),
            line: Some(i + 1),
            message,
        };
        if fields.len() < 15 {
            return Err(bad(format!(
                "{} fields, expected 15 (type, truncated, occluded, alpha, 2D box, h w l, x y z, rotation_y)",
                fields.len()
            )));
        }
        let num = |k: usize| -> Result<f64> {
            let v: f64 = fields[k]
                .parse()
                .map_err(|_| bad(format!("field {} is {:?}, not a number", k + 1, fields[k])))?;
            if v.is_finite() {
                Ok(v)
            } else {
                Err(bad(format!("field {} is not finite", k + 1)))
            }
        };
        // Every numeric field is checked, those the labels use and the others alike.
        for k in 1..15 {
            num(k)?;
        }
        let hwl = [num(8)?, num(9)?, num(10)?];
        if fields[0] != "DontCare" {
            crate::geom::check_box_extents(&hwl, ["h", "w", "l"]).map_err(bad)?;
        }
        out.push(ObjectLabel {
            kind: fields[0].to_string(),
            hwl,
            location: na::Point3::new(num(11)?, num(12)?, num(13)?),
            rotation_y: num(14)?,
        });
    }
    Ok(out)
}

/// Reads a `label_2` file.
pub fn read(path: &Path) -> Result<Vec<ObjectLabel>> {
    let text = crate::fs::read_text(path, crate::fs::Limit::Text)?;
    parse(&text, path)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_lines_and_names_bad_ones() {
        let text =
            "Car 0.00 0 1.85 387.63 181.54 423.81 203.12 1.67 1.87 3.69 -16.53 2.39 58.49 1.57\n\n";
        let v = parse(text, Path::new("l.txt")).unwrap();
        assert_eq!(v[0].kind, "Car");
        assert_eq!(v[0].hwl, [1.67, 1.87, 3.69]);
        assert_eq!(v[0].rotation_y, 1.57);
        let e = parse("Car 0 0 1.85 1 2 3\n", Path::new("l.txt"))
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("l.txt:1: 7 fields, expected 15"), "{e}");
        let bom = format!("\u{feff}Truck{}", &text[3..]);
        let v = parse(&bom, Path::new("l.txt")).unwrap();
        assert_eq!(v[0].kind, "Truck");
        assert!(v[0].is_known_type());
        let neg = text.replace("1.67 1.87 3.69", "1.67 -1.87 3.69");
        let e = parse(&neg, Path::new("l.txt")).unwrap_err().to_string();
        assert!(e.contains("l.txt:1: box size must be positive"), "{e}");
        let dc = "DontCare -1 -1 -10 503.89 169.71 590.61 190.13 -1 -1 -1 -1000 -1000 -1000 -10\n";
        assert!(!parse(dc, Path::new("l.txt")).unwrap().is_empty());
        // An unused field (alpha) is checked as the used ones are.
        let nan = text.replace("1.85", "nan");
        let e = parse(&nan, Path::new("l.txt")).unwrap_err().to_string();
        assert!(e.contains("field 4 is not finite"), "{e}");
    }
}
