//! Back from the map to every point: the class a range-image prediction gives each point of the
//! scan (users are scored on points, not cells).
//!
//! [`Method::Cell`]: a point takes its cell's class. [`Method::Knn`]: RangeNet++'s
//! post-processing (lidar-bonnetal `postproc/KNN.py`), the reference's result point for point:
//!
//! - the `window x window` cells around the point's cell, in row-major order, the centre taking
//!   the point's own range (a point that lost its cell to a nearer one keeps its range);
//! - a cell outside the map is zero padding (range 0, class 0); an empty cell has an infinite
//!   range;
//! - distance = `|range - point range| * (1 - g)`, `g` the normalised Gaussian kernel of `sigma`
//!   over the window (computed in double precision and rounded to single, where the reference
//!   computes it in single: they differ by at most one unit in the last place);
//! - the `k` nearest by distance (ties: the earlier cell of the window; the reference leaves
//!   them to `torch.topk`);
//! - with `cutoff > 0`, a neighbour farther than `cutoff` votes for nobody;
//! - the class with most votes among the classes that may win (the class map's non-ignored
//!   classes: SemanticKITTI's all but 0 `unlabeled`, as the reference's `[1:-1]`), ties to the
//!   lower id; no vote at all gives the first such class (the reference's `argmax` of zeros).
//!
//! Deliberate differences, behind options and off by default: [`KnnParams::wrap_columns`] takes
//! the neighbours across the 360-degree seam instead of zero padding. For a class map whose class
//! 0 may win (the paper's `background`), padding votes for nobody rather than for class 0.
//!
//! Points outside the map's field of view get no class (`None`: "not predicted").

#[cfg(target_arch = "x86_64")]
mod avx2;
#[cfg(target_arch = "x86_64")]
mod avx512;
#[cfg(target_arch = "x86_64")]
mod keys;
#[cfg(target_arch = "x86_64")]
mod lanes;
mod scalar;
#[cfg(target_arch = "x86_64")]
mod vectors;

use crate::error::{Error, Result};
use crate::label::{ClassId, ClassMap};
use crate::simd::first_where;

use super::EMPTY;

/// RangeNet++'s kNN parameters (its defaults: k 5, window 5, sigma 1.0, cutoff 1.0).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct KnnParams {
    /// Neighbours that vote.
    pub k: usize,
    /// Side of the search window, cells (odd).
    pub window: usize,
    /// Standard deviation of the Gaussian that down-weights far cells of the window, cells.
    pub sigma: f32,
    /// Neighbours whose weighted range difference is above this vote for nobody (<= 0: none
    /// is cut off).
    pub cutoff: f32,
    /// Take the window across the left and right edges of a 360-degree map (the reference pads
    /// with zeros there).
    pub wrap_columns: bool,
}

impl Default for KnnParams {
    fn default() -> Self {
        KnnParams {
            k: 5,
            window: 5,
            sigma: 1.0,
            cutoff: 1.0,
            wrap_columns: false,
        }
    }
}

impl KnnParams {
    /// Checks the numbers.
    pub fn validate(&self) -> Result<()> {
        let bad = |m: String| Err(Error::Config(m));
        if self.window.is_multiple_of(2) || self.window > 31 {
            return bad(format!("kNN window {} must be odd, 1 to 31", self.window));
        }
        if self.k == 0 || self.k > self.window * self.window {
            return bad(format!(
                "kNN k {} must be 1 to {} (the window's cells)",
                self.k,
                self.window * self.window
            ));
        }
        if !(self.sigma > 0.0 && self.sigma.is_finite()) {
            return bad(format!(
                "kNN sigma {} must be a positive number",
                self.sigma
            ));
        }
        if !self.cutoff.is_finite() {
            return bad(format!("kNN cutoff {} must be finite", self.cutoff));
        }
        Ok(())
    }

    /// `1 - g` for each cell of the window, row-major: `g` the Gaussian of `sigma` around the
    /// window's centre, normalised to sum 1.
    pub fn weights(&self) -> Vec<f32> {
        let s = self.window;
        let mean = (s as f64 - 1.0) / 2.0;
        let var = (self.sigma as f64).powi(2);
        let g: Vec<f64> = (0..s * s)
            .map(|i| {
                let (y, x) = ((i / s) as f64, (i % s) as f64);
                (1.0 / (2.0 * std::f64::consts::PI * var))
                    * (-((x - mean).powi(2) + (y - mean).powi(2)) / (2.0 * var)).exp()
            })
            .collect();
        let sum: f64 = g.iter().sum();
        g.iter().map(|v| 1.0 - (v / sum) as f32).collect()
    }
}

/// How a point's class is found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Method {
    /// Its cell's class.
    Cell,
    /// RangeNet++'s kNN vote.
    Knn(KnnParams),
}

impl Method {
    /// Checks the parameters (the kNN's): an [`Error::Config`] before any work.
    pub fn validate(&self) -> Result<()> {
        match self {
            Method::Cell => Ok(()),
            Method::Knn(p) => p.validate(),
        }
    }

    /// The method's name.
    pub fn kind(&self) -> MethodKind {
        match self {
            Method::Cell => MethodKind::Cell,
            Method::Knn(_) => MethodKind::Knn,
        }
    }
}

/// A [`Method`] by name, without its parameters (the CLI's and the Python module's choice).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MethodKind {
    /// [`Method::Cell`].
    Cell,
    /// [`Method::Knn`].
    Knn,
}

crate::named_enum!(MethodKind, "unprojection method", [
    Cell => "cell" [] "The class of the point's cell",
    Knn => "knn" [] "RangeNet++'s kNN post-processing (its result point for point)",
]);

impl MethodKind {
    /// The method, with `knn`'s parameters for the kNN.
    pub fn with(self, knn: KnnParams) -> Method {
        match self {
            MethodKind::Cell => Method::Cell,
            MethodKind::Knn => Method::Knn(knn),
        }
    }
}

/// A scan in its map: where each point went, and the ranges the kNN compares.
#[derive(Debug, Clone, Copy)]
pub struct PointsInMap<'a> {
    /// Map rows.
    pub rows: usize,
    /// Map columns.
    pub cols: usize,
    /// The cell (`row * cols + col`) of every point; [`EMPTY`] outside the field of view.
    pub point_cell: &'a [u32],
    /// Each point's range, metres.
    pub point_range: &'a [f32],
    /// Range of the point kept in each cell, metres; 0 (or less) for an empty cell.
    pub cell_range: &'a [f32],
}

impl<'a> PointsInMap<'a> {
    /// The points of `proj` (made [`with point cells`](super::project_with_point_cells)), whose
    /// ranges are `point_range`.
    pub fn of(proj: &'a super::Projection, point_range: &'a [f32]) -> PointsInMap<'a> {
        PointsInMap {
            rows: proj.spec.rows,
            cols: proj.spec.cols,
            point_cell: &proj.point_cell,
            point_range,
            cell_range: &proj.cell_range,
        }
    }
}

/// The class of every point (`None`: outside the map) from `pred`, the predicted class of each
/// cell (row-major), for a map of the classes of `classes`.
pub fn unproject(
    m: &PointsInMap<'_>,
    pred: &[ClassId],
    method: &Method,
    classes: &ClassMap,
) -> Result<Vec<Option<ClassId>>> {
    check_inputs(m, pred, classes)?;
    match method {
        Method::Cell => Ok(m
            .point_cell
            .iter()
            .map(|&c| (c != EMPTY).then(|| pred[c as usize]))
            .collect()),
        Method::Knn(p) => {
            p.validate()?;
            Ok(knn_unchecked(m, pred, p, classes, KnnKernel::best()))
        }
    }
}

/// The inputs' lengths against the map, the predicted classes against the class map, and the
/// points' cells against the map (the lane kernels read without bounds tests).
fn check_inputs(m: &PointsInMap<'_>, pred: &[ClassId], classes: &ClassMap) -> Result<()> {
    let cells = m.rows * m.cols;
    let check = |what: &str, n: usize, want: usize| {
        if n == want {
            Ok(())
        } else {
            Err(Error::Config(format!(
                "{what} has {n} entries, expected {want}"
            )))
        }
    };
    check("the prediction", pred.len(), cells)?;
    check("the point ranges", m.point_range.len(), m.point_cell.len())?;
    check("the cell ranges", m.cell_range.len(), cells)?;
    // Compares at the values' own width (as `usize` they took four lanes a vector, not 32).
    let n_classes = u8::try_from(classes.len()).unwrap_or(u8::MAX);
    let past_classes = classes.len() <= u8::MAX as usize;
    if let Some(i) = first_where(pred, |&c| past_classes & (c >= n_classes)) {
        return Err(Error::Config(format!(
            "cell ({}, {}) is predicted as class {}, the map {:?} has {}",
            i / m.cols,
            i % m.cols,
            pred[i],
            classes.name,
            classes.len()
        )));
    }
    // (`EMPTY` is `u32::MAX`, which no more cells than that make a cell.)
    let cells32 = u32::try_from(cells).unwrap_or(u32::MAX);
    if let Some(i) = first_where(m.point_cell, |&c| (c != EMPTY) & (c >= cells32)) {
        return Err(Error::Config(format!(
            "point {i} is in cell {}, beyond the map's {cells}",
            m.point_cell[i]
        )));
    }
    Ok(())
}

/// Which code runs the kNN: the scalar code, or several points at a time where the CPU can (the
/// same classes, bit for bit; the scalar code serves the shapes and machines the others do not).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum KnnKernel {
    /// One point at a time, any CPU.
    Scalar,
    /// Eight points at a time (AVX2, x86-64), for the usual windows (3, 5 and 7 with k equal to
    /// the side) and class maps of at most 31 classes; the scalar code otherwise.
    Avx2,
    /// Sixteen points at a time (AVX-512F), the same windows and class maps.
    Avx512,
}

impl KnnKernel {
    /// The fastest this machine runs.
    pub fn best() -> KnnKernel {
        *KnnKernel::available().last().expect("the scalar kernel")
    }

    /// The kernels this machine runs, slowest first.
    pub fn available() -> Vec<KnnKernel> {
        let mut v = vec![KnnKernel::Scalar];
        #[cfg(target_arch = "x86_64")]
        {
            if avx2::available() {
                v.push(KnnKernel::Avx2);
            }
            if avx512::available() {
                v.push(KnnKernel::Avx512);
            }
        }
        v
    }
}

/// The kNN vote of every point by `kernel` (the parameters validated).
///
/// # Panics
/// Where [`unproject`] says the inputs are wrong (lengths, classes, cells), with its message:
/// the lane kernels read the map without bounds tests.
pub fn knn_with(
    m: &PointsInMap<'_>,
    pred: &[ClassId],
    p: &KnnParams,
    classes: &ClassMap,
    kernel: KnnKernel,
) -> Vec<Option<ClassId>> {
    if let Err(e) = check_inputs(m, pred, classes) {
        panic!("knn_with: {e}");
    }
    knn_unchecked(m, pred, p, classes, kernel)
}

/// [`knn_with`] of inputs checked by the caller.
fn knn_unchecked(
    m: &PointsInMap<'_>,
    pred: &[ClassId],
    p: &KnnParams,
    classes: &ClassMap,
    kernel: KnnKernel,
) -> Vec<Option<ClassId>> {
    if m.rows * m.cols == 0 {
        // No cell, so no point in the map (the cells are checked): nothing to vote on (and no
        // column to wrap the seam with).
        return vec![None; m.point_cell.len()];
    }
    #[cfg(target_arch = "x86_64")]
    if kernel != KnnKernel::Scalar
        && KnnKernel::available().contains(&kernel)
        && classes.len() <= 31
        && matches!((p.window, p.k), (3, 3) | (5, 5) | (7, 7))
    {
        let vote = Vote::new(p, classes);
        let mut out = vec![None; m.point_cell.len()];
        let o = &mut out;
        // SAFETY (each call): the CPU has the kernel's instructions, checked just above.
        match (kernel, p.window) {
            (KnnKernel::Avx512, 5) => unsafe { avx512::knn::<5, 25, 5>(m, pred, p, &vote, o) },
            (KnnKernel::Avx512, 3) => unsafe { avx512::knn::<3, 9, 3>(m, pred, p, &vote, o) },
            (KnnKernel::Avx512, _) => unsafe { avx512::knn::<7, 49, 7>(m, pred, p, &vote, o) },
            (_, 5) => unsafe { avx2::knn::<5, 25, 5>(m, pred, p, &vote, o) },
            (_, 3) => unsafe { avx2::knn::<3, 9, 3>(m, pred, p, &vote, o) },
            (_, _) => unsafe { avx2::knn::<7, 49, 7>(m, pred, p, &vote, o) },
        }
        return out;
    }
    let _ = kernel;
    // RangeNet++'s defaults, and the other usual windows, with the sizes known to the compiler
    // (arrays on the stack, loops unrolled); any other shape in general code.
    match (p.window, p.k) {
        (5, 5) => scalar::knn_fixed::<5, 25, 5>(m, pred, p, classes),
        (3, 3) => scalar::knn_fixed::<3, 9, 3>(m, pred, p, classes),
        (7, 7) => scalar::knn_fixed::<7, 49, 7>(m, pred, p, classes),
        _ => scalar::knn(m, pred, p, classes),
    }
}

/// What every kNN kernel shares: who may win, what padding votes for, the weights.
struct Vote {
    can_win: Vec<bool>,
    first_winner: usize,
    nobody: usize,
    pad_vote: usize,
    weights: Vec<f32>,
}

/// A cell's range as the kNN compares it: an empty cell (range 0) is infinitely far.
#[inline(always)]
fn far(cell_range: f32) -> f32 {
    if cell_range > 0.0 {
        cell_range
    } else {
        f32::INFINITY
    }
}

impl Vote {
    fn new(p: &KnnParams, classes: &ClassMap) -> Vote {
        let n_classes = classes.len();
        let can_win: Vec<bool> = (0..n_classes)
            .map(|c| !classes.ignore.contains(&(c as ClassId)))
            .collect();
        Vote {
            first_winner: can_win.iter().position(|&w| w).unwrap_or(0),
            nobody: n_classes,
            // Zero padding votes for class 0, which cannot win where it is ignored (the
            // reference's `unlabeled`); elsewhere it votes for nobody.
            pad_vote: if can_win.first() == Some(&false) {
                0
            } else {
                n_classes
            },
            can_win,
            weights: p.weights(),
        }
    }

    /// The winner among `n` chosen neighbours (distances `d`, classes `v`): most votes among
    /// the classes that may win, ties to the lower id; no vote gives the first such class.
    #[inline(always)]
    fn winner(&self, d: &[f32], v: &[usize], cutoff: f32) -> usize {
        let (mut winner, mut most) = (self.first_winner, 0usize);
        let cls = |i: usize| {
            if cutoff > 0.0 && d[i] > cutoff {
                self.nobody
            } else {
                v[i]
            }
        };
        for a in 0..d.len() {
            let c = cls(a);
            if c >= self.nobody || !self.can_win[c] {
                continue;
            }
            let count = (0..d.len()).filter(|&b| cls(b) == c).count();
            if count > most || (count == most && c < winner) {
                winner = c;
                most = count;
            }
        }
        winner
    }
}

#[cfg(test)]
mod tests;
