//! PROJECT: each point's claim on its cell, the nearest point keeping it ([`super::project_impl`]).

use std::mem::MaybeUninit;

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
}

/// Every point's claim on its cell ([`claim_cells`]), the points split among up to `threads`
/// threads (each part claims cells of its own, the parts' keys merged by their minimum: the
/// same result, the keys holding each point's index in the whole cloud).
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
                    range.start,
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
    let (cell_point, cell_range) = merge_keys(keys, threads);
    Claimed {
        cell_point,
        cell_range,
        point_cell,
        in_fov,
    }
}

/// The point and range of every cell from the parts' keys: their minimum ([`split_key`]), in
/// up to `threads` bands of cells at once.
fn merge_keys(mut keys: Vec<Vec<u64>>, threads: usize) -> (Vec<u32>, Vec<f32>) {
    let mut first = keys.remove(0);
    if keys.is_empty() {
        // One part: collected straight from its keys (no zero fill first).
        return crate::simd::with_simd(
            #[inline(always)]
            || {
                let point = first.iter().map(|&k| split_key(k).0).collect();
                (point, first.iter().map(|&k| split_key(k).1).collect())
            },
        );
    }
    let cells = first.len();
    let (mut point, mut range) = (vec![0u32; cells], vec![0f32; cells]);
    let band = cells.div_ceil(threads.max(1)).max(1);
    let bands = first.par_chunks_mut(band).zip(point.par_chunks_mut(band));
    bands
        .zip(range.par_chunks_mut(band))
        .enumerate()
        .for_each(|(b, ((k, p), r))| {
            crate::simd::with_simd(
                #[inline(always)]
                || {
                    for other in &keys {
                        for (k, o) in k.iter_mut().zip(&other[b * band..]) {
                            *k = (*k).min(*o);
                        }
                    }
                    for ((&k, p), r) in k.iter().zip(p).zip(r) {
                        (*p, *r) = split_key(k);
                    }
                },
            )
        });
    (point, range)
}

/// Every point's claim on its cell: the key of the point each cell keeps into `cell_key` (the
/// map's cells and a spare one), the cell of every point into `point_cell_out` (when not
/// empty); returns the points in view. `first` is the index of `points[0]` in the cloud.
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
    first: usize,
    cell_key: &mut [u64],
    point_cell: &mut [MaybeUninit<u32>],
) -> u64 {
    assert_eq!(
        cell_key.len(),
        spec.cells() + 1,
        "the map's cells and a spare one"
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
        // The first cell of each beam's row, by beam, where the first pass gives the cells.
        row_start: match (rings, geometry.columns) {
            (Some(_), None) => Some(std::array::from_fn(|b| {
                let first = spec.beam_row(b as u8, beams) * spec.cols;
                // (a beam past the sensor's is never looked up: the rings are checked)
                first.min(u32::MAX as usize / 2) as u32
            })),
            _ => None,
        },
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
            let cols = self.spec.cols as u32;
            for ((c, &code), &ring) in cell.iter_mut().zip(code).zip(rings) {
                *c = at(code, u32::from(ring) * cols);
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
                point_cell[i].write(if inside { c } else { EMPTY });
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
