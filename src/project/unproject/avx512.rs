//! The kNN vote sixteen points at a time (AVX-512), the same result as the scalar code bit for
//! bit: the eight-lane kernel ([`super::avx2`]) on twice the lanes, with compares into masks
//! and masked blends.

use std::arch::x86_64::*;

use super::lanes::{drive, window_starts, Block, Grid, Setup};
use super::{KnnParams, PointsInMap, Vote};
use crate::label::ClassId;

/// Whether this machine runs the AVX-512 path.
pub(super) fn available() -> bool {
    is_x86_feature_detected!("avx512f")
}

/// The kNN class of every point (`S` x `S` = `N` window, `K` nearest), into `out` (one slot per
/// point, `None` already where the point is outside the map). The class map has at most 31
/// classes.
///
/// # Safety
/// The CPU must have AVX-512F ([`available`]).
#[target_feature(enable = "avx512f")]
pub(super) unsafe fn knn<const S: usize, const N: usize, const K: usize>(
    m: &PointsInMap<'_>,
    pred: &[ClassId],
    p: &KnnParams,
    vote: &Vote,
    out: &mut [Option<ClassId>],
) {
    let grid = Grid::new(m, pred, vote, S / 2, p.wrap_columns, 16);
    let k = Kernel::<S, N, K>(Setup::new(&grid, vote, p));
    drive::<16>(m, out, |block, ranges, _| {
        // SAFETY: this function runs with AVX-512F.
        unsafe {
            let r = _mm512_loadu_ps(ranges.as_ptr());
            let winners = match block {
                Block::Row(at) => k.vote_row(&grid, r, grid.top_left(at, m.cols)),
                Block::Scattered(lanes) => {
                    let starts = window_starts(&grid, m, lanes);
                    k.vote_cells(&grid, r, _mm512_loadu_si512(starts.as_ptr() as *const _))
                }
            };
            let mut w = [0i32; 16];
            _mm512_storeu_si512(w.as_mut_ptr() as *mut _, winners);
            w
        }
    });
}

/// The window's shape in the type: `S` x `S` = `N` cells, `K` nearest.
struct Kernel<const S: usize, const N: usize, const K: usize>(Setup<N>);

impl<const S: usize, const N: usize, const K: usize> Kernel<S, N, K> {
    /// The distance bits of window cell `j` from its ranges `far` (the centre's 0, whatever its
    /// cell's range).
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn dist(&self, far: __m512, r: __m512, j: usize) -> __m512i {
        if j == N / 2 {
            return _mm512_setzero_si512();
        }
        let diff = _mm512_abs_ps(_mm512_sub_ps(far, r));
        _mm512_castps_si512(_mm512_mul_ps(diff, _mm512_set1_ps(self.0.w[j])))
    }

    /// Keeps the candidate among the `K` nearest (the eight-lane kernel's rule).
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn insert(bd: &mut [__m512i; K], bc: &mut [__m512i; K], d: __m512i, cls: __m512i) {
        let mut lt = _mm512_cmpgt_epi32_mask(bd[K - 1], d);
        for i in (1..K).rev() {
            let lt_prev = _mm512_cmpgt_epi32_mask(bd[i - 1], d);
            let from_c = _mm512_mask_blend_epi32(lt_prev, cls, bc[i - 1]);
            bc[i] = _mm512_mask_blend_epi32(lt, bc[i], from_c);
            bd[i] = _mm512_min_epi32(bd[i], _mm512_max_epi32(bd[i - 1], d));
            lt = lt_prev;
        }
        bd[0] = _mm512_min_epi32(bd[0], d);
        bc[0] = _mm512_mask_blend_epi32(lt, bc[0], cls);
    }

    /// The winner of each lane, the lanes being neighbouring cells of a row whose windows
    /// start at grid index `base`.
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn vote_row(&self, grid: &Grid, r: __m512, base: usize) -> __m512i {
        let (far_ptr, cls_ptr) = (grid.far.as_ptr().add(base), grid.cls.as_ptr().add(base));
        let mut bd = [_mm512_set1_epi32(i32::MAX); K];
        let mut bc = [_mm512_setzero_si512(); K];
        for j in 0..N {
            let o = self.0.off[j];
            let far = _mm512_loadu_ps(far_ptr.add(o));
            let cls = _mm512_loadu_si512(cls_ptr.add(o) as *const _);
            Self::insert(&mut bd, &mut bc, self.dist(far, r, j), cls);
        }
        self.winner(&bd, &bc)
    }

    /// The winner of each lane, each lane's window starting at its own grid index in
    /// `starts`.
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn vote_cells(&self, grid: &Grid, r: __m512, starts: __m512i) -> __m512i {
        let (far_ptr, cls_ptr) = (grid.far.as_ptr(), grid.cls.as_ptr());
        let mut bd = [_mm512_set1_epi32(i32::MAX); K];
        let mut bc = [_mm512_setzero_si512(); K];
        for j in 0..N {
            let idx = _mm512_add_epi32(starts, _mm512_set1_epi32(self.0.off[j] as i32));
            let far = _mm512_i32gather_ps::<4>(idx, far_ptr);
            let cls = _mm512_i32gather_epi32::<4>(idx, cls_ptr);
            Self::insert(&mut bd, &mut bc, self.dist(far, r, j), cls);
        }
        self.winner(&bd, &bc)
    }

    /// Most votes among the classes that may win, ties to the lower id; no vote: the first
    /// class that may win.
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn winner(&self, bd: &[__m512i; K], bc: &[__m512i; K]) -> __m512i {
        let nobody = _mm512_set1_epi32(self.0.nobody);
        let mut c = *bc;
        if self.0.cutoff > 0.0 {
            let cutoff = _mm512_set1_ps(self.0.cutoff);
            for a in 0..K {
                let far = _mm512_cmp_ps_mask::<_CMP_GT_OQ>(_mm512_castsi512_ps(bd[a]), cutoff);
                c[a] = _mm512_mask_blend_epi32(far, c[a], nobody);
            }
        }
        let one = _mm512_set1_epi32(1);
        let mask = _mm512_set1_epi32(self.0.can_win as i32);
        let mut winner = _mm512_set1_epi32(self.0.first_winner);
        let mut most = _mm512_setzero_si512();
        for a in 0..K {
            let valid = _mm512_test_epi32_mask(_mm512_srlv_epi32(mask, c[a]), one);
            let mut count = _mm512_setzero_si512();
            for b in 0..K {
                let same = _mm512_cmpeq_epi32_mask(c[b], c[a]);
                count = _mm512_mask_add_epi32(count, same, count, one);
            }
            let more = _mm512_cmpgt_epi32_mask(count, most);
            let tie = _mm512_cmpeq_epi32_mask(count, most) & _mm512_cmpgt_epi32_mask(winner, c[a]);
            let better = valid & (more | tie);
            winner = _mm512_mask_blend_epi32(better, winner, c[a]);
            most = _mm512_mask_blend_epi32(better, most, count);
        }
        winner
    }
}
