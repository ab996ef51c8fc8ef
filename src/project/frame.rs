//! PROJECT: the channels of one converted frame, assembled from a scan, its labels and the
//! cell assignment of [`super::project`].
//!
//! The tensor is H x W x C float32 in row-major (HWC) order with SqueezeSeg's channel order
//! ([`Channels::npy`]): x, y, z, intensity, range, label, then r, g, b when colour is on. Empty
//! cells are all zeros, which is what SqueezeSeg's loader expects (its mask is `range > 0`).

use std::mem::MaybeUninit;

use serde::Serialize;

use super::cells16;
use super::channels::{Channel, Channels};
use super::{Projection, EMPTY};
use crate::geom::Point3;
use crate::label::{ClassCounts, ClassId, PointLabels};
use crate::source::Scan;

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
        ClassCounts::count_kept(n, &self.label, &self.mask)
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
            intensity: &scan.intensity,
            class: &labels.class,
            instance: &labels.instance,
        }
    }
}

/// The colour of every cell of a map (zeros where it has none) and whether it has one,
/// row-major: what its r, g, b channels and [`PgmFrame::rgb_valid`] hold.
#[derive(Debug, Clone, PartialEq)]
pub struct CellColours {
    /// Each cell's r, g, b (0-1).
    pub rgb: Vec<[f32; 3]>,
    /// 1 where the cell has a colour.
    pub valid: Vec<u8>,
}

impl CellColours {
    /// The colours of `proj`'s cells: `colour(i)` of the point `i` each keeps (`None`: no
    /// colour), in one pass over the cells (inlined: the colours of many cells are sampled at
    /// once, their image reads overlapping).
    #[inline]
    pub fn of(proj: &Projection, colour: impl Fn(usize) -> Option<[f32; 3]>) -> CellColours {
        let cells = proj.cell_point.len();
        let (mut rgb, mut valid) = (Vec::with_capacity(cells), Vec::with_capacity(cells));
        for &i in &proj.cell_point {
            let c = if i == EMPTY { None } else { colour(i as usize) };
            rgb.push(c.unwrap_or_default());
            valid.push(u8::from(c.is_some()));
        }
        CellColours { rgb, valid }
    }
}

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

/// Assembles the frame; `colour`: its cells' colours ([`CellColours::of`]), when colour is on.
pub fn assemble(
    values: PointValues<'_>,
    proj: &Projection,
    colour: Option<&CellColours>,
) -> PgmFrame {
    assemble_on(values, proj, colour, 1)
}

/// [`assemble`] with the cells split into bands among up to `threads` threads (without colour;
/// the same frame).
pub(crate) fn assemble_on(
    values: PointValues<'_>,
    proj: &Projection,
    colour: Option<&CellColours>,
    threads: usize,
) -> PgmFrame {
    let channels = Channels::npy(colour.is_some());
    if let Some(c) = colour {
        let cells = proj.cell_point.len();
        assert!(
            c.rgb.len() == cells && c.valid.len() == cells,
            "a colour per cell"
        );
    }
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
        ..
    } = match colour {
        None => lidar_cells(values, proj, threads),
        Some(f) => {
            let mut out = PerCell::with_capacity::<9>(proj.cell_point.len(), true);
            cell_values::<9>(values, proj, 0, out.slots(), Some(f));
            // SAFETY: `cell_values` wrote every cell of every output.
            unsafe { out.set_len() }
        }
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
    /// Cells.
    cells: usize,
    /// Channels of `data`.
    depth: usize,
    data: Vec<f32>,
    label: Vec<ClassId>,
    instance: Vec<u16>,
    mask: Vec<u8>,
    rgb_valid: Option<Vec<u8>>,
}

/// The outputs of a band of cells, to be written (each slot once).
struct Cells<'a> {
    data: &'a mut [MaybeUninit<f32>],
    label: &'a mut [MaybeUninit<ClassId>],
    instance: &'a mut [MaybeUninit<u16>],
    mask: &'a mut [MaybeUninit<u8>],
    rgb_valid: Option<&'a mut [MaybeUninit<u8>]>,
}

impl<'a> Cells<'a> {
    /// The LiDAR outputs of these cells, for [`cells16::cells`].
    fn out(&mut self) -> cells16::Out<'_> {
        cells16::Out {
            data: &mut *self.data,
            label: &mut *self.label,
            instance: &mut *self.instance,
            mask: &mut *self.mask,
        }
    }

    /// The outputs of these cells from cell `done` on.
    fn from(self, done: usize) -> Cells<'a> {
        let depth = self.data.len() / self.label.len().max(1);
        Cells {
            data: &mut self.data[done * depth..],
            label: &mut self.label[done..],
            instance: &mut self.instance[done..],
            mask: &mut self.mask[done..],
            rgb_valid: self.rgb_valid.map(|v| &mut v[done..]),
        }
    }
}

/// What [`cells16::cells`] reads of the `cells` cells from `first` on.
fn kept_of<'a>(
    values: PointValues<'a>,
    proj: &'a Projection,
    first: usize,
    cells: usize,
) -> cells16::Kept<'a> {
    let n = values.points.len();
    cells16::Kept {
        points: values.points,
        intensity: &values.intensity[..n],
        class: &values.class[..n],
        instance: &values.instance[..n],
        cell_point: &proj.cell_point[first..first + cells],
        cell_range: &proj.cell_range[first..first + cells],
    }
}

impl PerCell {
    /// Room for `cells` cells of `D` channels, nothing written yet.
    fn with_capacity<const D: usize>(cells: usize, colour: bool) -> PerCell {
        PerCell {
            cells,
            depth: D,
            data: Vec::with_capacity(cells * D),
            label: Vec::with_capacity(cells),
            instance: Vec::with_capacity(cells),
            mask: Vec::with_capacity(cells),
            rgb_valid: colour.then(|| Vec::with_capacity(cells)),
        }
    }

    /// The unwritten outputs of all the cells.
    fn slots(&mut self) -> Cells<'_> {
        let n = self.cells;
        Cells {
            data: &mut self.data.spare_capacity_mut()[..n * self.depth],
            label: &mut self.label.spare_capacity_mut()[..n],
            instance: &mut self.instance.spare_capacity_mut()[..n],
            mask: &mut self.mask.spare_capacity_mut()[..n],
            rgb_valid: self
                .rgb_valid
                .as_mut()
                .map(|v| &mut v.spare_capacity_mut()[..n]),
        }
    }

    /// The outputs, every cell written.
    ///
    /// # Safety
    /// Every slot of [`PerCell::slots`] was written.
    unsafe fn set_len(mut self) -> PerCell {
        let n = self.cells;
        // SAFETY: the caller wrote them all; the capacities were asked for exactly these.
        unsafe {
            self.data.set_len(n * self.depth);
            self.label.set_len(n);
            self.instance.set_len(n);
            self.mask.set_len(n);
            if let Some(v) = &mut self.rgb_valid {
                v.set_len(n);
            }
        }
        self
    }
}

/// Cells per band of [`lidar_cells`]: whole bands for a thread, not fewer.
const MIN_BAND: usize = 16_384;

/// The six [`LIDAR`] channels, class, instance and mask of every cell, in up to `threads`
/// bands of cells at once, each pass compiled for the widest vectors the CPU has.
fn lidar_cells(values: PointValues<'_>, proj: &Projection, threads: usize) -> PerCell {
    use rayon::prelude::*;
    let cells = proj.cell_point.len();
    let mut out = PerCell::with_capacity::<6>(cells, false);
    let bands = threads.min(cells / MIN_BAND).max(1);
    let band = cells.div_ceil(bands).max(1);
    let fill = |first: usize, mut band: Cells<'_>| {
        // Sixteen cells at a time where the CPU has AVX-512, the rest a cell at a time.
        let done = cells16::cells(kept_of(values, proj, first, band.label.len()), band.out());
        let rest = band.from(done);
        crate::simd::with_simd(
            #[inline(always)]
            move || cell_values::<6>(values, proj, first + done, rest, None),
        )
    };
    let all = out.slots();
    if bands == 1 {
        fill(0, all);
    } else {
        let Cells {
            data,
            label,
            instance,
            mask,
            ..
        } = all;
        let parts = data
            .par_chunks_mut(band * 6)
            .zip(label.par_chunks_mut(band));
        let parts = parts
            .zip(instance.par_chunks_mut(band))
            .zip(mask.par_chunks_mut(band));
        parts
            .enumerate()
            .for_each(|(b, (((data, label), instance), mask))| {
                let cells = Cells {
                    data,
                    label,
                    instance,
                    mask,
                    rgb_valid: None,
                };
                fill(b * band, cells)
            });
    }
    // SAFETY: the bands cover the cells, and `cell_values` wrote every cell of its band.
    unsafe { out.set_len() }
}

/// The `D` channels ([`LIDAR`], then r, g, b where `colour` is given), the class, instance,
/// mask (and colour validity) of the cells from `first` on that `out` holds, row-major, in one
/// pass over the cells, writing every slot of `out`.
///
/// Every value is stored straight into its output once, without a branch: an empty cell reads
/// the first point and keeps zeros instead (a cell built as an array on the stack and copied
/// stalled on store forwarding; a branch per cell was mispredicted at every empty one).
#[inline(always)]
fn cell_values<const D: usize>(
    values: PointValues<'_>,
    proj: &Projection,
    first: usize,
    out: Cells<'_>,
    colour: Option<&CellColours>,
) {
    assert_eq!(D, LIDAR.len() + if colour.is_some() { 3 } else { 0 });
    let cells = out.label.len();
    assert_eq!(out.data.len(), cells * D);
    assert!(out.instance.len() == cells && out.mask.len() == cells);
    assert_eq!(
        out.rgb_valid.as_ref().map(|v| v.len()),
        colour.map(|_| cells)
    );
    let kept = &proj.cell_point[first..first + cells];
    let ranges = &proj.cell_range[first..first + cells];
    let Cells {
        data,
        label,
        instance: inst,
        mask,
        mut rgb_valid,
    } = out;
    if values.points.is_empty() {
        // No point, so every cell is empty: zeros everywhere.
        data.iter_mut().for_each(|v| {
            v.write(0.0);
        });
        for ((l, i), m) in label.iter_mut().zip(inst.iter_mut()).zip(mask.iter_mut()) {
            l.write(0);
            i.write(0);
            m.write(0);
        }
        rgb_valid
            .iter_mut()
            .flat_map(|v| v.iter_mut())
            .for_each(|v| {
                v.write(0);
            });
        return;
    }
    // One length for every per-point array, so that one bounds check covers them all.
    let n = values.points.len();
    let (points, intensity) = (values.points, &values.intensity[..n]);
    let (class, instance) = (&values.class[..n], &values.instance[..n]);
    let kept = kept.iter().zip(ranges);
    for (c, (dst, (&pi, &range))) in data.chunks_exact_mut(D).zip(kept).enumerate() {
        // All ones for a kept cell, zeros for an empty one: a mask, not a select, which
        // the compiler would turn back into a branch (its operands are loads; and it does
        // branch on the mask itself unless `black_box` hides where the mask comes from).
        let keep = std::hint::black_box(((pi != EMPTY) as u32).wrapping_neg());
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
        if let (Some(colour), Some(valid)) = (colour, &mut rgb_valid) {
            for (d, &v) in dst[LIDAR.len()..].iter_mut().zip(&colour.rgb[first + c]) {
                d.write(v);
            }
            valid[c].write(colour.valid[first + c]);
        }
    }
}
