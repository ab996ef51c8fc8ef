//! `sensor_msgs/msg/PointCloud2`, as ROS 2 serialises it (CDR, either byte order): the header
//! stamp and frame, the point fields, and the rows of point records (`row_step` bytes a row,
//! `point_step` a point), decoded into a [`Scan`] or repacked for a PCD file.

use std::path::Path;

use super::cdr::{Cdr, CdrResult};
use super::fields::{Field, FieldType, PointLayout};
use super::Scan;
use crate::error::{Error, Result};

/// The ROS 2 type name this module decodes.
pub const TYPE_NAME: &str = "sensor_msgs/msg/PointCloud2";

/// A message's `header.stamp`: seconds and nanoseconds since the epoch (or the bag's clock).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Default)]
pub struct Stamp {
    /// Whole seconds.
    pub sec: i32,
    /// Nanoseconds, 0-999,999,999.
    pub nanosec: u32,
}

impl Stamp {
    /// Nanoseconds since the clock's zero.
    pub fn nanos(self) -> i64 {
        self.sec as i64 * 1_000_000_000 + self.nanosec as i64
    }

    /// Seconds after `start`, as a float.
    pub fn seconds_since(self, start: Stamp) -> f64 {
        (self.nanos() - start.nanos()) as f64 * 1e-9
    }
}

impl std::fmt::Display for Stamp {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}.{:09}", self.sec, self.nanosec)
    }
}

/// A decoded `PointCloud2`, its point data borrowed from the message.
#[derive(Debug, Clone)]
pub struct PointCloud2<'a> {
    /// `header.stamp`.
    pub stamp: Stamp,
    /// `header.frame_id`: the frame the points are in.
    pub frame_id: String,
    /// Rows (1 for an unorganised cloud).
    pub height: usize,
    /// Points a row.
    pub width: usize,
    /// The point record (`point_step` bytes; `is_bigendian` kept).
    pub layout: PointLayout,
    /// Bytes a row.
    pub row_step: usize,
    /// `height` rows of `row_step` bytes.
    pub data: &'a [u8],
    /// `is_dense`: no invalid points.
    pub is_dense: bool,
}

/// PointField's datatype constants (`INT8` = 1 ... `FLOAT64` = 8).
fn datatype(code: u8) -> Option<FieldType> {
    Some(match code {
        1 => FieldType::I8,
        2 => FieldType::U8,
        3 => FieldType::I16,
        4 => FieldType::U16,
        5 => FieldType::I32,
        6 => FieldType::U32,
        7 => FieldType::F32,
        8 => FieldType::F64,
        _ => return None,
    })
}

fn fields(c: &mut Cdr<'_>) -> CdrResult<Vec<Field>> {
    let n = c.u32("the field count")? as usize;
    let mut out = Vec::with_capacity(n.min(64));
    for i in 0..n {
        let name = c.string("a field name")?;
        let offset = c.u32("a field offset")? as usize;
        let code = c.u8("a field datatype")?;
        let count = c.u32("a field count")? as usize;
        let ty = datatype(code).ok_or_else(|| {
            format!("field {i} ({name}) has datatype {code}, not one of PointField's 1-8")
        })?;
        out.push(Field {
            name,
            ty,
            count,
            offset,
        });
    }
    Ok(out)
}

fn parse(message: &[u8]) -> CdrResult<PointCloud2<'_>> {
    let mut c = Cdr::new(message)?;
    let stamp = Stamp {
        sec: c.i32("header.stamp.sec")?,
        nanosec: c.u32("header.stamp.nanosec")?,
    };
    let frame_id = c.string("header.frame_id")?;
    let height = c.u32("height")? as usize;
    let width = c.u32("width")? as usize;
    let fields = fields(&mut c)?;
    let big_endian = c.bool("is_bigendian")?;
    let step = c.u32("point_step")? as usize;
    let row_step = c.u32("row_step")? as usize;
    let data = c.bytes("data")?;
    let is_dense = c.bool("is_dense")?;
    if step == 0 {
        return Err("point_step is 0".into());
    }
    if row_step < width.saturating_mul(step) {
        return Err(format!(
            "row_step {row_step} is less than width x point_step = {width} x {step}"
        ));
    }
    let need = height.saturating_mul(row_step);
    if data.len() != need {
        return Err(format!(
            "data holds {} bytes, height x row_step is {height} x {row_step} = {need}",
            data.len()
        ));
    }
    Ok(PointCloud2 {
        stamp,
        frame_id,
        height,
        width,
        layout: PointLayout {
            fields,
            step,
            big_endian,
        },
        row_step,
        data,
        is_dense,
    })
}

impl<'a> PointCloud2<'a> {
    /// Decodes a CDR-serialised message; `what` (the bag and the message) names it in errors.
    /// The fields must lie inside `point_step` and include x, y and z.
    pub fn decode(message: &'a [u8], what: &Path) -> Result<PointCloud2<'a>> {
        let m = parse(message).map_err(|e| Error::format(what, format!("PointCloud2: {e}")))?;
        m.layout.roles(what)?;
        Ok(m)
    }

    /// Points in the message (`width * height`).
    pub fn points(&self) -> usize {
        self.width * self.height
    }

    /// The point records end to end (rows without their padding), borrowed when the rows are
    /// already contiguous.
    fn records(&self) -> std::borrow::Cow<'a, [u8]> {
        let row = self.width * self.layout.step;
        if row == self.row_step {
            return self.data.into();
        }
        let mut out = Vec::with_capacity(row * self.height);
        for r in self.data.chunks_exact(self.row_step) {
            out.extend_from_slice(&r[..row]);
        }
        out.into()
    }

    /// The cloud: finite points in message order (row by row), intensity and ring where the
    /// fields have them.
    pub fn cloud(&self, what: &Path) -> Result<Scan> {
        self.layout.decode(&self.records(), self.points(), what)
    }

    /// The records repacked as a PCD stores them: the fields in offset order, without padding,
    /// little-endian. Returns the packed layout and the bytes.
    pub fn packed(&self) -> (PointLayout, Vec<u8>) {
        let mut fields = self.layout.fields.clone();
        fields.sort_by_key(|f| f.offset);
        let src: Vec<(usize, usize, usize)> = fields
            .iter()
            .map(|f| (f.offset, f.ty.size(), f.count))
            .collect();
        let mut offset = 0;
        for f in &mut fields {
            f.offset = offset;
            offset += f.ty.size() * f.count;
        }
        let layout = PointLayout {
            fields,
            step: offset,
            big_endian: false,
        };
        let records = self.records();
        let mut out = Vec::with_capacity(self.points() * layout.step);
        let swap = self.layout.big_endian;
        for rec in records.chunks_exact(self.layout.step) {
            for &(at, size, count) in &src {
                for v in rec[at..at + size * count].chunks_exact(size) {
                    let start = out.len();
                    out.extend_from_slice(v);
                    if swap {
                        out[start..].reverse();
                    }
                }
            }
        }
        (layout, out)
    }
}
