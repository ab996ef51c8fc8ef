//! PROJECT: each point's claim on its cell, the nearest point keeping it ([`super::project_impl`]).

use std::mem::MaybeUninit;
use std::ops::Range;

use rayon::prelude::*;

use super::columns::{Geometry, BORDER, OUTSIDE};
use super::{norm, PgmSpec, PointCells, EMPTY};
use crate::geom::Point3;

/// Points per block of the two-pass loop (columns and ranges, then cells).
const BLOCK: usize = 512;

/// The fewest points a thread of [`claim`] takes (fewer are not worth a thread's start).
const MIN_PART: usize = 16_384;

/// What [`claim`] gives: the point and range each cell keeps, the cell of every point (when
/// kept), and the points in view.
pub(super) struct Claimed {
    pub cell_point: Vec<u32>,
    pub cell_range: Vec<f32>,
    pub point_cell: Vec<u32>,
    pub in_fov: u64,
    /// Cells that keep a point.
    pub filled: u64,
}

/// Every point's claim on its cell ([`claim_cells`]), the points split among up to `threads`
/// threads: in parts of disjoint rows where the rows allow it ([`row_bands`]: one parallel
/// step, no merge), else each part claims cells of its own and the parts' keys are merged by
/// their minimum (the same result, the keys holding each point's index in the whole cloud).
pub(super) fn claim(
    points: &[Point3],
    spec: &PgmSpec,
    point_cells: PointCells,
    (ring_ids, beams): (Option<&[u8]>, usize),
    geometry: Geometry<'_>,
    threads: usize,
) -> Claimed {
    let (n, cells) = (points.len(), spec.cells());
    let keep = point_cells == PointCells::Keep;
    let parts = threads.min(n / MIN_PART).max(1);
    if let Some(bands) = row_bands(spec, (ring_ids, beams), geometry, parts) {
        return claim_banded(
            points,
            spec,
            point_cells,
            (ring_ids, beams),
            geometry,
            bands,
        );
    }
    let chunk = n.div_ceil(parts).max(1);
    // Every point's cell is written by its part (no fill first).
    let mut point_cell = Vec::with_capacity(if keep { n } else { 0 });
    let out = &mut point_cell.spare_capacity_mut()[..if keep { n } else { 0 }];
    let mut outs: Vec<&mut [MaybeUninit<u32>]> = match keep {
        true if n > 0 => out.chunks_mut(chunk).collect(),
        _ => (0..parts).map(|_| Default::default()).collect(),
    };
    let part = |p: usize, out: &mut [MaybeUninit<u32>]| {
        let range = p * chunk..((p + 1) * chunk).min(n);
        // The map's cells and a spare one (dropped below).
        let mut key = vec![u64::MAX; cells + 1];
        let (pts, geometry) = (&points[range.clone()], geometry.part(range.clone()));
        let rings = ring_ids.map(|r| &r[range.clone()]);
        let in_fov = crate::simd::with_simd(
            #[inline(always)]
            || {
                claim_cells(
                    pts,
                    spec,
                    (rings, beams),
                    geometry,
                    (range.start, 0),
                    &mut key,
                    out,
                )
            },
        );
        key.truncate(cells);
        (key, in_fov)
    };
    let claimed: Vec<(Vec<u64>, u64)> = if parts == 1 {
        vec![part(0, outs.pop().unwrap_or_default())]
    } else {
        outs.into_par_iter()
            .enumerate()
            .map(|(p, o)| part(p, o))
            .collect()
    };
    if keep {
        // SAFETY: each part wrote the cell of each of its points, and the parts cover them.
        unsafe { point_cell.set_len(n) };
    }
    let in_fov = claimed.iter().map(|(_, f)| f).sum();
    let keys: Vec<Vec<u64>> = claimed.into_iter().map(|(k, _)| k).collect();
    let (cell_point, cell_range, filled) = merge_keys(keys, threads);
    Claimed {
        cell_point,
        cell_range,
        point_cell,
        in_fov,
        filled,
    }
}

/// A part of [`claim_banded`]: its points and the cells they can claim (whole rows).
struct Band {
    points: Range<usize>,
    cells: Range<usize>,
}

/// The points split into `parts` parts whose rows do not overlap, where the rows are known
/// (rings or beams, columns by azimuth) and never go back up along the points (the scan order's
/// rings always): each part then claims the cells of its own rows, and no keys need merging.
/// `None` for one part, or where the rows allow no such split.
fn row_bands(
    spec: &PgmSpec,
    (rings, beams): (Option<&[u8]>, usize),
    geometry: Geometry<'_>,
    parts: usize,
) -> Option<Vec<Band>> {
    let rings = rings.filter(|r| parts > 1 && geometry.columns.is_none() && r.is_sorted())?;
    let (n, cols) = (rings.len(), spec.cols);
    let row = |ring: u8| spec.beam_row(ring, beams);
    // (first point, first row) of each part; a part may be empty.
    let mut starts = vec![(0, 0)];
    for p in 1..parts {
        let prev = starts[p - 1].1;
        let r = row(rings[p * n / parts]).max(prev);
        starts.push((rings.partition_point(|&g| row(g) < r), r));
    }
    starts.push((n, spec.rows));
    let bands = starts.windows(2).map(|w| Band {
        points: w[0].0..w[1].0,
        cells: w[0].1 * cols..w[1].1 * cols,
    });
    Some(bands.collect())
}

/// [`claim`] in parts of disjoint rows ([`row_bands`]), all at once: each part keeps the keys
/// of its own cells (and a spare one), and splits them into their cells' points and ranges.
fn claim_banded(
    points: &[Point3],
    spec: &PgmSpec,
    point_cells: PointCells,
    (ring_ids, beams): (Option<&[u8]>, usize),
    geometry: Geometry<'_>,
    bands: Vec<Band>,
) -> Claimed {
    let (n, cells) = (points.len(), spec.cells());
    let keep = point_cells == PointCells::Keep;
    let mut point_cell = Vec::with_capacity(if keep { n } else { 0 });
    let (mut cell_point, mut cell_range) = (Vec::with_capacity(cells), Vec::with_capacity(cells));
    let mut out_cell = &mut point_cell.spare_capacity_mut()[..if keep { n } else { 0 }];
    let mut out_point = &mut cell_point.spare_capacity_mut()[..cells];
    let mut out_range = &mut cell_range.spare_capacity_mut()[..cells];
    let mut jobs = Vec::with_capacity(bands.len());
    for band in bands {
        let (p, rest) = std::mem::take(&mut out_point).split_at_mut(band.cells.len());
        out_point = rest;
        let (r, rest) = std::mem::take(&mut out_range).split_at_mut(band.cells.len());
        out_range = rest;
        let (c, rest) =
            std::mem::take(&mut out_cell).split_at_mut(if keep { band.points.len() } else { 0 });
        out_cell = rest;
        jobs.push((band, p, r, c));
    }
    let (in_fov, filled) = jobs
        .into_par_iter()
        .map(|(band, point, range, cell)| {
            let pts = band.points.clone();
            let mut key = vec![u64::MAX; band.cells.len() + 1];
            crate::simd::with_simd(
                #[inline(always)]
                || {
                    let in_fov = claim_cells(
                        &points[pts.clone()],
                        spec,
                        (ring_ids.map(|r| &r[pts.clone()]), beams),
                        geometry.part(pts.clone()),
                        (pts.start, band.cells.start),
                        &mut key,
                        cell,
                    );
                    (in_fov, split_keys(&key, point, range))
                },
            )
        })
        .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
    // SAFETY: the bands cover the cells and the points, and each wrote all of its own.
    unsafe {
        cell_point.set_len(cells);
        cell_range.set_len(cells);
        if keep {
            point_cell.set_len(n);
        }
    }
    Claimed {
        cell_point,
        cell_range,
        point_cell,
        in_fov,
        filled,
    }
}

/// The point and range of every cell from the parts' keys: their minimum ([`split_key`]), in
/// up to `threads` bands of cells at once; and the cells that keep a point.
fn merge_keys(mut keys: Vec<Vec<u64>>, threads: usize) -> (Vec<u32>, Vec<f32>, u64) {
    let mut first = keys.remove(0);
    let cells = first.len();
    // Every cell's point and range written once (no zero fill first).
    let (mut point, mut range) = (Vec::with_capacity(cells), Vec::with_capacity(cells));
    let (out_point, out_range) = (
        &mut point.spare_capacity_mut()[..cells],
        &mut range.spare_capacity_mut()[..cells],
    );
    let filled = if keys.is_empty() {
        crate::simd::with_simd(
            #[inline(always)]
            || split_keys(&first, out_point, out_range),
        )
    } else {
        let band = cells.div_ceil(threads.max(1)).max(1);
        let bands = first
            .par_chunks_mut(band)
            .zip(out_point.par_chunks_mut(band));
        bands
            .zip(out_range.par_chunks_mut(band))
            .enumerate()
            .map(|(b, ((k, p), r))| {
                crate::simd::with_simd(
                    #[inline(always)]
                    || {
                        for other in &keys {
                            for (k, o) in k.iter_mut().zip(&other[b * band..]) {
                                *k = (*k).min(*o);
                            }
                        }
                        split_keys(k, p, r)
                    },
                )
            })
            .sum()
    };
    // SAFETY: `split_keys` wrote every cell's point and range (the bands cover the cells).
    unsafe {
        point.set_len(cells);
        range.set_len(cells);
    }
    (point, range, filled)
}

/// The point and range of the cells whose keys are `keys` into `point` and `range` (as many as
/// they hold; a spare key past them is left out), in one pass; returns the cells that keep a
/// point.
#[inline(always)]
fn split_keys(keys: &[u64], point: &mut [MaybeUninit<u32>], range: &mut [MaybeUninit<f32>]) -> u64 {
    assert!(point.len() == range.len() && keys.len() >= point.len());
    let mut filled = 0;
    for ((&k, p), r) in keys.iter().zip(point).zip(range) {
        let (i, v) = split_key(k);
        filled += u64::from(k != u64::MAX);
        p.write(i);
        r.write(v);
    }
    filled
}

/// Every point's claim on its cell: the key of the point each cell keeps into `cell_key` (the
/// cells from `offset` on, and a spare one), the cell of every point into `point_cell` (when
/// not empty); returns the points in view. `first` is the index of `points[0]` in the cloud;
/// the cells from `offset` on hold every cell the points can claim (all of the map's, with
/// `offset` 0, unless the rows are known and the columns by azimuth: [`row_bands`]).
///
/// The point kept in each cell as one key, range bits above index: the smallest key is the
/// nearest point, the first of equally near ones (ranges are finite and >= 0, whose bits order
/// as their values), kept without a branch.
///
/// With the rows known (rings or beams) and the columns by azimuth, the first pass gives each
/// point's cell, and a point outside the map claims a spare cell past the map's end instead of
/// being skipped: the second pass is then a branch-free minimum per point, but for the points
/// near a column border (about 1%), whose column the definition decides.
#[inline(always)]
fn claim_cells(
    points: &[Point3],
    spec: &PgmSpec,
    (rings, beams): (Option<&[u8]>, usize),
    geometry: Geometry<'_>,
    (first, offset): (usize, usize),
    cell_key: &mut [u64],
    point_cell: &mut [MaybeUninit<u32>],
) -> u64 {
    assert!(
        offset + cell_key.len() - 1 <= spec.cells(),
        "some of the map's cells and a spare one"
    );
    let by_rows = rings.is_some() && geometry.columns.is_none();
    assert!(
        by_rows || (offset, cell_key.len()) == (0, spec.cells() + 1),
        "all of the map's cells, where the rows are not known"
    );
    // The cell of every point is written, or none.
    assert!(point_cell.is_empty() || point_cell.len() == points.len());
    let mut out = Out {
        cell_key,
        point_cell,
    };
    let part = Part {
        spec,
        geometry,
        rings,
        beams,
        first,
        offset: offset as u32,
        // The first cell of each beam's row in `cell_key`, by beam, where the first pass gives
        // the cells (a beam outside the part's cells is never looked up).
        row_start: by_rows.then(|| {
            std::array::from_fn(|b| {
                let first = spec.beam_row(b as u8, beams) * spec.cols;
                // (a beam past the sensor's is never looked up: the rings are checked)
                (first.min(u32::MAX as usize / 2) as u32).wrapping_sub(offset as u32)
            })
        }),
    };
    // Cheap reject for maps narrower than 180 degrees: a point outside the front wedge.
    let wedge = spec.front_wedge().filter(|_| geometry.columns.is_none());
    let columns = spec.columns();
    let (rotate, scale) = (geometry.rotate, geometry.scale);
    let mut in_fov = 0u64;
    let (mut code, mut range) = ([0i32; BLOCK], [0f32; BLOCK]);
    for start in (0..points.len()).step_by(BLOCK) {
        let end = (start + BLOCK).min(points.len());
        let (base, pts) = (&geometry.base[start..end], &points[start..end]);
        let (code, range) = (&mut code[..end - start], &mut range[..end - start]);
        for ((c, r), b) in code.iter_mut().zip(range.iter_mut()).zip(base) {
            *c = columns.code(b, rotate as f32);
            *r = norm(b) * scale;
        }
        if let Some(t) = wedge {
            for (c, p) in code.iter_mut().zip(pts) {
                let inside = (p.x > 0.0) & (p.y.abs() <= p.x * t);
                *c = if inside { *c } else { OUTSIDE };
            }
        }
        in_fov += match part.row_start {
            Some(_) => part.by_rows(start, code, range, &mut out),
            None => part.each(start, pts, code, range, &mut out),
        };
    }
    in_fov
}

/// What a part of the points reads from: the map, its points' geometry and rings.
struct Part<'a> {
    spec: &'a PgmSpec,
    geometry: Geometry<'a>,
    rings: Option<&'a [u8]>,
    beams: usize,
    /// The index of the part's first point in the cloud.
    first: usize,
    /// The map's cell of `cell_key[0]`.
    offset: u32,
    /// The first cell of each beam's row, with rows known and columns by azimuth.
    row_start: Option<[u32; 256]>,
}

/// What a part of the points writes: the key each cell keeps (and the spare cell's), the cell
/// of every point (or nothing).
struct Out<'a> {
    cell_key: &'a mut [u64],
    point_cell: &'a mut [MaybeUninit<u32>],
}

impl Part<'_> {
    /// The key of the part's point `i` at `range`: range bits above the point's index in the
    /// cloud ([`claim_cells`]).
    #[inline(always)]
    fn key(&self, range: f32, i: usize) -> u64 {
        (u64::from(range.to_bits()) << 32) | (self.first + i) as u64
    }

    /// The claims of the block of points from `start`, whose column codes are `code`, each
    /// point's cell as it comes (rows by elevation, or given columns); the points in view.
    #[inline(always)]
    fn each(
        &self,
        start: usize,
        pts: &[Point3],
        code: &[i32],
        range: &[f32],
        out: &mut Out,
    ) -> u64 {
        let (spec, beams) = (self.spec, self.beams);
        let Out {
            cell_key,
            point_cell,
        } = out;
        let mut in_fov = 0;
        for (k, p) in pts.iter().enumerate() {
            let i = start + k;
            let cell = match code[k] {
                OUTSIDE => None,
                code => self.geometry.column(i, code, spec).map(|col| {
                    let row = match self.rings {
                        Some(r) => spec.beam_row(r[i], beams),
                        None => spec.elevation_row(p, range[k]),
                    };
                    row * spec.cols + col
                }),
            };
            if !point_cell.is_empty() {
                point_cell[i].write(cell.map_or(EMPTY, |c| c as u32));
            }
            if let Some(c) = cell {
                in_fov += 1;
                cell_key[c] = cell_key[c].min(self.key(range[k], i));
            }
        }
        in_fov
    }

    /// The claims of the block of points from `start` with rows known and columns by azimuth:
    /// the cells of the whole block first (the code's column plus its row's first cell; the
    /// spare cell outside the map; above it, near a border, for the definition to decide),
    /// then a branch-free minimum per point; the points in view.
    #[inline(always)]
    fn by_rows(&self, start: usize, code: &[i32], range: &[f32], out: &mut Out) -> u64 {
        let (Some(rs), Some(rings)) = (&self.row_start, self.rings) else {
            unreachable!("rows by rings")
        };
        let Out {
            cell_key,
            point_cell,
        } = out;
        let spare = (cell_key.len() - 1) as u32;
        let mut cell = [0u32; BLOCK];
        let (cell, rings) = (&mut cell[..code.len()], &rings[start..start + code.len()]);
        let at = |code: i32, first: u32| match code {
            OUTSIDE => spare,
            c if c >= 0 => first + c as u32,
            _ => u32::MAX,
        };
        if self.spec.rows == self.beams {
            // One row per beam (the common case): the first cell by a product, vectorised.
            let (cols, offset) = (self.spec.cols as u32, self.offset);
            for ((c, &code), &ring) in cell.iter_mut().zip(code).zip(rings) {
                *c = at(code, (u32::from(ring) * cols).wrapping_sub(offset));
            }
        } else {
            for ((c, &code), &ring) in cell.iter_mut().zip(code).zip(rings) {
                *c = at(code, rs[ring as usize]);
            }
        }
        let mut in_fov = 0;
        for (k, &c) in cell.iter().enumerate() {
            let i = start + k;
            let c = if c > spare {
                let col = self.geometry.column(i, BORDER, self.spec);
                col.map_or(spare, |col| rs[rings[k] as usize] + col as u32)
            } else {
                c
            };
            let inside = c != spare;
            in_fov += u64::from(inside);
            if !point_cell.is_empty() {
                point_cell[i].write(if inside { c + self.offset } else { EMPTY });
            }
            // A select, not the branch the compiler makes of `min` (mispredicted where a
            // point shares its cell with a nearer one).
            let (kept, key) = (&mut cell_key[c as usize], self.key(range[k], i));
            *kept = std::hint::select_unpredictable(key < *kept, key, *kept);
        }
        in_fov
    }
}

/// The point and the range a cell's key holds (range bits above point index; all ones for an
/// empty cell, whose low half is [`EMPTY`] already).
#[inline(always)]
fn split_key(k: u64) -> (u32, f32) {
    let range = match k {
        u64::MAX => 0.0,
        k => f32::from_bits((k >> 32) as u32),
    };
    (k as u32, range)
}
