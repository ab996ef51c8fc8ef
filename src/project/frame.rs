//! PROJECT: the channels of one converted frame, assembled from a scan, its labels and the
//! cell assignment of [`super::project`].
//!
//! The tensor is H x W x C float32 in row-major (HWC) order with SqueezeSeg's channel order
//! ([`Channels::npy`]): x, y, z, intensity, range, label, then r, g, b when colour is on. Empty
//! cells are all zeros, which is what SqueezeSeg's loader expects (its mask is `range > 0`).

use serde::Serialize;

use super::channels::{Channel, Channels};
use super::{Projection, EMPTY};
use crate::geom::Point3;
use crate::kitti::velodyne::Scan;
use crate::label::{ClassCounts, ClassId, PointLabels};

/// One frame as a Polar Grid Map.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PgmFrame {
    /// Rows.
    pub rows: usize,
    /// Columns.
    pub cols: usize,
    /// Channel of each plane of `data`.
    pub channels: Channels,
    /// H x W x C float32, row-major.
    pub data: Vec<f32>,
    /// Class id per cell.
    pub label: Vec<ClassId>,
    /// Instance id per cell (box index + 1, 0 for none).
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

    /// Number of cells.
    pub fn cells(&self) -> usize {
        self.rows * self.cols
    }

    /// Valid cells per class among `n` classes.
    pub fn class_cells(&self, n: usize) -> ClassCounts {
        let valid = self.label.iter().zip(&self.mask).filter(|(_, m)| **m != 0);
        ClassCounts::count(n, valid.map(|(l, _)| *l))
    }
}

/// What each point of a projected cloud carries into the map, in the cloud's order.
#[derive(Debug, Clone, Copy)]
pub struct PointValues<'a> {
    /// Coordinates, velodyne frame, metres.
    pub points: &'a [Point3],
    /// Reflectance (0-1).
    pub intensity: &'a [f32],
    /// Class id.
    pub class: &'a [ClassId],
    /// Instance id (0 = none).
    pub instance: &'a [u16],
}

impl<'a> PointValues<'a> {
    /// The values of a scan's points with their labels.
    pub fn of_scan(scan: &'a Scan, labels: &'a PointLabels) -> PointValues<'a> {
        PointValues {
            points: &scan.points,
            intensity: &scan.reflectance,
            class: &labels.class,
            instance: &labels.instance,
        }
    }
}

/// Assembles the frame. `colour(point index)` gives the colour of a kept point, when colour is on.
pub fn assemble(
    values: PointValues<'_>,
    proj: &Projection,
    colour: Option<&dyn Fn(usize) -> Option<[f32; 3]>>,
) -> PgmFrame {
    let channels = Channels::npy(colour.is_some());
    let depth = channels.len();
    let at = |c: Channel| channels.index(c).expect("an .npy layout channel");
    let (x, intensity, range_at, label_at) = (
        at(Channel::X),
        at(Channel::Intensity),
        at(Channel::Range),
        at(Channel::Label),
    );
    let rgb_at = channels.index(Channel::R);
    let cells = proj.spec.cells();
    let mut data = vec![0f32; cells * depth];
    let mut label = vec![0 as ClassId; cells];
    let mut instance = vec![0u16; cells];
    let mut mask = vec![0u8; cells];
    let mut rgb_valid = colour.map(|_| vec![0u8; cells]);
    let per_cell = data
        .chunks_exact_mut(depth)
        .zip(&mut label)
        .zip(&mut instance)
        .zip(&mut mask)
        .zip(proj.cell_point.iter().zip(&proj.cell_range))
        .enumerate();
    for (c, ((((out, label), instance), mask), (&pi, &range))) in per_cell {
        if pi == EMPTY {
            continue;
        }
        let i = pi as usize;
        let p = &values.points[i];
        let class = values.class[i];
        out[x..x + 3].copy_from_slice(&[p.x, p.y, p.z]);
        out[intensity] = values.intensity[i];
        out[range_at] = range;
        out[label_at] = class as f32;
        *label = class;
        *instance = values.instance[i];
        *mask = (range > 0.0) as u8;
        if let (Some(f), Some(valid), Some(r)) = (colour, rgb_valid.as_mut(), rgb_at) {
            if let Some(rgb) = f(i) {
                out[r..r + 3].copy_from_slice(&rgb);
                valid[c] = 1;
            }
        }
    }
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
