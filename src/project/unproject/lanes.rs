//! What the kernels that take several points at a time share: the padded map ([`Grid`]), the
//! numbers of the window ([`Setup`]), and the order the points are taken in ([`drive`]).

use super::{far, KnnParams, PointsInMap, Vote};
use crate::label::ClassId;
use crate::project::EMPTY;

/// The map's cell ranges (as the kNN compares them: empty cells infinitely far) and classes
/// with `h` cells of padding on every side (zero range, the padding's vote; or the columns
/// wrapped) and `lanes` more columns on the right, so that no window needs a bounds test and a
/// block of lanes starting at any column stays inside.
pub(super) struct Grid {
    pub far: Vec<f32>,
    pub cls: Vec<i32>,
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
        let mut grid_far = vec![0.0f32; rows * stride];
        let mut cls = vec![vote.pad_vote as i32; rows * stride];
        for r in 0..m.rows {
            let (src_range, src_cls) = (
                &m.cell_range[r * m.cols..(r + 1) * m.cols],
                &pred[r * m.cols..(r + 1) * m.cols],
            );
            let at = (r + h) * stride + h;
            for (d, &s) in grid_far[at..at + m.cols].iter_mut().zip(src_range) {
                *d = far(s);
            }
            for (d, &s) in cls[at..at + m.cols].iter_mut().zip(src_cls) {
                *d = s as i32;
            }
            if wrap {
                // The h columns beyond each side, taken from the other side.
                for c in 1..=h {
                    let (left, right) = (m.cols - c % m.cols.max(1), (c - 1) % m.cols);
                    grid_far[at - c] = far(src_range[left % m.cols]);
                    cls[at - c] = src_cls[left % m.cols] as i32;
                    grid_far[at + m.cols - 1 + c] = far(src_range[right]);
                    cls[at + m.cols - 1 + c] = src_cls[right] as i32;
                }
            }
        }
        Grid {
            far: grid_far,
            cls,
            stride,
        }
    }

    /// Where the window of the cell `cell` (`row * cols + col`) starts (its top-left cell).
    pub fn top_left(&self, cell: usize, cols: usize) -> usize {
        let (row, col) = (cell / cols, cell % cols);
        row * self.stride + col
    }
}

/// The numbers of a window of `N` cells: weights (the centre's 0: the point's own cell is at
/// distance 0, its range being finite), offsets in the grid, and the vote's rules.
pub(super) struct Setup<const N: usize> {
    pub w: [f32; N],
    pub off: [usize; N],
    /// Bit `c`: class `c` may win (at most 31 classes).
    pub can_win: u32,
    pub nobody: i32,
    pub first_winner: i32,
    pub cutoff: f32,
}

impl<const N: usize> Setup<N> {
    pub fn new(grid: &Grid, vote: &Vote, p: &KnnParams) -> Setup<N> {
        let s = p.window;
        let mut w: [f32; N] = vote.weights[..].try_into().expect("S x S weights");
        w[N / 2] = 0.0;
        let mut off = [0usize; N];
        for (j, o) in off.iter_mut().enumerate() {
            *o = (j / s) * grid.stride + j % s;
        }
        Setup {
            w,
            off,
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

/// Which points a block of lanes holds.
#[derive(Debug, Clone, Copy)]
pub(super) enum Block {
    /// The first points of `L` neighbouring cells of a row from this cell on: their windows
    /// side by side.
    Row(usize),
    /// Any points, each in its own cell.
    Scattered,
}

/// Takes the points `L` at a time (`u32::MAX` for an empty lane): the first point of every cell
/// by `L` neighbouring cells of a row, then the points behind a nearer one in their cell.
pub(super) fn drive<const L: usize>(m: &PointsInMap<'_>, mut block: impl FnMut(Block, &[u32; L])) {
    let mut first = vec![u32::MAX; m.rows * m.cols];
    let mut others = Vec::new();
    for (i, &c) in m.point_cell.iter().enumerate() {
        if c == EMPTY {
            continue;
        }
        match &mut first[c as usize] {
            f if *f == u32::MAX => *f = i as u32,
            _ => others.push(i as u32),
        }
    }
    for r in 0..m.rows {
        for col0 in (0..m.cols).step_by(L) {
            let at = r * m.cols + col0;
            let mut lanes = [u32::MAX; L];
            let n = (m.cols - col0).min(L);
            lanes[..n].copy_from_slice(&first[at..at + n]);
            if lanes.iter().any(|&l| l != u32::MAX) {
                block(Block::Row(at), &lanes);
            }
        }
    }
    for chunk in others.chunks(L) {
        let mut lanes = [u32::MAX; L];
        lanes[..chunk.len()].copy_from_slice(chunk);
        block(Block::Scattered, &lanes);
    }
}

/// The ranges of the lanes' points (0 for an empty lane).
#[inline]
pub(super) fn lane_ranges<const L: usize>(lanes: &[u32; L], point_range: &[f32]) -> [f32; L] {
    let mut r = [0.0f32; L];
    for (v, &l) in r.iter_mut().zip(lanes) {
        if l != u32::MAX {
            *v = point_range[l as usize];
        }
    }
    r
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

/// Writes each lane's winner to its point.
#[inline]
pub(super) fn store<const L: usize>(
    lanes: &[u32; L],
    winners: &[i32; L],
    out: &mut [Option<ClassId>],
) {
    for (l, &c) in lanes.iter().zip(winners) {
        if *l != u32::MAX {
            out[*l as usize] = Some(c as ClassId);
        }
    }
}
