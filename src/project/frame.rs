//! PROJECT: the channels of one converted frame, assembled from a scan, its labels and the
//! cell assignment of [`super::project`].
//!
//! The tensor is H x W x C float32 in row-major (HWC) order with SqueezeSeg's channel order:
//! x, y, z, intensity, range, label, then r, g, b when colour is on. Empty cells are all zeros,
//! which is what SqueezeSeg's loader expects (its mask is `range > 0`).

use serde::Serialize;

use super::{Projection, EMPTY};
use crate::kitti::velodyne::Scan;
use crate::label::{Class, PointLabels};

/// Channel names of the LiDAR-only tensor, in order.
pub const LIDAR_CHANNELS: [&str; 6] = ["x", "y", "z", "intensity", "range", "label"];
/// Channel names of the tensor with colour, in order.
pub const RGB_CHANNELS: [&str; 9] = ["x", "y", "z", "intensity", "range", "label", "r", "g", "b"];

/// One frame as a Polar Grid Map.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PgmFrame {
    /// Rows.
    pub rows: usize,
    /// Columns.
    pub cols: usize,
    /// Channel names, in tensor order.
    pub channels: Vec<&'static str>,
    /// H x W x C float32, row-major.
    pub data: Vec<f32>,
    /// Class id per cell.
    pub label: Vec<u8>,
    /// Instance id per cell (tracklet index + 1, 0 for none).
    pub instance: Vec<u16>,
    /// 1 where the cell holds a point (range > 0).
    pub mask: Vec<u8>,
    /// 1 where the cell has a colour; `None` without colour channels.
    pub rgb_valid: Option<Vec<u8>>,
}

impl PgmFrame {
    /// Number of channels.
    pub fn depth(&self) -> usize {
        self.channels.len()
    }

    /// Cells per class, indexed by class id (valid cells only).
    pub fn class_cells(&self) -> [u64; Class::COUNT] {
        let mut c = [0u64; Class::COUNT];
        for (l, m) in self.label.iter().zip(&self.mask) {
            if *m != 0 {
                c[*l as usize] += 1;
            }
        }
        c
    }
}

/// Assembles the frame. `colour(point index)` gives the colour of a kept point, when colour is on.
pub fn assemble(
    scan: &Scan,
    labels: &PointLabels,
    proj: &Projection,
    colour: Option<&dyn Fn(usize) -> Option<[f32; 3]>>,
) -> PgmFrame {
    let depth = if colour.is_some() {
        RGB_CHANNELS.len()
    } else {
        LIDAR_CHANNELS.len()
    };
    let cells = proj.spec.cells();
    let mut data = vec![0f32; cells * depth];
    let mut label = vec![0u8; cells];
    let mut instance = vec![0u16; cells];
    let mut mask = vec![0u8; cells];
    let mut rgb_valid = colour.map(|_| vec![0u8; cells]);
    for (c, &pi) in proj.cell_point.iter().enumerate() {
        if pi == EMPTY {
            continue;
        }
        let i = pi as usize;
        let p = &scan.points[i];
        let range = proj.cell_range[c];
        let out = &mut data[c * depth..(c + 1) * depth];
        let class = labels.class[i];
        out[..6].copy_from_slice(&[p.x, p.y, p.z, scan.reflectance[i], range, class.id() as f32]);
        label[c] = class.id();
        instance[c] = labels.instance[i];
        mask[c] = (range > 0.0) as u8;
        if let (Some(f), Some(valid)) = (colour, rgb_valid.as_mut()) {
            if let Some(rgb) = f(i) {
                out[6..9].copy_from_slice(&rgb);
                valid[c] = 1;
            }
        }
    }
    let channels = if depth == RGB_CHANNELS.len() {
        RGB_CHANNELS.to_vec()
    } else {
        LIDAR_CHANNELS.to_vec()
    };
    PgmFrame {
        rows: proj.spec.rows,
        cols: proj.spec.cols,
        channels,
        data,
        label,
        instance,
        mask,
        rgb_valid,
    }
}
