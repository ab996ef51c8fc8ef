//! `unproject`: a map prediction carried back to every point, and its arguments' checks.

use numpy::PyArray1;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

use kitti2pgm::geom::Point3;
use kitti2pgm::project::{norm, EMPTY};

use crate::arrays::{self, PointRows};
use crate::{named, py_err, readers};

/// Carries a map prediction back to every point of the scan it was projected from.
///
/// pred: (H, W) class ids (a model's label map); row, col: (N,) each point's cell, as `project`
/// returns them (-1 outside the map); points: (N, 3+) the scan (its ranges are computed as the
/// map's); cell_range: (H, W) the map's range channel (`m["map"][..., 4]`), needed by "knn".
/// method: "knn" (the default, as `kitti2pgm unproject`'s: RangeNet++'s post-processing, its
/// result point for point: k nearest by range in a window around the cell, Gaussian-weighted,
/// neighbours beyond cutoff vote for nobody, the class map's ignored classes never win) or
/// "cell" (a point takes its cell's class).
/// class_map: the classes (a name or yaml path); wrap_columns: neighbours across the 360-degree
/// seam (the reference pads with zeros there).
///
/// Returns (N,) int16: each point's class, -1 for points outside the map ("not predicted").
#[pyfunction]
#[pyo3(signature = (pred, row, col, points, cell_range=None, *, method="knn", class_map="semantic-kitti",
    k=5, window=5, sigma=1.0, cutoff=1.0, wrap_columns=false))]
// One Rust argument per Python keyword: the signature is the Python API.
#[allow(clippy::too_many_arguments)]
pub(crate) fn unproject<'py>(
    py: Python<'py>,
    pred: &Bound<'py, PyAny>,
    row: &Bound<'py, PyAny>,
    col: &Bound<'py, PyAny>,
    points: &Bound<'py, PyAny>,
    cell_range: Option<&Bound<'py, PyAny>>,
    method: &str,
    class_map: &str,
    k: usize,
    window: usize,
    sigma: f32,
    cutoff: f32,
    wrap_columns: bool,
) -> PyResult<Bound<'py, PyArray1<i16>>> {
    use kitti2pgm::project::unproject::{unproject as run, KnnParams, MethodKind, PointsInMap};
    let (pred, h, w) = arrays::grid_arg::<u8>(pred, "pred")?;
    // Each point's range and cell in one pass over the points, row and col, read in place.
    let (point_range, point_cell) = arrays::with_point_rows(points, "points", |rows| {
        let n = rows.len();
        arrays::with_vec::<i32, _>(row, "row", n, |row| {
            arrays::with_vec::<i32, _>(col, "col", n, |col| match rows {
                PointRows::Three(p) => ranges_and_cells(p, row, col, (h, w)),
                PointRows::Four(p) => ranges_and_cells(p, row, col, (h, w)),
            })
        })
    })?;
    let method = named::<MethodKind>("method", method)?.with(KnnParams {
        k,
        window,
        sigma,
        cutoff,
        wrap_columns,
    });
    let cell_range = match cell_range {
        Some(c) => cell_range_arg(c, (h, w))?,
        None if method.kind() == MethodKind::Knn => {
            return Err(PyValueError::new_err(
                "method 'knn' needs cell_range: the map's range channel (m['map'][..., 4])",
            ))
        }
        None => vec![0.0; h * w],
    };
    let classes = readers::class_map_of(class_map)?;
    let labels = py
        .detach(|| {
            let m = PointsInMap {
                rows: h,
                cols: w,
                point_cell: &point_cell,
                point_range: &point_range,
                cell_range: &cell_range,
            };
            run(&m, &pred, &method, &classes)
        })
        .map_err(py_err)?;
    // AVX2 at most: compiled for AVX-512, this loop built a mask register from the `Option`
    // tags bit by bit (a tenth of a kNN call; 0.88 -> 1.00 ms).
    let out: Vec<i16> = arrays::with_avx2(
        #[inline(always)]
        || arrays::map_exact(&labels, |l| l.map_or(-1, i16::from)),
    );
    Ok(PyArray1::from_vec(py, out))
}

/// `unproject`'s `cell_range`: an `h x w` float32 map's range channel, finite and >= 0 (0 in
/// empty cells), copied and checked in one branch-free pass (the bad value looked for only
/// when there is one).
fn cell_range_arg(c: &Bound<'_, PyAny>, (h, w): (usize, usize)) -> PyResult<Vec<f32>> {
    arrays::with_grid::<f32, _>(c, "cell_range", |v, ch, cw| {
        if (ch, cw) != (h, w) {
            return Err(PyValueError::new_err(format!(
                "cell_range is {ch}x{cw}, pred is {h}x{w}"
            )));
        }
        // Copied and checked in one pass.
        let bad = |r: f32| !(r.is_finite() & (r >= 0.0));
        let (copy, any_bad) = arrays::with_simd(
            #[inline(always)]
            || {
                let mut any_bad = false;
                let copy = arrays::map_exact(v, |r| {
                    any_bad |= bad(r);
                    r
                });
                (copy, any_bad)
            },
        );
        if !any_bad {
            return Ok(copy);
        }
        let i = v.iter().position(|&r| bad(r)).expect("one value is bad");
        Err(PyValueError::new_err(format!(
            "cell_range: value {} at cell ({}, {}) is not a range (finite, >= 0)",
            v[i],
            i / w,
            i % w
        )))
    })
}

/// The range of every point ([`kitti2pgm::project::norm`], as the map's) and its cell
/// (`row * w + col`) from `project`'s row and col arrays (-1, -1: outside the map); an error
/// for a cell outside the `h x w` prediction.
fn ranges_and_cells<const C: usize>(
    points: &[[f32; C]],
    row: &[i32],
    col: &[i32],
    (h, w): (usize, usize),
) -> PyResult<(Vec<f32>, Vec<u32>)> {
    // One branch-free pass (the widest vectors the CPU has) that only notes whether a point is
    // bad; the first is looked for and named after it (a `Result` per element made this the
    // Python call's second largest cost). `&`, not `&&`: no branch, so the pass vectorises.
    let n = points.len();
    assert!(
        row.len() == n && col.len() == n,
        "one row and col a point (checked)"
    );
    let (h32, w32) = (h as u32, w as u32);
    let in_map = move |r: i32, c: i32| ((r as u32) < h32) & ((c as u32) < w32);
    let bad_point = move |r: i32, c: i32| !in_map(r, c) & !((r == -1) & (c == -1));
    // (`move`: the bounds are the pass's own values, which no store of it can change)
    let (ranges, cells, any_bad) = arrays::with_simd(
        #[inline(always)]
        move || {
            let (mut ranges, mut cells) = (Vec::with_capacity(n), Vec::with_capacity(n));
            let mut any_bad = false;
            let slots = (ranges.spare_capacity_mut()[..n].iter_mut())
                .zip(&mut cells.spare_capacity_mut()[..n]);
            for ((((range, cell), p), &r), &c) in slots.zip(points).zip(row).zip(col) {
                range.write(norm(&Point3::new(p[0], p[1], p[2])));
                any_bad |= bad_point(r, c);
                let at = (r as u32).wrapping_mul(w32).wrapping_add(c as u32);
                cell.write(if in_map(r, c) { at } else { EMPTY });
            }
            // SAFETY: the loop wrote the first `n` slots of both (the four of one length).
            unsafe {
                ranges.set_len(n);
                cells.set_len(n);
            }
            (ranges, cells, any_bad)
        },
    );
    if !any_bad {
        return Ok((ranges, cells));
    }
    let (i, (&r, &c)) = (row.iter().zip(col).enumerate())
        .find(|(_, (&r, &c))| bad_point(r, c))
        .expect("one point is bad");
    Err(PyValueError::new_err(format!(
        "point {i} is in cell ({r}, {c}), outside the {h}x{w} prediction"
    )))
}
