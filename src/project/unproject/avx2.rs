//! The kNN vote eight points at a time (AVX2): the lane operations of [`super::keys`]'s kernel
//! on 256-bit vectors, the scattered points' windows read by transposes, and the pass over the
//! points (which the AVX-512 kernel runs too).

use std::arch::x86_64::*;

use super::keys::{Cells, Kernel, Windows};
use super::lanes::{point_pass, CellWinners, Grid, Setup};
use super::vectors::Simd;
use super::{KnnParams, PointsInMap, Vote};
use crate::label::ClassId;
use crate::project::EMPTY;

/// Whether this machine runs the AVX2 path (as the passes over every point do: not where the
/// environment narrows them, [`crate::simd::Level::widest`]).
pub(super) fn available() -> bool {
    crate::simd::Level::widest() >= crate::simd::Level::Avx2
}

super::keys::kernel!(Avx2, "avx2");

/// The kNN class of every point (`S` x `S` = `N` window, `K` nearest), into `out` (one slot per
/// point, `None` already where the point is outside the map). The class map has at most 31
/// classes (their "may win" set is a bit mask); `S` is at most 7.
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
    let k = Kernel::<Avx2, S, N, K>::new(Setup::new(vote, p));
    let winners = k.cell_winners::<8>(&grid, m);
    let others = points(m, &winners, out);
    k.scattered::<8>(&grid, m, &others, out);
}

/// AVX2's lanes: eight, masks as vectors (all bits set in a lane that is in).
#[derive(Clone, Copy)]
pub(super) struct Avx2;

impl Simd for Avx2 {
    const L: usize = 8;
    type F = __m256;
    type I = __m256i;
    type M = __m256i;
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn splat_f(x: f32) -> __m256 {
        _mm256_set1_ps(x)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn splat(x: i32) -> __m256i {
        _mm256_set1_epi32(x)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn load_f(p: *const f32) -> __m256 {
        _mm256_loadu_ps(p)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn load_bytes(p: *const u8) -> __m256i {
        widen(p)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn store_bytes(v: __m256i, p: *mut u8) {
        // 4 in each 128-bit half, then together.
        let bytes = _mm256_packus_epi16(_mm256_packus_epi32(v, v), _mm256_packus_epi32(v, v));
        let eight = (_mm256_cvtsi256_si32(bytes) as u32 as u64)
            | ((_mm256_extract_epi32::<4>(bytes) as u32 as u64) << 32);
        (p as *mut u64).write_unaligned(eight.to_le());
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn store(v: __m256i, p: *mut i32) {
        _mm256_storeu_si256(p as *mut __m256i, v)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn sub_f(a: __m256, b: __m256) -> __m256 {
        _mm256_sub_ps(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn mul_f(a: __m256, b: __m256) -> __m256 {
        _mm256_mul_ps(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn bits(a: __m256) -> __m256i {
        _mm256_castps_si256(a)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn from_bits(a: __m256i) -> __m256 {
        _mm256_castsi256_ps(a)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn to_f(a: __m256i) -> __m256 {
        _mm256_cvtepi32_ps(a)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn and(a: __m256i, b: __m256i) -> __m256i {
        _mm256_and_si256(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn or(a: __m256i, b: __m256i) -> __m256i {
        _mm256_or_si256(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn xor(a: __m256i, b: __m256i) -> __m256i {
        _mm256_xor_si256(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn sub(a: __m256i, b: __m256i) -> __m256i {
        _mm256_sub_epi32(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn min(a: __m256i, b: __m256i) -> __m256i {
        _mm256_min_epi32(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn max(a: __m256i, b: __m256i) -> __m256i {
        _mm256_max_epi32(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn sllv(a: __m256i, n: __m256i) -> __m256i {
        _mm256_sllv_epi32(a, n)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn srli<const N: i32>(a: __m256i) -> __m256i {
        _mm256_srli_epi32::<N>(a)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn eq(a: __m256i, b: __m256i) -> __m256i {
        _mm256_cmpeq_epi32(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn gt(a: __m256i, b: __m256i) -> __m256i {
        _mm256_cmpgt_epi32(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn gt_f(a: __m256, b: __m256) -> __m256i {
        _mm256_castps_si256(_mm256_cmp_ps::<_CMP_GT_OQ>(a, b))
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn select(m: __m256i, a: __m256i, b: __m256i) -> __m256i {
        _mm256_blendv_epi8(a, b, m)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn mask_or(a: __m256i, b: __m256i) -> __m256i {
        _mm256_or_si256(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn mask_andnot(a: __m256i, b: __m256i) -> __m256i {
        _mm256_andnot_si256(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn mask_bits(m: __m256i) -> u32 {
        _mm256_movemask_ps(_mm256_castsi256_ps(m)) as u32
    }
}

impl Windows<Avx2> for Cells<8> {
    /// Each lane's row loaded whole (8 cells) and the eight transposed: plain loads and
    /// shuffles, where gathers cost several times more.
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn row<const S: usize>(self, grid: &Grid, dy: usize) -> ([__m256; S], [__m256i; S]) {
        let (far, cls) = rows_transposed(grid, &self.0, dy);
        let (mut f, mut c) = ([_mm256_setzero_ps(); S], [_mm256_setzero_si256(); S]);
        for x in 0..S {
            f[x] = far[x];
            c[x] = _mm256_castps_si256(cls[x]);
        }
        (f, c)
    }
}

/// Row `dy` of the windows from the grid indices `starts`, 8 cells of each, transposed: element
/// `x` of every window in vector `x` (ranges, and classes as integer bits).
///
/// # Safety
/// The CPU must have AVX2; each window lies in `grid`, with 8 cells to read from its row's start.
#[inline]
#[target_feature(enable = "avx2")]
pub(super) unsafe fn rows_transposed(
    grid: &Grid,
    starts: &[i32],
    dy: usize,
) -> ([__m256; 8], [__m256; 8]) {
    let at = |l: usize| starts[l] as usize + dy * grid.stride;
    // SAFETY (both): the lane's window lies in the grid (the caller's promise).
    let far = transpose(std::array::from_fn(|l| unsafe {
        _mm256_loadu_ps(grid.far.as_ptr().add(at(l)))
    }));
    let cls = transpose(std::array::from_fn(|l| unsafe {
        _mm256_castsi256_ps(widen(grid.cls.as_ptr().add(at(l))))
    }));
    (far, cls)
}

/// The pass over the points ([`point_pass`]'s result) eight at a time: their cells' ranges and
/// winners loaded, the points behind a nearer one packed to the front of a vector by a table
/// and stored whole (their count moves on by the mask's population). No branch but for the
/// loop's: taken by the points at random, the scalar pass's branch mispredicted.
///
/// # Safety
/// The CPU must have AVX2; the map has a cell; every point's cell is in the map or [`EMPTY`]
/// (checked by the caller).
#[target_feature(enable = "avx2")]
pub(super) unsafe fn points(
    m: &PointsInMap<'_>,
    winners: &CellWinners,
    out: &mut [Option<ClassId>],
) -> Vec<u32> {
    let n = out.len();
    let blocks = n / 8;
    // Room for the last block's whole vector.
    let mut others: Vec<u32> = Vec::with_capacity(n + 8);
    let mut kept = 0usize;
    let (cells, ranges) = (m.point_cell.as_ptr(), m.point_range.as_ptr());
    let (cell_range, cls) = (m.cell_range.as_ptr(), winners.0.as_ptr());
    let (empty, zero) = (_mm256_set1_epi32(EMPTY as i32), _mm256_setzero_ps());
    for b in 0..blocks {
        let at = b * 8;
        let c = _mm256_loadu_si256(cells.add(at) as *const __m256i);
        let r = _mm256_loadu_ps(ranges.add(at));
        let inside = _mm256_xor_si256(_mm256_cmpeq_epi32(c, empty), _mm256_set1_epi32(-1));
        // The cells' ranges and winners by plain loads, a lane at a time (lanes outside the
        // map read cell 0's): faster than two gathers on AMD Zen 3, where gathers are
        // microcoded. SAFETY: every index is a cell of the map (the caller's promise).
        let lane_cells: &[u32; 8] = m.point_cell[at..at + 8].try_into().expect("8 points");
        let at_cell = lane_cells.map(|c| if c == EMPTY { 0 } else { c as usize });
        let kr: [f32; 8] = std::array::from_fn(|l| *cell_range.add(at_cell[l]));
        let won: [i32; 8] = std::array::from_fn(|l| *cls.add(at_cell[l]) as i32);
        let (kr, won) = (
            _mm256_loadu_ps(kr.as_ptr()),
            _mm256_loadu_si256(won.as_ptr() as *const __m256i),
        );
        let same = _mm256_and_si256(
            _mm256_cmpeq_epi32(_mm256_castps_si256(r), _mm256_castps_si256(kr)),
            _mm256_castps_si256(_mm256_cmp_ps::<_CMP_GT_OQ>(kr, zero)),
        );
        let other = _mm256_movemask_ps(_mm256_castsi256_ps(_mm256_andnot_si256(same, inside)));
        let packed = _mm256_add_epi32(
            _mm256_set1_epi32(at as i32),
            _mm256_loadu_si256(PACK[other as usize].as_ptr() as *const __m256i),
        );
        // SAFETY: `kept` <= `at`, and the vector has room for 8 from `n`.
        _mm256_storeu_si256(others.as_mut_ptr().add(kept) as *mut __m256i, packed);
        kept += other.count_ones() as usize;
        let mut w = [0i32; 8];
        _mm256_storeu_si256(w.as_mut_ptr() as *mut __m256i, won);
        let inside = _mm256_movemask_ps(_mm256_castsi256_ps(inside));
        for (l, (o, &w)) in out[at..at + 8].iter_mut().zip(&w).enumerate() {
            *o = (inside >> l & 1 == 1).then_some(w as ClassId);
        }
    }
    // SAFETY: the first `kept` entries were written.
    others.set_len(kept);
    point_pass(m, winners, blocks * 8, out, &mut others);
    others
}

/// For each 8-bit mask, its set lanes' indices packed to the front.
static PACK: [[u32; 8]; 256] = {
    let mut t = [[0u32; 8]; 256];
    let mut mask = 0;
    while mask < 256 {
        let (mut lane, mut n) = (0, 0);
        while lane < 8 {
            if mask >> lane & 1 == 1 {
                t[mask][n] = lane as u32;
                n += 1;
            }
            lane += 1;
        }
        mask += 1;
    }
    t
};

/// The eight classes (bytes) from `at`, one a lane.
///
/// # Safety
/// The CPU must have AVX2; eight bytes from `at` are readable.
#[inline]
#[target_feature(enable = "avx2")]
pub(super) unsafe fn widen(at: *const u8) -> __m256i {
    _mm256_cvtepu8_epi32(_mm_loadl_epi64(at as *const __m128i))
}

/// Column `x` of the result holds element `x` of every input, lane `l` from input `l`.
#[inline]
#[target_feature(enable = "avx2")]
pub(super) fn transpose(r: [__m256; 8]) -> [__m256; 8] {
    let t: [__m256; 8] = std::array::from_fn(|i| {
        let (a, b) = (r[i / 2 * 2], r[i / 2 * 2 + 1]);
        if i % 2 == 0 {
            _mm256_unpacklo_ps(a, b)
        } else {
            _mm256_unpackhi_ps(a, b)
        }
    });
    // u[4 * half + x]: element x (and x + 4) of inputs 4 * half .. 4 * half + 4.
    let u: [__m256; 8] = std::array::from_fn(|i| {
        let (half, x) = (i / 4, i % 4);
        let (a, b) = (t[4 * half + x / 2], t[4 * half + x / 2 + 2]);
        if x % 2 == 0 {
            _mm256_shuffle_ps::<0x44>(a, b)
        } else {
            _mm256_shuffle_ps::<0xEE>(a, b)
        }
    });
    std::array::from_fn(|x| {
        if x < 4 {
            _mm256_permute2f128_ps::<0x20>(u[x], u[4 + x])
        } else {
            _mm256_permute2f128_ps::<0x31>(u[x - 4], u[x])
        }
    })
}
