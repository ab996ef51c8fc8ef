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

/// The colour of a kept point (by its index), when colour is on.
type Colour<'a> = &'a dyn Fn(usize) -> Option<[f32; 3]>;

/// The `.npy` layout's first six planes, in [`Channels::npy`]'s order (checked by
/// [`assemble`]): what [`cell_values`] stores in each cell, at these offsets.
const LIDAR: [Channel; 6] = [
    Channel::X,
    Channel::Y,
    Channel::Z,
    Channel::Intensity,
    Channel::Range,
    Channel::Label,
];

/// Assembles the frame. `colour(point index)` gives the colour of a kept point, when colour is on.
pub fn assemble(
    values: PointValues<'_>,
    proj: &Projection,
    colour: Option<&dyn Fn(usize) -> Option<[f32; 3]>>,
) -> PgmFrame {
    let channels = Channels::npy(colour.is_some());
    assert!(
        channels.0[..LIDAR.len()] == LIDAR,
        "the .npy layout starts with x, y, z, intensity, range, label"
    );
    let PerCell {
        data,
        label,
        instance,
        mask,
        rgb_valid,
    } = match colour {
        // Every pass over the cells compiled with AVX2 where the CPU has it.
        None => crate::simd::with_avx2(
            #[inline(always)]
            move || cell_values::<6>(values, proj, None),
        ),
        Some(f) => cell_values::<9>(values, proj, Some(f)),
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

/// What [`cell_values`] gives for every cell, in [`PgmFrame`]'s fields.
struct PerCell {
    data: Vec<f32>,
    label: Vec<ClassId>,
    instance: Vec<u16>,
    mask: Vec<u8>,
    rgb_valid: Option<Vec<u8>>,
}

/// The `D` channels ([`LIDAR`], then r, g, b where `colour` is given), the class, instance,
/// mask (and colour validity) of every cell, row-major, in one pass over the cells.
///
/// Every value is stored straight into its output once, without a branch: an empty cell reads
/// the first point and keeps zeros instead (a cell built as an array on the stack and copied
/// stalled on store forwarding; a branch per cell was mispredicted at every empty one).
#[inline(always)]
fn cell_values<const D: usize>(
    values: PointValues<'_>,
    proj: &Projection,
    colour: Option<Colour<'_>>,
) -> PerCell {
    assert_eq!(D, LIDAR.len() + if colour.is_some() { 3 } else { 0 });
    let cells = proj.cell_point.len();
    let mut out = PerCell {
        data: Vec::with_capacity(cells * D),
        label: Vec::with_capacity(cells),
        instance: Vec::with_capacity(cells),
        mask: Vec::with_capacity(cells),
        rgb_valid: colour.map(|_| Vec::with_capacity(cells)),
    };
    if values.points.is_empty() {
        // No point, so every cell is empty: zeros everywhere.
        out.data.resize(cells * D, 0.0);
        out.label.resize(cells, 0);
        out.instance.resize(cells, 0);
        out.mask.resize(cells, 0);
        if let Some(v) = &mut out.rgb_valid {
            v.resize(cells, 0);
        }
        return out;
    }
    // One length for every per-point array, so that one bounds check covers them all.
    let n = values.points.len();
    let (points, intensity) = (values.points, &values.intensity[..n]);
    let (class, instance) = (&values.class[..n], &values.instance[..n]);
    {
        let data = &mut out.data.spare_capacity_mut()[..cells * D];
        let label = &mut out.label.spare_capacity_mut()[..cells];
        let inst = &mut out.instance.spare_capacity_mut()[..cells];
        let mask = &mut out.mask.spare_capacity_mut()[..cells];
        let mut valid = out
            .rgb_valid
            .as_mut()
            .map(|v| &mut v.spare_capacity_mut()[..cells]);
        let kept = proj.cell_point.iter().zip(&proj.cell_range);
        for (c, (dst, (&pi, &range))) in data.chunks_exact_mut(D).zip(kept).enumerate() {
            // All ones for a kept cell, zeros for an empty one: a mask, not a select, which
            // the compiler would turn back into a branch (its operands are loads).
            let keep = ((pi != EMPTY) as u32).wrapping_neg();
            let i = (pi & keep) as usize;
            debug_assert!(i < n, "a cell keeps one of the points");
            let i = i.min(n - 1);
            let zeroed = |v: f32| f32::from_bits(v.to_bits() & keep);
            let p = &points[i];
            // `range` is 0 in an empty cell already.
            let lidar = [p.x, p.y, p.z, intensity[i], range, class[i] as f32];
            for (d, v) in dst.iter_mut().zip(lidar) {
                d.write(zeroed(v));
            }
            label[c].write(class[i] & keep as ClassId);
            inst[c].write(instance[i] & keep as u16);
            mask[c].write((keep as u8) & (range > 0.0) as u8);
            if let (Some(f), Some(valid)) = (colour, &mut valid) {
                let rgb = if keep == 0 { None } else { f(i) };
                for (d, v) in dst[LIDAR.len()..].iter_mut().zip(rgb.unwrap_or_default()) {
                    d.write(v);
                }
                valid[c].write(rgb.is_some() as u8);
            }
        }
    }
    // SAFETY: the loop wrote every cell of every output: all `D` values of a cell (six, and
    // three more with colour, where D is nine: asserted above), and its label, instance, mask
    // and colour validity.
    unsafe {
        out.data.set_len(cells * D);
        out.label.set_len(cells);
        out.instance.set_len(cells);
        out.mask.set_len(cells);
        if let Some(v) = &mut out.rgb_valid {
            v.set_len(cells);
        }
    }
    out
}
