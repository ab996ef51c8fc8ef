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

/// Where the values go in a cell of the `.npy` layout.
#[derive(Debug, Clone, Copy)]
struct Slots {
    x: usize,
    intensity: usize,
    range: usize,
    label: usize,
    rgb: Option<usize>,
}

/// The colour of a kept point (by its index), when colour is on.
type Colour<'a> = &'a dyn Fn(usize) -> Option<[f32; 3]>;

/// Assembles the frame. `colour(point index)` gives the colour of a kept point, when colour is on.
pub fn assemble(
    values: PointValues<'_>,
    proj: &Projection,
    colour: Option<&dyn Fn(usize) -> Option<[f32; 3]>>,
) -> PgmFrame {
    let channels = Channels::npy(colour.is_some());
    let at = |c: Channel| channels.index(c).expect("an .npy layout channel");
    let slots = Slots {
        x: at(Channel::X),
        intensity: at(Channel::Intensity),
        range: at(Channel::Range),
        label: at(Channel::Label),
        rgb: channels.index(Channel::R),
    };
    let cells = proj.spec.cells();
    // Every cell is written once, empty ones as zeros (filling buffers with zeros first and
    // writing most cells again cost a tenth of a Python `project` call).
    let mut rgb_valid = colour.map(|_| Vec::with_capacity(cells));
    let data = match (colour, channels.len()) {
        (None, 6) => cell_values::<6>(values, proj, slots, None),
        (Some(f), 9) => cell_values::<9>(values, proj, slots, Some((f, rgb_valid.as_mut()))),
        (_, depth) => unreachable!("the .npy layout has 6 or 9 channels, not {depth}"),
    };
    let mask = proj.cell_point.iter().zip(&proj.cell_range);
    let mask = mask.map(|(&pi, &range)| (pi != EMPTY && range > 0.0) as u8);
    PgmFrame {
        rows: proj.spec.rows,
        cols: proj.spec.cols,
        channels,
        data,
        label: per_cell(proj, values.class),
        instance: per_cell(proj, values.instance),
        mask: mask.collect(),
        rgb_valid,
    }
}

/// A per-point value for every cell: its point's, 0 where the cell is empty.
fn per_cell<T: Copy + Default>(proj: &Projection, of_point: &[T]) -> Vec<T> {
    let at = |&pi: &u32| {
        if pi == EMPTY {
            T::default()
        } else {
            of_point[pi as usize]
        }
    };
    proj.cell_point.iter().map(at).collect()
}

/// The `D` channels of every cell, row-major; with colour, the cells' colour validity is
/// pushed to `colour`'s vector.
///
/// Each value is stored straight into the output, every slot once (a cell built as an array
/// on the stack and copied stalled on store forwarding: two thirds of this function's time).
fn cell_values<const D: usize>(
    values: PointValues<'_>,
    proj: &Projection,
    at: Slots,
    mut colour: Option<(Colour<'_>, Option<&mut Vec<u8>>)>,
) -> Vec<f32> {
    // The slots a kept cell's stores fill: all `D`, each once (the `set_len` below rests on it).
    let rgb = at.rgb.filter(|_| colour.is_some());
    let filled = [at.x, at.x + 1, at.x + 2, at.intensity, at.range, at.label]
        .into_iter()
        .chain(rgb.into_iter().flat_map(|r| r..r + 3))
        .fold(0u64, |m, slot| m | (1 << slot));
    assert_eq!(filled, (1 << D) - 1, "the layout's slots fill a cell");
    let n = proj.cell_point.len() * D;
    let mut data: Vec<f32> = Vec::with_capacity(n);
    let out = &mut data.spare_capacity_mut()[..n];
    let cells = proj.cell_point.iter().zip(&proj.cell_range);
    for (dst, (&pi, &range)) in out.chunks_exact_mut(D).zip(cells) {
        if pi == EMPTY {
            dst.iter_mut().for_each(|v| {
                v.write(0.0);
            });
            if let Some((_, Some(v))) = &mut colour {
                v.push(0);
            }
            continue;
        }
        let i = pi as usize;
        let p = &values.points[i];
        dst[at.x].write(p.x);
        dst[at.x + 1].write(p.y);
        dst[at.x + 2].write(p.z);
        dst[at.intensity].write(values.intensity[i]);
        dst[at.range].write(range);
        dst[at.label].write(values.class[i] as f32);
        if let (Some((f, valid)), Some(r)) = (&mut colour, at.rgb) {
            let rgb = f(i);
            dst[r..r + 3]
                .iter_mut()
                .zip(rgb.unwrap_or_default())
                .for_each(|(d, c)| {
                    d.write(c);
                });
            if let Some(v) = valid {
                v.push(rgb.is_some() as u8);
            }
        }
    }
    // SAFETY: the loop wrote all `D` values of every cell: an empty cell's by the fill, a kept
    // one's by its stores, which fill every slot (asserted above).
    unsafe { data.set_len(n) };
    data
}
