//! WRITE and read back a converted frame as `.npy`: SqueezeSeg's `lidar_2d` layout.
//!
//! H x W x C float32 in C order, C = 6 (x, y, z, intensity, range, label) or 9 (+ r, g, b): the
//! `.npy` carries no channel names, so its depth names them ([`Channels::npy_of_depth`]). A file
//! of another float or integer dtype (SqueezeSeg's published maps, a user's own) is read through
//! the general decoder and converted to float32.

use std::path::Path;

use super::npy;
use crate::error::{Error, Result};
use crate::label::{ClassId, ClassMap};
use crate::project::{Channel, Channels, PgmFrame};

/// A map read from a `.npy` file.
#[derive(Debug, Clone, PartialEq)]
pub struct PgmFile {
    /// Rows.
    pub rows: usize,
    /// Columns.
    pub cols: usize,
    /// Channel of each plane.
    pub channels: Channels,
    /// H x W x C, row-major.
    pub data: Vec<f32>,
}

/// The `.npy` bytes of a converted frame.
pub fn encode(frame: &PgmFrame) -> Vec<u8> {
    npy::encode_f32(&shape(frame), &frame.data)
}

/// Writes a converted frame to `path`, atomically: the bytes of [`encode`], written without
/// copying the map into them first.
pub fn write(path: &Path, frame: &PgmFrame, durability: super::Durability) -> Result<()> {
    let (header, body) = npy::parts_f32(&shape(frame), &frame.data);
    super::atomic_write_parts(path, &[&header, &body], durability)
}

/// The `.npy` shape of a converted frame: H x W x C.
fn shape(frame: &PgmFrame) -> [u64; 3] {
    [frame.rows as u64, frame.cols as u64, frame.depth() as u64]
}

/// Reads a map: H x W x 6 or 9, any numeric dtype.
pub fn read(path: &Path) -> Result<PgmFile> {
    let (shape, data) = match npy::read_f32(path) {
        Ok(v) => v,
        Err(Error::Dtype { .. }) => {
            let a = npy::read_any(path)?;
            (a.shape, a.data.into_iter().map(|v| v as f32).collect())
        }
        Err(e) => return Err(e),
    };
    let channels = match shape.as_slice() {
        [_, _, c] => Channels::npy_of_depth(*c as usize),
        _ => None,
    }
    .ok_or_else(|| Error::Shape {
        path: path.into(),
        what: "the array".into(),
        found: shape.iter().map(|&d| d as usize).collect(),
        expected: "a map H x W x 6 (x, y, z, intensity, range, label) or 9 (+ r, g, b)".into(),
    })?;
    Ok(PgmFile {
        rows: shape[0] as usize,
        cols: shape[1] as usize,
        channels,
        data,
    })
}

impl PgmFile {
    /// Number of cells.
    pub fn cells(&self) -> usize {
        self.rows * self.cols
    }

    /// The values of cell `i` (row-major), one per channel.
    pub fn cell(&self, i: usize) -> &[f32] {
        let d = self.channels.len();
        &self.data[i * d..(i + 1) * d]
    }

    /// The converted frame this map holds: labels checked against `map`, the mask where
    /// range > 0, colour valid where any of r, g, b is above 0; no instances (a `.npy` holds
    /// none). `path` names the file in errors.
    pub fn into_frame(self, map: &ClassMap, path: &Path) -> Result<PgmFrame> {
        let (label, mask) = self.labels_and_mask(map, path)?;
        let rgb_valid = self.channels.index(Channel::R).map(|r| {
            (0..self.cells())
                .map(|i| self.cell(i)[r..r + 3].iter().any(|v| *v > 0.0) as u8)
                .collect()
        });
        Ok(PgmFrame {
            rows: self.rows,
            cols: self.cols,
            instance: vec![0; self.cells()],
            channels: self.channels,
            data: self.data,
            label,
            mask,
            rgb_valid,
        })
    }

    /// The label and mask of every cell: mask 1 where range > 0; the label of a masked cell
    /// checked to be a class of `map` (0 in empty cells). `path` names the file in errors.
    fn labels_and_mask(&self, map: &ClassMap, path: &Path) -> Result<(Vec<ClassId>, Vec<u8>)> {
        let range = self.channels.index(Channel::Range).expect("an .npy layout");
        let label = self.channels.index(Channel::Label).expect("an .npy layout");
        let mut labels = vec![0 as ClassId; self.cells()];
        let mut mask = vec![0u8; self.cells()];
        for i in 0..self.cells() {
            let cell = self.cell(i);
            if cell[range] > 0.0 {
                let v = cell[label];
                if v.fract() != 0.0 || v < 0.0 {
                    return Err(Error::NotAClass {
                        path: path.into(),
                        what: format!("cell ({}, {})", i / self.cols, i % self.cols),
                        value: v.into(),
                        map: map.name.clone(),
                        max: map.len() - 1,
                        hint: None,
                    });
                }
                labels[i] = map.check(v as u64, path, || {
                    format!("cell ({}, {})", i / self.cols, i % self.cols)
                })?;
                mask[i] = 1;
            }
        }
        Ok((labels, mask))
    }
}
