//! PROJECT: each point's claim on its cell, the nearest point keeping it ([`super::project_impl`]).

use super::columns::{Geometry, OUTSIDE};
use super::{norm, PgmSpec, PointCells, EMPTY};
use crate::geom::Point3;

/// Points per block of the two-pass loop (columns and ranges, then cells).
const BLOCK: usize = 512;

/// Every point's claim on its cell: the key of the point each cell keeps, the cell of every
/// point (when kept) and the points in view ([`super::project_impl`]).
///
/// The point kept in each cell as one key, range bits above index: the smallest key is the
/// nearest point, the first of equally near ones (ranges are finite and >= 0, whose bits order
/// as their values), kept without a branch.
#[inline(always)]
pub(super) fn claim_cells(
    points: &[Point3],
    spec: &PgmSpec,
    point_cells: PointCells,
    (ring_ids, beams): (Option<&[u8]>, usize),
    geometry: Geometry<'_>,
) -> (Vec<u64>, Vec<u32>, u64) {
    let mut cell_key = vec![u64::MAX; spec.cells()];
    let keep_point_cells = point_cells == PointCells::Keep;
    // Every point's cell is written below, in the loop over all points (no fill first).
    let mut point_cell = Vec::with_capacity(if keep_point_cells { points.len() } else { 0 });
    let point_cell_out = &mut point_cell.spare_capacity_mut()[..];
    let mut in_fov = 0u64;
    // Cheap reject for maps narrower than 180 degrees: a point outside the front wedge.
    let wedge = spec.front_wedge().filter(|_| geometry.columns.is_none());
    let columns = spec.columns();
    let (rotate, scale) = (geometry.rotate, geometry.scale);
    // With the rows known and columns by azimuth, the first pass gives the cell itself: the
    // first cell of each beam's row, by beam.
    let row_start: Option<[i32; 256]> = match (ring_ids, geometry.columns) {
        (Some(_), None) => Some(std::array::from_fn(|b| {
            (spec.beam_row(b as u8, beams) * spec.cols).min(i32::MAX as usize) as i32
        })),
        _ => None,
    };
    let mut code = [0i32; BLOCK];
    let mut range = [0f32; BLOCK];
    for start in (0..points.len()).step_by(BLOCK) {
        let end = (start + BLOCK).min(points.len());
        let base = &geometry.base[start..end];
        let pts = &points[start..end];
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
        if let (Some(rs), Some(r)) = (&row_start, ring_ids) {
            // Cells: the code's column plus its row's first cell; OUTSIDE and BORDER kept.
            for (c, &ring) in code.iter_mut().zip(&r[start..end]) {
                *c = if *c >= 0 { *c + rs[ring as usize] } else { *c };
            }
        }
        for (k, p) in pts.iter().enumerate() {
            let i = start + k;
            let cell = match (code[k], &row_start) {
                (OUTSIDE, _) => None,
                // The cell from the first pass.
                (c, Some(_)) if c >= 0 => Some(c as usize),
                (code, _) => geometry.column(i, code, spec).map(|col| {
                    let row = match ring_ids {
                        Some(r) => spec.beam_row(r[i], beams),
                        None => spec.elevation_row(p, range[k]),
                    };
                    row * spec.cols + col
                }),
            };
            if keep_point_cells {
                point_cell_out[i].write(cell.map_or(EMPTY, |c| c as u32));
            }
            if let Some(c) = cell {
                in_fov += 1;
                let key = (u64::from(range[k].to_bits()) << 32) | i as u64;
                cell_key[c] = cell_key[c].min(key);
            }
        }
    }
    if keep_point_cells {
        // SAFETY: the loop above wrote the cell of every point.
        unsafe { point_cell.set_len(points.len()) };
    }
    (cell_key, point_cell, in_fov)
}

/// The point and the range of every cell from its key (range bits above point index; all ones
/// for an empty cell, whose low half is [`EMPTY`] already).
#[inline(always)]
pub(super) fn split_keys(cell_key: &[u64]) -> (Vec<u32>, Vec<f32>) {
    let point = cell_key.iter().map(|&k| k as u32).collect();
    let range = cell_key
        .iter()
        .map(|&k| match k {
            u64::MAX => 0.0,
            k => f32::from_bits((k >> 32) as u32),
        })
        .collect();
    (point, range)
}
