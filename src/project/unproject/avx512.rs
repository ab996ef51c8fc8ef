//! The kNN vote sixteen points at a time (AVX-512F): the lane operations of [`super::keys`]'s
//! kernel on 512-bit vectors, compares into mask registers; the scattered points' windows read
//! by two of the AVX2 kernel's transposes, and its pass over the points.

use std::arch::x86_64::*;

use super::avx2::{points, rows_transposed};
use super::keys::{Cells, Kernel, Windows};
use super::lanes::{Grid, Setup};
use super::vectors::Simd;
use super::{KnnParams, PointsInMap, Vote};
use crate::label::ClassId;

/// Whether this machine runs the AVX-512 path (as the passes over every point do: not where the
/// environment narrows them, [`crate::simd::Level::widest`]).
pub(super) fn available() -> bool {
    crate::simd::Level::widest() >= crate::simd::Level::Avx512
}

super::keys::kernel!(Avx512, "avx512f");

/// The kNN class of every point (`S` x `S` = `N` window, `K` nearest), into `out` (one slot per
/// point, `None` already where the point is outside the map). The class map has at most 31
/// classes; `S` is at most 7.
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
    let k = Kernel::<Avx512, S, N, K>::new(Setup::new(vote, p));
    let winners = k.cell_winners::<16>(&grid, m);
    let others = points(m, &winners, out);
    k.scattered::<16>(&grid, m, &others, out);
}

/// AVX-512's lanes: sixteen, masks in mask registers.
#[derive(Clone, Copy)]
pub(super) struct Avx512;

impl Simd for Avx512 {
    const L: usize = 16;
    type F = __m512;
    type I = __m512i;
    type M = __mmask16;
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn splat_f(x: f32) -> __m512 {
        _mm512_set1_ps(x)
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn splat(x: i32) -> __m512i {
        _mm512_set1_epi32(x)
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn load_f(p: *const f32) -> __m512 {
        _mm512_loadu_ps(p)
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn load_bytes(p: *const u8) -> __m512i {
        _mm512_cvtepu8_epi32(_mm_loadu_si128(p as *const __m128i))
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn store_bytes(v: __m512i, p: *mut u8) {
        _mm_storeu_si128(p as *mut __m128i, _mm512_cvtepi32_epi8(v))
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn store(v: __m512i, p: *mut i32) {
        _mm512_storeu_si512(p as *mut _, v)
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn sub_f(a: __m512, b: __m512) -> __m512 {
        _mm512_sub_ps(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn mul_f(a: __m512, b: __m512) -> __m512 {
        _mm512_mul_ps(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn bits(a: __m512) -> __m512i {
        _mm512_castps_si512(a)
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn from_bits(a: __m512i) -> __m512 {
        _mm512_castsi512_ps(a)
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn to_f(a: __m512i) -> __m512 {
        _mm512_cvtepi32_ps(a)
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn and(a: __m512i, b: __m512i) -> __m512i {
        _mm512_and_si512(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn or(a: __m512i, b: __m512i) -> __m512i {
        _mm512_or_si512(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn xor(a: __m512i, b: __m512i) -> __m512i {
        _mm512_xor_si512(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn sub(a: __m512i, b: __m512i) -> __m512i {
        _mm512_sub_epi32(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn min(a: __m512i, b: __m512i) -> __m512i {
        _mm512_min_epi32(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn max(a: __m512i, b: __m512i) -> __m512i {
        _mm512_max_epi32(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn sllv(a: __m512i, n: __m512i) -> __m512i {
        _mm512_sllv_epi32(a, n)
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn srli<const N: i32>(a: __m512i) -> __m512i {
        // (A shift by a constant: compiled as the immediate one, whose count is a `u32` here.)
        _mm512_srl_epi32(a, _mm_cvtsi32_si128(N))
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn eq(a: __m512i, b: __m512i) -> __mmask16 {
        _mm512_cmpeq_epi32_mask(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn gt(a: __m512i, b: __m512i) -> __mmask16 {
        _mm512_cmpgt_epi32_mask(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn gt_f(a: __m512, b: __m512) -> __mmask16 {
        _mm512_cmp_ps_mask::<_CMP_GT_OQ>(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn select(m: __mmask16, a: __m512i, b: __m512i) -> __m512i {
        _mm512_mask_blend_epi32(m, a, b)
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn mask_or(a: __mmask16, b: __mmask16) -> __mmask16 {
        a | b
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn mask_andnot(a: __mmask16, b: __mmask16) -> __mmask16 {
        !a & b
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn mask_bits(m: __mmask16) -> u32 {
        m as u32
    }
}

impl Windows<Avx512> for Cells<16> {
    /// Each lane's row loaded whole (8 cells), each eight lanes transposed (AVX2's), the two
    /// halves joined: plain loads and shuffles, where gathers cost more.
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn row<const S: usize>(self, grid: &Grid, dy: usize) -> ([__m512; S], [__m512i; S]) {
        let (far_lo, cls_lo) = rows_transposed(grid, &self.0[..8], dy);
        let (far_hi, cls_hi) = rows_transposed(grid, &self.0[8..], dy);
        let join = |lo: __m256, hi: __m256| {
            _mm512_castpd_ps(_mm512_insertf64x4::<1>(
                _mm512_castpd256_pd512(_mm256_castps_pd(lo)),
                _mm256_castps_pd(hi),
            ))
        };
        let (mut f, mut c) = ([_mm512_setzero_ps(); S], [_mm512_setzero_si512(); S]);
        for x in 0..S {
            f[x] = join(far_lo[x], far_hi[x]);
            c[x] = _mm512_castps_si512(join(cls_lo[x], cls_hi[x]));
        }
        (f, c)
    }
}
