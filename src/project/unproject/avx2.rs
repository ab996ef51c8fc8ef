//! The kNN vote eight points at a time (AVX2), the same result as the scalar code bit for bit
//! (tested against it on real scans).
//!
//! Each lane is a point. The window's ranges and classes come from a copy of the map padded with
//! the window's half-width on every side ([`Grid`]: zero-range padding voting for the padding's
//! class, or the columns wrapped), so that no window needs a bounds test. The first point of each
//! cell is taken eight neighbouring cells at a time, their windows read by plain vector loads; the
//! points that share a cell with a nearer one are taken eight at a time by gathers. The `K`
//! nearest are kept sorted per lane: a candidate, coming after every kept one in window order,
//! goes in front of the kept ones it is strictly nearer than (ties stay with the earlier cell, the
//! scalar rule), by compares and blends, no branch. Distances are compared as their bits
//! (non-negative floats order as their bits; the empty slot is `i32::MAX`, above infinity).

use std::arch::x86_64::*;

use super::lanes::{drive, lane_ranges, store, window_starts, Block, Grid, Setup};
use super::{KnnParams, PointsInMap, Vote};
use crate::label::ClassId;

/// Whether this machine runs the AVX2 path.
pub(super) fn available() -> bool {
    is_x86_feature_detected!("avx2")
}

/// The kNN class of every point (`S` x `S` = `N` window, `K` nearest), into `out` (one slot per
/// point, `None` already where the point is outside the map). The class map has at most 31
/// classes (their "may win" set is a bit mask).
///
/// # Safety
/// The CPU must have AVX2 ([`available`]).
#[target_feature(enable = "avx2")]
pub(super) unsafe fn knn<const S: usize, const N: usize, const K: usize>(
    m: &PointsInMap<'_>,
    pred: &[ClassId],
    p: &KnnParams,
    vote: &Vote,
    out: &mut [Option<ClassId>],
) {
    let grid = Grid::new(m, pred, vote, S / 2, p.wrap_columns, 8);
    let k = Kernel::<S, N, K>(Setup::new(&grid, vote, p));
    drive::<8>(m, |block, lanes| {
        // SAFETY: this function runs with AVX2.
        unsafe {
            let r = _mm256_loadu_ps(lane_ranges(lanes, m.point_range).as_ptr());
            let winners = match block {
                Block::Row(at) => k.vote_row(&grid, r, grid.top_left(at, m.cols)),
                Block::Scattered => {
                    let starts = window_starts(&grid, m, lanes);
                    let starts = _mm256_loadu_si256(starts.as_ptr() as *const __m256i);
                    k.vote_cells(&grid, r, starts)
                }
            };
            let mut w = [0i32; 8];
            _mm256_storeu_si256(w.as_mut_ptr() as *mut __m256i, winners);
            store(lanes, &w, out)
        }
    });
}

/// The window's shape in the type: `S` x `S` = `N` cells, `K` nearest.
struct Kernel<const S: usize, const N: usize, const K: usize>(Setup<N>);

impl<const S: usize, const N: usize, const K: usize> Kernel<S, N, K> {
    /// Nothing kept yet: every slot farther than anything (`i32::MAX`, above infinity's bits).
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn empty() -> ([__m256i; K], [__m256i; K]) {
        (
            [_mm256_set1_epi32(i32::MAX); K],
            [_mm256_setzero_si256(); K],
        )
    }

    /// The distance bits of window cell `j` from its ranges `far` (the centre's weight is 0:
    /// the point's own cell is at distance 0, its range being finite).
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn dist(&self, far: __m256, r: __m256, j: usize) -> __m256i {
        let abs = _mm256_castsi256_ps(_mm256_set1_epi32(0x7fff_ffff));
        let diff = _mm256_and_ps(_mm256_sub_ps(far, r), abs);
        _mm256_castps_si256(_mm256_mul_ps(diff, _mm256_set1_ps(self.0.w[j])))
    }

    /// Keeps the candidate (distance bits `d`, class `cls`) among the `K` nearest: it goes in
    /// front of the kept entries it is strictly nearer than (it comes after all of them in
    /// window order).
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn insert(bd: &mut [__m256i; K], bc: &mut [__m256i; K], d: __m256i, cls: __m256i) {
        // Distances: entry i becomes the median of entry i - 1, the candidate and entry i (all
        // non-negative: signed min and max order them as their bits); classes follow the masks.
        let mut lt = _mm256_cmpgt_epi32(bd[K - 1], d);
        for i in (1..K).rev() {
            let lt_prev = _mm256_cmpgt_epi32(bd[i - 1], d);
            let from_c = _mm256_blendv_epi8(cls, bc[i - 1], lt_prev);
            bc[i] = _mm256_blendv_epi8(bc[i], from_c, lt);
            bd[i] = _mm256_min_epi32(bd[i], _mm256_max_epi32(bd[i - 1], d));
            lt = lt_prev;
        }
        bd[0] = _mm256_min_epi32(bd[0], d);
        bc[0] = _mm256_blendv_epi8(bc[0], cls, lt);
    }

    /// The winner of each lane, the lanes being neighbouring cells of a row whose windows
    /// start at grid index `base`.
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn vote_row(&self, grid: &Grid, r: __m256, base: usize) -> __m256i {
        let (far_ptr, cls_ptr) = (grid.far.as_ptr().add(base), grid.cls.as_ptr().add(base));
        let (mut bd, mut bc) = Self::empty();
        for j in 0..N {
            let o = self.0.off[j];
            let far = _mm256_loadu_ps(far_ptr.add(o));
            let cls = _mm256_loadu_si256(cls_ptr.add(o) as *const __m256i);
            Self::insert(&mut bd, &mut bc, self.dist(far, r, j), cls);
        }
        self.winner(&bd, &bc)
    }

    /// The winner of each lane, each lane's window starting at its own grid index in
    /// `starts`.
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn vote_cells(&self, grid: &Grid, r: __m256, starts: __m256i) -> __m256i {
        let (far_ptr, cls_ptr) = (grid.far.as_ptr(), grid.cls.as_ptr());
        let (mut bd, mut bc) = Self::empty();
        for j in 0..N {
            let idx = _mm256_add_epi32(starts, _mm256_set1_epi32(self.0.off[j] as i32));
            let far = _mm256_i32gather_ps::<4>(far_ptr, idx);
            let cls = _mm256_i32gather_epi32::<4>(cls_ptr, idx);
            Self::insert(&mut bd, &mut bc, self.dist(far, r, j), cls);
        }
        self.winner(&bd, &bc)
    }

    /// Most votes among the classes that may win, ties to the lower id; no vote: the first
    /// class that may win (the scalar `Vote::winner`).
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn winner(&self, bd: &[__m256i; K], bc: &[__m256i; K]) -> __m256i {
        let nobody = _mm256_set1_epi32(self.0.nobody);
        let mut c = *bc;
        if self.0.cutoff > 0.0 {
            let cutoff = _mm256_set1_ps(self.0.cutoff);
            for a in 0..K {
                let far = _mm256_cmp_ps::<_CMP_GT_OQ>(_mm256_castsi256_ps(bd[a]), cutoff);
                c[a] = _mm256_blendv_epi8(c[a], nobody, _mm256_castps_si256(far));
            }
        }
        let one = _mm256_set1_epi32(1);
        let mask = _mm256_set1_epi32(self.0.can_win as i32);
        let mut winner = _mm256_set1_epi32(self.0.first_winner);
        let mut most = _mm256_setzero_si256();
        for a in 0..K {
            // nobody (and any id past the map) is not in the mask: the shift gives 0.
            let may = _mm256_and_si256(_mm256_srlv_epi32(mask, c[a]), one);
            let valid = _mm256_cmpeq_epi32(may, one);
            let mut count = _mm256_setzero_si256();
            for b in 0..K {
                count = _mm256_sub_epi32(count, _mm256_cmpeq_epi32(c[b], c[a]));
            }
            let more = _mm256_cmpgt_epi32(count, most);
            let tie = _mm256_and_si256(
                _mm256_cmpeq_epi32(count, most),
                _mm256_cmpgt_epi32(winner, c[a]),
            );
            let better = _mm256_and_si256(valid, _mm256_or_si256(more, tie));
            winner = _mm256_blendv_epi8(winner, c[a], better);
            most = _mm256_blendv_epi8(most, count, better);
        }
        winner
    }
}
