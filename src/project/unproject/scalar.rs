//! The kNN one point at a time: any window, any k, any CPU (the reference the lane kernels are
//! tested against).

use super::{far, KnnParams, PointsInMap, Vote};
use crate::label::{ClassId, ClassMap};
use crate::project::EMPTY;

/// [`knn`] with the window (`S` x `S` = `N` cells) and `K` known at compile time.
pub(super) fn knn_fixed<const S: usize, const N: usize, const K: usize>(
    m: &PointsInMap<'_>,
    pred: &[ClassId],
    p: &KnnParams,
    classes: &ClassMap,
) -> Vec<Option<ClassId>> {
    let vote = Vote::new(p, classes);
    let w: [f32; N] = vote.weights[..].try_into().expect("S x S weights");
    let half = S / 2;
    let centre = half * S + half;
    let (rows, cols) = (m.rows, m.cols);
    let far: Vec<f32> = m.cell_range.iter().map(|&r| far(r)).collect();
    let mut out = Vec::with_capacity(m.point_cell.len());
    for (&cell, &r) in m.point_cell.iter().zip(m.point_range) {
        if cell == EMPTY {
            out.push(None);
            continue;
        }
        let (row, col) = (cell as usize / cols, cell as usize % cols);
        let mut dist = [0f32; N];
        let mut cls = [0usize; N];
        if row >= half && row + half < rows && col >= half && col + half < cols {
            // The common case: the window lies in the map; its rows are contiguous.
            let top = (row - half) * cols + col - half;
            for dy in 0..S {
                let base = top + dy * cols;
                let rr: &[f32; S] = far[base..base + S].try_into().expect("S cells");
                let pp: &[u8; S] = pred[base..base + S].try_into().expect("S cells");
                for x in 0..S {
                    dist[dy * S + x] = (rr[x] - r).abs() * w[dy * S + x];
                    cls[dy * S + x] = pp[x] as usize;
                }
            }
            dist[centre] = 0.0;
        } else {
            window(m, pred, p, &vote, (row, col, r), &mut dist, &mut cls);
        }
        let mut best = [u64::MAX; K];
        k_smallest(&dist, &mut best);
        let bd: [f32; K] = std::array::from_fn(|a| f32::from_bits((best[a] >> 32) as u32));
        let v: [usize; K] = std::array::from_fn(|a| cls[(best[a] & 0xFFFF_FFFF) as usize]);
        out.push(Some(vote.winner(&bd, &v, p.cutoff) as ClassId));
    }
    out
}

/// The K smallest distances of a window (K = `best.len()`), as keys: the distance's bits above
/// the window cell's index. A distance is never negative, so its bits order as it does, and
/// with the index every key is distinct: ties go to the earlier cell. Branch free: each key
/// passes down the sorted list, leaving the smaller behind. `best` must start at `u64::MAX`.
#[inline(always)]
fn k_smallest(dist: &[f32], best: &mut [u64]) {
    for (j, d) in dist.iter().enumerate() {
        let mut x = ((d.to_bits() as u64) << 32) | j as u64;
        for b in best.iter_mut() {
            let lo = (*b).min(x);
            x = (*b).max(x);
            *b = lo;
        }
    }
}

/// The distances and classes of the window around the point at `(row, col)` of range `r`,
/// row-major, any window: zero padding outside the map (or the columns wrapped), the centre
/// at distance 0.
fn window(
    m: &PointsInMap<'_>,
    pred: &[ClassId],
    p: &KnnParams,
    vote: &Vote,
    (row, col, r): (usize, usize, f32),
    dist: &mut [f32],
    cls: &mut [usize],
) {
    let s = p.window;
    let half = (s / 2) as isize;
    let (rows, cols) = (m.rows as isize, m.cols as isize);
    for dy in 0..s {
        for dx in 0..s {
            let j = dy * s + dx;
            let rr = row as isize + dy as isize - half;
            let mut cc = col as isize + dx as isize - half;
            if p.wrap_columns {
                cc = cc.rem_euclid(cols);
            }
            let (range, class) = if rr < 0 || rr >= rows || cc < 0 || cc >= cols {
                (0.0, vote.pad_vote)
            } else {
                let k = (rr * cols + cc) as usize;
                (far(m.cell_range[k]), pred[k] as usize)
            };
            dist[j] = (range - r).abs() * vote.weights[j];
            cls[j] = class;
        }
    }
    dist[(half as usize) * s + half as usize] = 0.0;
}

/// The vote of every point, any window and k (see the module docs).
pub(super) fn knn(
    m: &PointsInMap<'_>,
    pred: &[ClassId],
    p: &KnnParams,
    classes: &ClassMap,
) -> Vec<Option<ClassId>> {
    let vote = Vote::new(p, classes);
    let mut dist = vec![0f32; p.window * p.window];
    let mut cls = vec![0usize; p.window * p.window];
    let mut best = vec![u64::MAX; p.k];
    m.point_cell
        .iter()
        .zip(m.point_range)
        .map(|(&cell, &r)| {
            if cell == EMPTY {
                return None;
            }
            let (row, col) = (cell as usize / m.cols, cell as usize % m.cols);
            window(m, pred, p, &vote, (row, col, r), &mut dist, &mut cls);
            best.fill(u64::MAX);
            k_smallest(&dist, &mut best);
            let d: Vec<f32> = best
                .iter()
                .map(|b| f32::from_bits((b >> 32) as u32))
                .collect();
            let v: Vec<usize> = best
                .iter()
                .map(|b| cls[(b & 0xFFFF_FFFF) as usize])
                .collect();
            Some(vote.winner(&d, &v, p.cutoff) as ClassId)
        })
        .collect()
}
