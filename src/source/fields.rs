//! Point layouts: the fields of one point record (name, type, count, offset), as PCD headers,
//! PointCloud2 messages and `--fields` declarations describe them, and their decoding into a
//! [`Scan`](super::Scan) (the `decode` module).
//!
//! Roles by field name: `x`, `y`, `z` (required); the intensity is the first of `intensity`,
//! `reflectivity`, `reflectance`, `remission`, `i`; the beam id the first of `ring`, `channel`,
//! `laser_id`, `laser`, `line`. Other fields are read past.

use std::path::Path;

use crate::error::{Error, Result};

/// The scalar type of a field.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FieldType {
    /// Signed 8-bit integer.
    I8,
    /// Unsigned 8-bit integer.
    U8,
    /// Signed 16-bit integer.
    I16,
    /// Unsigned 16-bit integer.
    U16,
    /// Signed 32-bit integer.
    I32,
    /// Unsigned 32-bit integer.
    U32,
    /// Signed 64-bit integer.
    I64,
    /// Unsigned 64-bit integer.
    U64,
    /// 32-bit float.
    F32,
    /// 64-bit float.
    F64,
}

impl FieldType {
    /// Bytes of one value.
    pub fn size(self) -> usize {
        match self {
            FieldType::I8 | FieldType::U8 => 1,
            FieldType::I16 | FieldType::U16 => 2,
            FieldType::I32 | FieldType::U32 | FieldType::F32 => 4,
            FieldType::I64 | FieldType::U64 | FieldType::F64 => 8,
        }
    }

    /// Whether a value read as text (an ascii PCD's) is one of this type: an integer within the
    /// type's range, or for floats any number (NaN marks a non-dense cloud's empty point; a
    /// finite value beyond f32's range is not a float32).
    pub fn holds(self, v: f64) -> bool {
        let int = |lo: f64, hi: f64| v.fract() == 0.0 && (lo..=hi).contains(&v);
        match self {
            FieldType::I8 => int(i8::MIN.into(), i8::MAX.into()),
            FieldType::U8 => int(0.0, u8::MAX.into()),
            FieldType::I16 => int(i16::MIN.into(), i16::MAX.into()),
            FieldType::U16 => int(0.0, u16::MAX.into()),
            FieldType::I32 => int(i32::MIN.into(), i32::MAX.into()),
            FieldType::U32 => int(0.0, u32::MAX.into()),
            FieldType::I64 => int(i64::MIN as f64, i64::MAX as f64),
            FieldType::U64 => int(0.0, u64::MAX as f64),
            FieldType::F32 => !v.is_finite() || v.abs() <= f32::MAX as f64,
            FieldType::F64 => true,
        }
    }

    /// PCD's type letter and size (`F 4`, `U 2`).
    pub fn from_pcd(letter: &str, size: usize) -> Option<FieldType> {
        Some(match (letter, size) {
            ("I", 1) => FieldType::I8,
            ("U", 1) => FieldType::U8,
            ("I", 2) => FieldType::I16,
            ("U", 2) => FieldType::U16,
            ("I", 4) => FieldType::I32,
            ("U", 4) => FieldType::U32,
            ("I", 8) => FieldType::I64,
            ("U", 8) => FieldType::U64,
            ("F", 4) => FieldType::F32,
            ("F", 8) => FieldType::F64,
            _ => return None,
        })
    }

    /// PCD's type letter (`I`, `U`, `F`); the size is [`FieldType::size`].
    pub fn pcd_letter(self) -> char {
        match self {
            FieldType::I8 | FieldType::I16 | FieldType::I32 | FieldType::I64 => 'I',
            FieldType::U8 | FieldType::U16 | FieldType::U32 | FieldType::U64 => 'U',
            FieldType::F32 | FieldType::F64 => 'F',
        }
    }

    /// Decodes one value from the start of `b` (at least [`FieldType::size`] bytes).
    #[inline]
    pub fn read(self, b: &[u8], big_endian: bool) -> f64 {
        macro_rules! num {
            ($t:ty, $n:literal) => {{
                let a: [u8; $n] = b[..$n].try_into().expect("sized by the layout");
                (if big_endian {
                    <$t>::from_be_bytes(a)
                } else {
                    <$t>::from_le_bytes(a)
                }) as f64
            }};
        }
        match self {
            FieldType::I8 => b[0] as i8 as f64,
            FieldType::U8 => b[0] as f64,
            FieldType::I16 => num!(i16, 2),
            FieldType::U16 => num!(u16, 2),
            FieldType::I32 => num!(i32, 4),
            FieldType::U32 => num!(u32, 4),
            FieldType::I64 => num!(i64, 8),
            FieldType::U64 => num!(u64, 8),
            FieldType::F32 => num!(f32, 4),
            FieldType::F64 => num!(f64, 8),
        }
    }
}

crate::named_enum!(FieldType, "field type", [
    I8 => "i8" [] "signed 8-bit integer",
    U8 => "u8" [] "unsigned 8-bit integer",
    I16 => "i16" [] "signed 16-bit integer",
    U16 => "u16" [] "unsigned 16-bit integer",
    I32 => "i32" [] "signed 32-bit integer",
    U32 => "u32" [] "unsigned 32-bit integer",
    I64 => "i64" [] "signed 64-bit integer",
    U64 => "u64" [] "unsigned 64-bit integer",
    F32 => "f32" [] "32-bit float",
    F64 => "f64" [] "64-bit float",
]);

/// One field of a point record.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Field {
    /// Its name.
    pub name: String,
    /// Its scalar type.
    pub ty: FieldType,
    /// Values per point (1 for scalars).
    pub count: usize,
    /// Byte offset in the record.
    pub offset: usize,
}

/// The fields of one point record and the record's length (`point_step`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PointLayout {
    /// The fields, in record order.
    pub fields: Vec<Field>,
    /// Bytes of one record (at least the end of the last field).
    pub step: usize,
    /// Whether the values are big-endian (PointCloud2's `is_bigendian`).
    pub big_endian: bool,
}

/// Names of the intensity field, by preference.
pub const INTENSITY_NAMES: [&str; 5] =
    ["intensity", "reflectivity", "reflectance", "remission", "i"];
/// Names of the beam id field, by preference.
pub const RING_NAMES: [&str; 5] = ["ring", "channel", "laser_id", "laser", "line"];

/// Where the roles sit in a record.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Roles {
    pub(crate) xyz: [(usize, FieldType); 3],
    pub(crate) intensity: Option<(usize, FieldType)>,
    pub(crate) ring: Option<(usize, FieldType)>,
}

impl PointLayout {
    /// A packed layout of `fields` (name, type), offsets in order.
    pub fn packed(fields: &[(&str, FieldType)]) -> PointLayout {
        let mut offset = 0;
        let fields = fields
            .iter()
            .map(|&(name, ty)| {
                let f = Field {
                    name: name.into(),
                    ty,
                    count: 1,
                    offset,
                };
                offset += ty.size();
                f
            })
            .collect();
        PointLayout {
            fields,
            step: offset,
            big_endian: false,
        }
    }

    /// Parses a declaration such as `x,y,z,intensity,ring:f32` or `x,y,z:f32,intensity:u8,_:u8,
    /// ring:u16`: comma-separated names, each with an optional `:type`; a field without a type
    /// takes the type of the next field that has one (so the last field must have one); `_` is
    /// padding, the only name that may come twice.
    pub fn declared(spec: &str) -> Result<PointLayout> {
        let bad = |m: String| Error::Config(format!("--fields {spec:?}: {m}"));
        let mut named: Vec<(String, Option<FieldType>)> = Vec::new();
        for part in spec.split(',') {
            let part = part.trim();
            let (name, ty) = match part.split_once(':') {
                Some((n, t)) => (
                    n.trim(),
                    Some(t.trim().parse::<FieldType>().map_err(|_| {
                        let names: Vec<&str> = FieldType::ALL.iter().map(|f| f.as_str()).collect();
                        bad(format!("unknown type {t:?} (one of {})", names.join(", ")))
                    })?),
                ),
                None => (part, None),
            };
            if name.is_empty() {
                return Err(bad("an empty field name".into()));
            }
            if name != "_" && named.iter().any(|(n, _)| n == name) {
                return Err(bad(format!("field {name} is named twice")));
            }
            named.push((name.to_string(), ty));
        }
        if let Some((name, None)) = named.last() {
            return Err(bad(format!(
                "the last field, {name}, has no type: a type ends each run of names it types \
                 (x,y,z:f32 makes all three float32)"
            )));
        }
        let mut next = FieldType::F32;
        let mut typed: Vec<(String, FieldType)> = Vec::with_capacity(named.len());
        for (name, ty) in named.into_iter().rev() {
            next = ty.unwrap_or(next);
            typed.push((name, next));
        }
        typed.reverse();
        let pairs: Vec<(&str, FieldType)> = typed.iter().map(|(n, t)| (n.as_str(), *t)).collect();
        let layout = PointLayout::packed(&pairs);
        layout
            .roles(Path::new("--fields"))
            .map_err(|e| bad(e.to_string()))?;
        Ok(layout)
    }

    /// The layout as a declaration [`PointLayout::declared`] reads back to it, every field with
    /// its type (`x:f32,y:f32,z:f32,intensity:u8,_:u8,ring:u16`): how parameters record it.
    pub fn declaration(&self) -> String {
        let fields: Vec<String> = (self.fields.iter())
            .map(|f| format!("{}:{}", f.name, f.ty.as_str()))
            .collect();
        fields.join(",")
    }

    /// The first field named one of `names` (in their order of preference); a field of count
    /// 0 is zero bytes wide and holds nothing, so it is never one.
    fn find(&self, names: &[&str]) -> Option<&Field> {
        names.iter().find_map(|n| {
            (self.fields.iter()).find(|f| f.count > 0 && f.name.eq_ignore_ascii_case(n))
        })
    }

    /// Checks the layout (fields inside the record, x, y, z present) and finds the roles.
    pub(crate) fn roles(&self, path: &Path) -> Result<Roles> {
        for f in &self.fields {
            let end = f.offset + f.ty.size() * f.count;
            if end > self.step {
                return Err(Error::format(
                    path,
                    format!(
                        "field {} ends at byte {end}, beyond the {}-byte point record",
                        f.name, self.step
                    ),
                ));
            }
        }
        let scalar = |f: &Field| (f.offset, f.ty);
        let axis = |n: &str| {
            self.find(&[n]).map(scalar).ok_or_else(|| {
                Error::format(
                    path,
                    format!(
                        "no {n} field (fields: {})",
                        self.fields
                            .iter()
                            .map(|f| f.name.as_str())
                            .collect::<Vec<_>>()
                            .join(", ")
                    ),
                )
            })
        };
        Ok(Roles {
            xyz: [axis("x")?, axis("y")?, axis("z")?],
            intensity: self.find(&INTENSITY_NAMES).map(scalar),
            ring: self.find(&RING_NAMES).map(scalar),
        })
    }
}
