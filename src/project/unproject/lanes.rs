//! What the kernels that take several points at a time share: the padded map ([`Grid`]), the
//! numbers of the window ([`Setup`]), and the order the points are taken in.
//!
//! A point's class depends on its cell and its range alone. So every cell's kept point (its
//! range the cell's) is voted for in blocks of `L` neighbouring cells of a row, their windows
//! read by plain loads ([`super::keys::Kernel::cell_winners`]), and a point at its cell's range
//! takes that cell's winner ([`point_pass`]); the points behind a nearer one in their cell (a
//! few in a hundred) go `L` at a time ([`scattered`]).

use super::{far, KnnParams, PointsInMap, Vote};
use crate::label::ClassId;
use crate::project::EMPTY;

/// The map's cell ranges (as the kNN compares them: empty cells infinitely far) and classes
/// with `h` cells of padding on every side (zero range, the padding's vote; or the columns
/// wrapped) and `lanes` more columns on the right, so that no window needs a bounds test and a
/// block of lanes starting at any column stays inside.
pub(super) struct Grid {
    pub far: Vec<f32>,
    /// Classes as bytes (a quarter of the memory of `i32`s to write and read), widened to
    /// lanes by the kernels.
    pub cls: Vec<u8>,
    pub stride: usize,
}

impl Grid {
    pub fn new(
        m: &PointsInMap<'_>,
        pred: &[ClassId],
        vote: &Vote,
        h: usize,
        wrap: bool,
        lanes: usize,
    ) -> Grid {
        let stride = m.cols + 2 * h + lanes;
        let rows = m.rows + 2 * h;
        // Written once, row by row (a fill of the whole grid first, then the map over it, cost
        // a few percent of a call).
        let (pad_far, pad_cls) = (0.0f32, vote.pad_vote as u8);
        let mut grid_far = Vec::with_capacity(rows * stride);
        let mut cls = Vec::with_capacity(rows * stride);
        grid_far.resize(h * stride, pad_far);
        cls.resize(h * stride, pad_cls);
        for r in 0..m.rows {
            let (src_range, src_cls) = (
                &m.cell_range[r * m.cols..(r + 1) * m.cols],
                &pred[r * m.cols..(r + 1) * m.cols],
            );
            // Source column `i` where the columns wrap, padding where they do not.
            let edge = |i: usize| match wrap {
                true => (far(src_range[i]), src_cls[i]),
                false => (pad_far, pad_cls),
            };
            let cols = m.cols.max(1);
            // The h columns left of the map (the last ones), the map's, the h right of it (the
            // first ones), then the lanes' columns.
            let left = (1..=h).rev().map(|c| edge((cols - c % cols) % cols));
            let right = (1..=h).map(|c| edge((c - 1) % cols));
            for (f, k) in left {
                grid_far.push(f);
                cls.push(k);
            }
            grid_far.extend(src_range.iter().map(|&s| far(s)));
            cls.extend_from_slice(src_cls);
            for (f, k) in right {
                grid_far.push(f);
                cls.push(k);
            }
            grid_far.resize(grid_far.len() + lanes, pad_far);
            cls.resize(cls.len() + lanes, pad_cls);
        }
        grid_far.resize(rows * stride, pad_far);
        cls.resize(rows * stride, pad_cls);
        Grid {
            far: grid_far,
            cls,
            stride,
        }
    }
}

impl Grid {
    /// Where the window of the cell `cell` (`row * cols + col`) starts (its top-left cell).
    pub fn top_left(&self, cell: usize, cols: usize) -> usize {
        let (row, col) = (cell / cols, cell % cols);
        row * self.stride + col
    }
}

/// The numbers of a window of `N` cells: weights (the centre's 0; the kernels put the centre at
/// distance 0 themselves, as its cell's range may be 0) and the vote's rules.
pub(super) struct Setup<const N: usize> {
    pub w: [f32; N],
    /// Bit `c`: class `c` may win (at most 31 classes).
    pub can_win: u32,
    pub nobody: i32,
    pub first_winner: i32,
    pub cutoff: f32,
}

impl<const N: usize> Setup<N> {
    pub fn new(vote: &Vote, p: &KnnParams) -> Setup<N> {
        let mut w: [f32; N] = vote.weights[..].try_into().expect("S x S weights");
        w[N / 2] = 0.0;
        Setup {
            w,
            can_win: vote
                .can_win
                .iter()
                .enumerate()
                .fold(0u32, |mask, (c, &yes)| mask | ((yes as u32) << c)),
            nobody: vote.nobody as i32,
            first_winner: vote.first_winner as i32,
            cutoff: p.cutoff,
        }
    }
}

/// The points `others` (behind a nearer one in their cell), `L` at a time, each in its own
/// window: their classes into `out`. `vote(lanes, ranges, used)`: the winners of a block's
/// points (`u32::MAX`: none), from their ranges, `used` the lanes (bit mask) that hold a point.
pub(super) fn scattered<const L: usize>(
    m: &PointsInMap<'_>,
    others: &[u32],
    out: &mut [Option<ClassId>],
    mut vote: impl FnMut(&[u32; L], &[f32; L], u32) -> [i32; L],
) {
    for chunk in others.chunks(L) {
        let (mut lanes, mut ranges) = ([u32::MAX; L], [0.0f32; L]);
        for ((lane, range), &i) in lanes.iter_mut().zip(&mut ranges).zip(chunk) {
            (*lane, *range) = (i, m.point_range[i as usize]);
        }
        let used = (1u32 << chunk.len()).wrapping_sub(1);
        let won = vote(&lanes, &ranges, used);
        for (&i, &w) in chunk.iter().zip(&won) {
            out[i as usize] = Some(w as ClassId);
        }
    }
}

/// The winner of every cell's kept point (row-major), and [`CellWinners::PAD`] more entries, so
/// that a vector's lanes (sixteen bytes at most) can be written from any cell's on.
pub(super) struct CellWinners(pub Vec<ClassId>);

impl CellWinners {
    pub const PAD: usize = 15;
}

/// The pass over the points `from..` (the scalar one): a point at its cell's range takes the
/// cell's winner (into `out`); the others (their index, into `others`) are voted for on their
/// own.
pub(super) fn point_pass(
    m: &PointsInMap<'_>,
    winners: &CellWinners,
    from: usize,
    out: &mut [Option<ClassId>],
    others: &mut Vec<u32>,
) {
    let points = (m.point_cell[from..].iter().zip(&m.point_range[from..])).zip(&mut out[from..]);
    for (i, ((&c, &r), o)) in (from..).zip(points) {
        if c == EMPTY {
            continue;
        }
        let kept = m.cell_range[c as usize];
        if r.to_bits() == kept.to_bits() && kept > 0.0 {
            *o = Some(winners.0[c as usize]);
        } else {
            others.push(i as u32);
        }
    }
}

/// Where each lane's window starts in `grid` (0 for an empty lane).
#[inline]
pub(super) fn window_starts<const L: usize>(
    grid: &Grid,
    m: &PointsInMap<'_>,
    lanes: &[u32; L],
) -> [i32; L] {
    let mut starts = [0i32; L];
    for (s, &l) in starts.iter_mut().zip(lanes) {
        if l != u32::MAX {
            *s = grid.top_left(m.point_cell[l as usize] as usize, m.cols) as i32;
        }
    }
    starts
}
