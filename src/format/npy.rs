//! WRITE and read back `.npy` arrays (NumPy format 1.0, little endian, C order).
//!
//! Encoding writes NumPy's own header and copies the data; decoding is npyz's. This module fixes
//! the dtypes the project uses and turns errors into ones that name the file.

use std::path::Path;

use crate::error::{Error, Result};

/// Encodes a float32 array of `shape` (C order) as `.npy` bytes (format 1.0, `<f4`).
///
/// The header is NumPy's own layout (a Python dict literal padded with spaces to a multiple of 64
/// bytes, ending in a newline); the data is copied as little-endian bytes in one pass. npyz's
/// writer goes value by value, which cost 1.4 ms
/// of a 9-channel frame (see docs/performance.md).
pub fn encode_f32(shape: &[u64], data: &[f32]) -> Vec<u8> {
    let (mut out, body) = parts_f32(shape, data);
    out.extend_from_slice(&body);
    out
}

/// The `.npy` file of float32 `data` of `shape` as its header and its data's bytes, for writers
/// that write the parts one after the other ([`encode_f32`] without the copy, where the memory
/// of the values already is little-endian float32).
pub fn parts_f32<'a>(shape: &[u64], data: &'a [f32]) -> (Vec<u8>, std::borrow::Cow<'a, [u8]>) {
    debug_assert_eq!(shape.iter().product::<u64>() as usize, data.len());
    #[cfg(target_endian = "little")]
    let body = std::borrow::Cow::Borrowed(bytemuck::cast_slice(data));
    #[cfg(not(target_endian = "little"))]
    let body = std::borrow::Cow::Owned(data.iter().flat_map(|v| v.to_le_bytes()).collect());
    (header_f32(shape), body)
}

/// The bytes of a float32 `.npy` file of `shape`: its header plus 4 bytes a value.
pub fn file_len_f32(shape: &[u64]) -> u64 {
    header_f32(shape).len() as u64 + 4 * shape.iter().product::<u64>()
}

/// NumPy's header for a C-order float32 array of `shape`, magic and length included.
fn header_f32(shape: &[u64]) -> Vec<u8> {
    let dims: Vec<String> = shape.iter().map(u64::to_string).collect();
    let shape_txt = if dims.len() == 1 {
        format!("({},)", dims[0])
    } else {
        format!("({})", dims.join(", "))
    };
    let mut header = format!("{{'descr': '<f4', 'fortran_order': False, 'shape': {shape_txt}, }}");
    // magic (6) + version (2) + header length (2) + header + '\n' is a multiple of 64.
    let unpadded = 10 + header.len() + 1;
    header.extend(std::iter::repeat_n(
        ' ',
        unpadded.next_multiple_of(64) - unpadded,
    ));
    header.push('\n');
    let mut out = Vec::with_capacity(10 + header.len());
    out.extend_from_slice(b"\x93NUMPY\x01\x00");
    out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    out
}

/// An array read from a `.npy` file, converted to f64 whatever its numeric dtype.
#[derive(Debug, Clone, PartialEq)]
pub struct NpyArray {
    /// Shape, C order.
    pub shape: Vec<u64>,
    /// Values in C order.
    pub data: Vec<f64>,
    /// The dtype as NumPy writes it (`<f4`, `<i8`, `|u1`, ...).
    pub dtype: String,
}

impl NpyArray {
    /// Whether the dtype is a floating-point one.
    pub fn is_float(&self) -> bool {
        self.dtype.contains('f')
    }
}

/// Reads a float32 `.npy` file (the converter's output) without conversion; a Fortran-ordered
/// file is transposed to C order.
///
/// npyz parses and checks the header; the data, little-endian `<f4` in C order, is then copied
/// straight from the file's tail, which is several times faster than decoding it value by value.
pub fn read_f32(path: &Path) -> Result<(Vec<u64>, Vec<f32>)> {
    let bytes = crate::fs::read(path, crate::fs::Limit::Data)?;
    let npy = npyz::NpyFile::new(&bytes[..]).map_err(|e| not_npy(path, e))?;
    let shape = npy.shape().to_vec();
    let dtype = npy.dtype().descr();
    if dtype != "'<f4'" {
        return Err(Error::Dtype {
            path: path.into(),
            found: dtype,
            expected: "float32 ('<f4')",
        });
    }
    let fortran = npy.order() == npyz::Order::Fortran;
    let need = npy.len() as usize * 4;
    // The data must start right after the header (checked by its length field) and fill the
    // rest of the file.
    let header_len = 10 + u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
    let header_len = if bytes[6] == 1 {
        header_len
    } else {
        12 + u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize
    };
    let data_start = header_len;
    if bytes.len().checked_sub(need) != Some(header_len) {
        return Err(Error::Length {
            path: path.into(),
            what: format!("the data of shape {shape:?} after the header"),
            found: bytes.len().saturating_sub(header_len),
            expected: need,
            unit: "bytes",
        });
    }
    let data: Vec<f32> = bytes[data_start..]
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    Ok((shape.clone(), c_order(&shape, data, fortran)))
}

/// `data` in C (row-major) order: unchanged when it already is, else transposed from Fortran
/// (column-major) order, as `np.asfortranarray` writes it.
fn c_order<T: Copy>(shape: &[u64], data: Vec<T>, fortran: bool) -> Vec<T> {
    if !fortran || shape.len() < 2 {
        return data;
    }
    let dims: Vec<usize> = shape.iter().map(|&d| d as usize).collect();
    // Fortran strides: the first axis varies fastest.
    let mut strides = vec![1usize; dims.len()];
    for k in 1..dims.len() {
        strides[k] = strides[k - 1] * dims[k - 1];
    }
    let mut out = Vec::with_capacity(data.len());
    let mut index = vec![0usize; dims.len()];
    for _ in 0..data.len() {
        out.push(
            data[index
                .iter()
                .zip(&strides)
                .map(|(i, s)| i * s)
                .sum::<usize>()],
        );
        // Next C-order index: the last axis varies fastest.
        for k in (0..dims.len()).rev() {
            index[k] += 1;
            if index[k] < dims[k] {
                break;
            }
            index[k] = 0;
        }
    }
    out
}

/// The error for a file npyz cannot read as NumPy (header or truncated data).
fn not_npy(path: &Path, e: impl std::fmt::Display) -> Error {
    Error::NotFormat {
        path: path.into(),
        format: "a (complete) .npy file",
        detail: e.to_string(),
    }
}

/// The values of `npy` as f64, each converted by `to_f64`.
fn values<T: npyz::Deserialize>(
    npy: npyz::NpyFile<&[u8]>,
    path: &Path,
    to_f64: impl Fn(T) -> f64,
) -> Result<Vec<f64>> {
    let v = npy.into_vec::<T>().map_err(|e| not_npy(path, e))?;
    Ok(v.into_iter().map(to_f64).collect())
}

/// Reads a numeric `.npy` file of any common dtype, converting values to f64 and Fortran order
/// to C order.
pub fn read_any(path: &Path) -> Result<NpyArray> {
    let bytes = crate::fs::read(path, crate::fs::Limit::Data)?;
    let npy = npyz::NpyFile::new(&bytes[..]).map_err(|e| not_npy(path, e))?;
    let shape = npy.shape().to_vec();
    let fortran = npy.order() == npyz::Order::Fortran;
    let descr = npy.dtype().descr();
    let dtype = descr.trim_matches('\'').to_string();
    let data: Vec<f64> = match dtype.as_str() {
        "<f4" => values(npy, path, |v: f32| v.into())?,
        "<f8" => values(npy, path, |v: f64| v)?,
        "|u1" | "<u1" => values(npy, path, |v: u8| v.into())?,
        "|i1" | "<i1" => values(npy, path, |v: i8| v.into())?,
        "<u2" => values(npy, path, |v: u16| v.into())?,
        "<i2" => values(npy, path, |v: i16| v.into())?,
        "<u4" => values(npy, path, |v: u32| v.into())?,
        "<i4" => values(npy, path, |v: i32| v.into())?,
        "<i8" => values(npy, path, |v: i64| v as f64)?,
        "<u8" => values(npy, path, |v: u64| v as f64)?,
        "|b1" => values(npy, path, |v: bool| f64::from(u8::from(v)))?,
        other => {
            return Err(Error::Dtype {
                path: path.into(),
                found: other.to_string(),
                expected: "a number (float, int, uint or bool)",
            })
        }
    };
    let data = c_order(&shape, data, fortran);
    Ok(NpyArray { shape, data, dtype })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn header_is_numpys() {
        // np.save of a (64, 512, 6) float32 array, first 128 bytes (NumPy 1.x and 2.x agree).
        let mut numpy = b"\x93NUMPY\x01\x00v\x00{'descr': '<f4', 'fortran_order': False, 'shape': (64, 512, 6), }".to_vec();
        numpy.extend(std::iter::repeat_n(b' ', 128 - numpy.len() - 1));
        numpy.push(b'\n');
        let data = vec![1.5f32; 64 * 512 * 6];
        let ours = encode_f32(&[64, 512, 6], &data);
        assert_eq!(&ours[..128], &numpy[..]);
        let (header, body) = parts_f32(&[64, 512, 6], &data);
        assert_eq!([header.as_slice(), &body].concat(), ours);
        assert_eq!(ours.len(), 128 + data.len() * 4);
        assert_eq!(&ours[128..132], &1.5f32.to_le_bytes());
    }

    #[test]
    fn f32_round_trip() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.npy");
        let data: Vec<f32> = (0..24).map(|v| v as f32 * 0.5).collect();
        crate::format::atomic_write(&p, &encode_f32(&[2, 3, 4], &data), Default::default())
            .unwrap();
        let (shape, back) = read_f32(&p).unwrap();
        assert_eq!(shape, vec![2, 3, 4]);
        assert_eq!(back, data);
        let any = read_any(&p).unwrap();
        assert_eq!(any.dtype, "<f4");
        assert_eq!(any.data[3], 1.5);
    }

    #[test]
    fn fortran_order_is_transposed() {
        // np.asfortranarray(np.arange(6).reshape(2, 3)) stores 0 3 1 4 2 5.
        let f = vec![0, 3, 1, 4, 2, 5];
        assert_eq!(c_order(&[2, 3], f, true), [0, 1, 2, 3, 4, 5]);
        // 2 x 3 x 2: element (i, j, k) = 6i + 2j + k, stored with i fastest.
        let mut f = Vec::new();
        for k in 0..2 {
            for j in 0..3 {
                for i in 0..2 {
                    f.push(6 * i + 2 * j + k);
                }
            }
        }
        assert_eq!(c_order(&[2, 3, 2], f, true), (0..12).collect::<Vec<_>>());
    }
}
