//! PCD v0.7 point clouds (the Point Cloud Library's format; every ROS and vendor tool writes
//! it): a text header (`VERSION`, `FIELDS`, `SIZE`, `TYPE`, `COUNT`, `WIDTH`, `HEIGHT`,
//! `VIEWPOINT`, `POINTS`, `DATA`), then the points as `ascii` lines, `binary` records, or
//! `binary_compressed` (LZF over the fields stored one after the other).
//!
//! Any field order, sizes and types are read; a field of `COUNT 0` is zero bytes wide and read as
//! nothing (three.js's PCDLoader and labelling tools' exports write such padding); bytes after
//! the declared points of `binary` data are left and counted
//! ([`Scan::trailing_bytes`]); an organised cloud (`HEIGHT` > 1) is read row by
//! row; NaN points (a non-dense cloud's empty pixels) are dropped and counted. `VIEWPOINT` is
//! read and not applied (the points are taken in the sensor frame, as drivers write them).

use std::path::Path;

use super::fields::{Field, FieldType, PointLayout};
use super::Scan;
use crate::error::{Error, Result};
use crate::fs::{self, Limit};

/// How the points are stored.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PcdData {
    /// One text line per point.
    Ascii,
    /// Records laid end to end.
    Binary,
    /// LZF-compressed, fields stored one after the other.
    BinaryCompressed,
}

/// A parsed PCD header.
#[derive(Debug, Clone, PartialEq)]
pub struct PcdHeader {
    /// The point record.
    pub layout: PointLayout,
    /// Points per row.
    pub width: usize,
    /// Rows (1 for an unorganised cloud).
    pub height: usize,
    /// Points (`width * height`).
    pub points: usize,
    /// How the points are stored.
    pub data: PcdData,
    /// Byte offset of the data.
    pub data_start: usize,
}

/// Encodes a `binary` PCD of `width` x `height` points: `layout` packed and little-endian
/// (fields in record order, no padding), `records` the points end to end.
pub fn encode(layout: &PointLayout, width: usize, height: usize, records: &[u8]) -> Vec<u8> {
    debug_assert!(!layout.big_endian);
    debug_assert_eq!(records.len(), width * height * layout.step);
    let list = |f: &dyn Fn(&Field) -> String| -> String {
        let v: Vec<String> = layout.fields.iter().map(f).collect();
        v.join(" ")
    };
    let head = format!(
        "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS {}\nSIZE {}\nTYPE {}\n\
         COUNT {}\nWIDTH {width}\nHEIGHT {height}\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {}\n\
         DATA binary\n",
        list(&|f| f.name.clone()),
        list(&|f| f.ty.size().to_string()),
        list(&|f| f.ty.pcd_letter().to_string()),
        list(&|f| f.count.to_string()),
        width * height,
    );
    let mut out = Vec::with_capacity(head.len() + records.len());
    out.extend_from_slice(head.as_bytes());
    out.extend_from_slice(records);
    out
}

/// Reads a PCD file.
pub fn read(path: &Path) -> Result<Scan> {
    let bytes = fs::read(path, Limit::Data)?;
    decode(&bytes, path)
}

/// The most points a header may declare (a PCD of 4 GiB holds at most 4 GiB / 12 bytes).
const MAX_POINTS: usize = 1 << 30;

/// A header line: its keyword, its values and its line number.
type Entry = (String, Vec<String>, usize);

/// The header's lines up to `DATA`: the other entries, `DATA`'s values and line, and the byte
/// offset after it.
fn header_lines(bytes: &[u8], path: &Path) -> Result<(Vec<Entry>, Entry, usize)> {
    let not_pcd = |detail: String| Error::NotFormat {
        path: path.into(),
        format: "a PCD file",
        detail,
    };
    let mut pos = 0;
    let mut line_no = 0;
    let mut entries: Vec<Entry> = Vec::new();
    while pos < bytes.len() {
        let end = bytes[pos..]
            .iter()
            .position(|&b| b == b'\n')
            .map_or(bytes.len(), |e| pos + e + 1);
        line_no += 1;
        let line = std::str::from_utf8(&bytes[pos..end])
            .map_err(|_| not_pcd(format!("header line {line_no} is not text")))?;
        pos = end;
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let mut words = line.split_ascii_whitespace();
        let key = words.next().unwrap_or_default().to_ascii_uppercase();
        let values: Vec<String> = words.map(str::to_string).collect();
        if key == "DATA" {
            return Ok((entries, (key, values, line_no), pos));
        }
        entries.push((key, values, line_no));
        if line_no > 64 {
            return Err(not_pcd("no DATA line in the first 64 lines".into()));
        }
    }
    Err(not_pcd("no DATA line: the header never ends".into()))
}

/// The fields of the header's `FIELDS`, `SIZE`, `TYPE` and `COUNT` lines.
fn fields_of(entries: &[Entry], path: &Path) -> Result<Vec<Field>> {
    let bad = |line: usize, m: String| Error::Format {
        path: path.into(),
        line: Some(line),
        message: m,
    };
    let get = |key: &str| entries.iter().find(|(k, _, _)| k == key);
    let Some((_, names, fields_line)) = get("FIELDS").or_else(|| get("COLUMNS")) else {
        return Err(Error::NotFormat {
            path: path.into(),
            format: "a PCD file",
            detail: "no FIELDS line".into(),
        });
    };
    let n = names.len();
    let list = |key: &str, default: Option<&str>| -> Result<Vec<String>> {
        match get(key) {
            Some((_, v, l)) if v.len() != n => Err(bad(
                *l,
                format!("{key} has {} values for {n} fields", v.len()),
            )),
            Some((_, v, _)) => Ok(v.clone()),
            None => match default {
                Some(d) => Ok(vec![d.to_string(); n]),
                None => Err(bad(*fields_line, format!("no {key} line"))),
            },
        }
    };
    let (sizes, types, counts) = (
        list("SIZE", None)?,
        list("TYPE", None)?,
        list("COUNT", Some("1"))?,
    );
    let line = get("TYPE").map_or(*fields_line, |e| e.2);
    let mut fields = Vec::with_capacity(n);
    let mut offset = 0usize;
    for i in 0..n {
        let size: usize = sizes[i].parse().map_err(|_| {
            bad(
                line,
                format!("SIZE {:?} of field {} is not a number", sizes[i], names[i]),
            )
        })?;
        let ty = FieldType::from_pcd(&types[i].to_ascii_uppercase(), size).ok_or_else(|| {
            bad(
                line,
                format!(
                    "field {} has TYPE {} with SIZE {size}: not a PCD type (I or U of 1, 2, 4, 8 \
                     bytes; F of 4 or 8)",
                    names[i], types[i]
                ),
            )
        })?;
        let count: usize = counts[i]
            .parse()
            .ok()
            .filter(|&c| c <= 1 << 16)
            .ok_or_else(|| {
                bad(
                    line,
                    format!(
                        "COUNT {:?} of field {} is not in 0-65536",
                        counts[i], names[i]
                    ),
                )
            })?;
        fields.push(Field {
            name: names[i].clone(),
            ty,
            count,
            offset,
        });
        offset += size * count;
    }
    Ok(fields)
}

/// Parses the header at the start of `bytes`.
pub fn header(bytes: &[u8], path: &Path) -> Result<PcdHeader> {
    let (entries, (_, data_words, data_line), data_start) = header_lines(bytes, path)?;
    let fields = fields_of(&entries, path)?;
    let bad = |line: usize, m: String| Error::Format {
        path: path.into(),
        line: Some(line),
        message: m,
    };
    let get = |key: &str| entries.iter().find(|(k, _, _)| k == key);
    let number = |key: &str| -> Result<Option<usize>> {
        match get(key) {
            None => Ok(None),
            Some((_, v, l)) => v
                .first()
                .and_then(|s| s.parse::<usize>().ok())
                .filter(|&v| v <= MAX_POINTS)
                .map(Some)
                .ok_or_else(|| bad(*l, format!("{key} {:?} is not a point count", v.join(" ")))),
        }
    };
    let width = number("WIDTH")?.ok_or_else(|| bad(data_line, "no WIDTH line".into()))?;
    let height = number("HEIGHT")?.unwrap_or(1);
    let points = number("POINTS")?.unwrap_or(width * height);
    if points != width * height {
        return Err(bad(
            get("POINTS").map_or(data_line, |e| e.2),
            format!(
                "POINTS is {points} but WIDTH x HEIGHT is {width} x {height} = {}",
                width * height
            ),
        ));
    }
    let data = match data_words.first().map(|s| s.to_ascii_lowercase()) {
        Some(d) if d == "ascii" => PcdData::Ascii,
        Some(d) if d == "binary" => PcdData::Binary,
        Some(d) if d == "binary_compressed" => PcdData::BinaryCompressed,
        other => {
            let shown = other.map_or("with no value".into(), |d| format!("{d:?}"));
            return Err(bad(
                data_line,
                format!("DATA {shown}: expected ascii, binary or binary_compressed"),
            ));
        }
    };
    let step = fields.iter().map(|f| f.ty.size() * f.count).sum();
    let layout = PointLayout {
        fields,
        step,
        big_endian: false,
    };
    layout.roles(path)?;
    Ok(PcdHeader {
        layout,
        width,
        height,
        points,
        data,
        data_start,
    })
}

/// Decodes the bytes of a PCD file; `path` names it in errors.
pub fn decode(bytes: &[u8], path: &Path) -> Result<Scan> {
    let h = header(bytes, path)?;
    let body = &bytes[h.data_start..];
    let (n, step) = (h.points, h.layout.step);
    match h.data {
        PcdData::Binary => {
            if body.len() < n * step {
                return Err(Error::Length {
                    path: path.into(),
                    what: format!("the binary data of {n} points of {step} bytes (POINTS)"),
                    found: body.len(),
                    expected: n * step,
                    unit: "bytes",
                });
            }
            // Bytes after the declared points (some exporters pad the file) are not points.
            let mut cloud = h.layout.decode(&body[..n * step], n, path)?;
            cloud.trailing_bytes = body.len() - n * step;
            Ok(cloud)
        }
        PcdData::BinaryCompressed => {
            let records = decompress(body, n, &h.layout, path)?;
            h.layout.decode(&records, n, path)
        }
        PcdData::Ascii => ascii(body, &h, path),
    }
}

/// LZF-decompresses `binary_compressed` data and interleaves its fields into records.
fn decompress(body: &[u8], n: usize, layout: &PointLayout, path: &Path) -> Result<Vec<u8>> {
    let damaged = |m: String| Error::format(path, format!("damaged binary_compressed data: {m}"));
    if body.len() < 8 {
        return Err(damaged(format!(
            "{} bytes, too short for its size words",
            body.len()
        )));
    }
    let word = |i: usize| u32::from_le_bytes(body[i..i + 4].try_into().expect("4 bytes")) as usize;
    let (compressed, uncompressed) = (word(0), word(4));
    let step = layout.step;
    if uncompressed != n * step {
        return Err(damaged(format!(
            "{uncompressed} bytes uncompressed, but {n} points of {step} bytes (POINTS) are {}",
            n * step
        )));
    }
    let Some(data) = body.get(8..8 + compressed) else {
        return Err(damaged(format!(
            "{compressed} compressed bytes announced, {} present (truncated?)",
            body.len() - 8
        )));
    };
    let mut soa = vec![0u8; uncompressed];
    let written = if uncompressed == 0 {
        0
    } else {
        lzf_rust::decompress(data, &mut soa).map_err(|e| damaged(e.to_string()))?
    };
    if written != uncompressed {
        return Err(damaged(format!(
            "decompressed to {written} bytes, {uncompressed} announced"
        )));
    }
    // Fields one after the other (each n values of its size x count) -> records.
    let mut aos = vec![0u8; uncompressed];
    let mut start = 0;
    for f in &layout.fields {
        let w = f.ty.size() * f.count;
        let column = &soa[start..start + w * n];
        for (i, v) in column.chunks_exact(w).enumerate() {
            aos[i * step + f.offset..i * step + f.offset + w].copy_from_slice(v);
        }
        start += w * n;
    }
    Ok(aos)
}

/// Every value of `layout` as f64, packed: the record an ascii line is read into.
fn widened(layout: &PointLayout) -> PointLayout {
    let mut fields = Vec::new();
    let mut offset = 0;
    for f in &layout.fields {
        fields.push(Field {
            name: f.name.clone(),
            ty: FieldType::F64,
            count: f.count,
            offset,
        });
        offset += 8 * f.count;
    }
    PointLayout {
        fields,
        step: offset,
        big_endian: false,
    }
}

/// Decodes `ascii` data: one line of values per point (every value of every field).
fn ascii(body: &[u8], h: &PcdHeader, path: &Path) -> Result<Scan> {
    let text = std::str::from_utf8(body)
        .map_err(|e| Error::format(path, format!("ascii data is not text: {e}")))?;
    let wide = widened(&h.layout);
    let (offset, values) = (wide.step, wide.step / 8);
    // The declared field of each value on a line, to check that the value is one of its type.
    let declared: Vec<&Field> = (h.layout.fields.iter())
        .flat_map(|f| std::iter::repeat_n(f, f.count))
        .collect();
    let mut records = Vec::with_capacity(h.points * offset);
    let mut lines = 0usize;
    for (k, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() {
            continue;
        }
        if lines == h.points {
            return Err(Error::format(
                path,
                format!(
                    "more than the {} points POINTS declares (data line {})",
                    h.points,
                    k + 1
                ),
            ));
        }
        let mut got = 0;
        for word in line.split_ascii_whitespace() {
            let v: f64 = word.parse().map_err(|_| {
                Error::format(path, format!("point {lines}: {word:?} is not a number"))
            })?;
            if let Some(f) = declared.get(got).filter(|f| !f.ty.holds(v)) {
                return Err(Error::format(
                    path,
                    format!(
                        "point {lines}: {word} is not a value of field {} ({} {})",
                        f.name,
                        f.ty.pcd_letter(),
                        f.ty.size()
                    ),
                ));
            }
            got += 1;
            if got <= values {
                records.extend_from_slice(&v.to_le_bytes());
            }
        }
        if got != values {
            return Err(Error::format(
                path,
                format!("point {lines} has {got} values, the header's fields have {values}"),
            ));
        }
        lines += 1;
    }
    if lines != h.points {
        return Err(Error::Length {
            path: path.into(),
            what: "the ascii data (POINTS)".into(),
            found: lines,
            expected: h.points,
            unit: "points",
        });
    }
    wide.decode(&records, h.points, path)
}
