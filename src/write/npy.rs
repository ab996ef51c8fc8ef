//! WRITE and read back `.npy` arrays (NumPy format 1.0, little endian, C order).
//!
//! The encoder and decoder are npyz's; this module fixes the dtypes the project uses and turns
//! errors into ones that name the file.

use std::path::Path;

use npyz::WriterBuilder;

use crate::error::{Error, Result};

/// Encodes a float32 array of `shape` (C order) as `.npy` bytes.
pub fn encode_f32(shape: &[u64], data: &[f32]) -> Vec<u8> {
    debug_assert_eq!(shape.iter().product::<u64>() as usize, data.len());
    let mut out = Vec::with_capacity(data.len() * 4 + 128);
    {
        let mut w = npyz::WriteOptions::new()
            .default_dtype()
            .shape(shape)
            .writer(&mut out)
            .begin_nd()
            .expect("writing to a Vec cannot fail");
        w.extend(data.iter().copied()).expect("writing to a Vec cannot fail");
        w.finish().expect("writing to a Vec cannot fail");
    }
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

/// Reads a float32 `.npy` file (the converter's output) without conversion.
pub fn read_f32(path: &Path) -> Result<(Vec<u64>, Vec<f32>)> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let npy = npyz::NpyFile::new(&bytes[..]).map_err(|e| Error::format(path, format!("not a .npy file: {e}")))?;
    let shape = npy.shape().to_vec();
    let dtype = npy.dtype().descr();
    if dtype != "'<f4'" {
        return Err(Error::format(path, format!("dtype {dtype}, expected float32 ('<f4')")));
    }
    let data = npy.into_vec::<f32>().map_err(|e| Error::format(path, format!("truncated .npy data: {e}")))?;
    Ok((shape, data))
}

/// Reads a numeric `.npy` file of any common dtype, converting values to f64.
pub fn read_any(path: &Path) -> Result<NpyArray> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let npy = npyz::NpyFile::new(&bytes[..]).map_err(|e| Error::format(path, format!("not a .npy file: {e}")))?;
    let shape = npy.shape().to_vec();
    let descr = npy.dtype().descr();
    let dtype = descr.trim_matches('\'').to_string();
    let trunc = |e: std::io::Error| Error::format(path, format!("truncated .npy data: {e}"));
    let data: Vec<f64> = match dtype.as_str() {
        "<f4" => npy.into_vec::<f32>().map_err(trunc)?.into_iter().map(f64::from).collect(),
        "<f8" => npy.into_vec::<f64>().map_err(trunc)?,
        "|u1" | "<u1" => npy.into_vec::<u8>().map_err(trunc)?.into_iter().map(f64::from).collect(),
        "|i1" | "<i1" => npy.into_vec::<i8>().map_err(trunc)?.into_iter().map(f64::from).collect(),
        "<u2" => npy.into_vec::<u16>().map_err(trunc)?.into_iter().map(f64::from).collect(),
        "<i2" => npy.into_vec::<i16>().map_err(trunc)?.into_iter().map(f64::from).collect(),
        "<u4" => npy.into_vec::<u32>().map_err(trunc)?.into_iter().map(f64::from).collect(),
        "<i4" => npy.into_vec::<i32>().map_err(trunc)?.into_iter().map(f64::from).collect(),
        "<i8" => npy.into_vec::<i64>().map_err(trunc)?.into_iter().map(|v| v as f64).collect(),
        "<u8" => npy.into_vec::<u64>().map_err(trunc)?.into_iter().map(|v| v as f64).collect(),
        "|b1" => npy.into_vec::<bool>().map_err(trunc)?.into_iter().map(|v| v as u8 as f64).collect(),
        other => return Err(Error::format(path, format!("unsupported dtype {other}"))),
    };
    Ok(NpyArray { shape, data, dtype })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn f32_round_trip() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.npy");
        let data: Vec<f32> = (0..24).map(|v| v as f32 * 0.5).collect();
        crate::write::atomic_write(&p, &encode_f32(&[2, 3, 4], &data), false).unwrap();
        let (shape, back) = read_f32(&p).unwrap();
        assert_eq!(shape, vec![2, 3, 4]);
        assert_eq!(back, data);
        let any = read_any(&p).unwrap();
        assert_eq!(any.dtype, "<f4");
        assert_eq!(any.data[3], 1.5);
    }
}
