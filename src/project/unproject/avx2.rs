//! The kNN vote eight points at a time (AVX2), the same result as the scalar code bit for bit
//! (tested against it on real scans).
//!
//! Each lane is a point. The window's ranges and classes come from a copy of the map padded with
//! the window's half-width on every side ([`Grid`]: zero-range padding voting for the padding's
//! class, or the columns wrapped), so that no window needs a bounds test. The first point of each
//! cell is taken eight neighbouring cells at a time, their windows read by plain vector loads; the
//! points that share a cell with a nearer one are taken eight at a time, each window row of the
//! eight loaded whole and transposed.
//!
//! The nearest are found by keys: a candidate's distance bits (non-negative floats order as their
//! bits) with the lowest [`CLASS_BITS`] replaced by its class. Keys order as their truncated
//! distances (keys of one truncated distance in any order), so minima and maxima sort them, no
//! compare, no blend: each window row's keys by an optimal sorting network, merged into the
//! kept ones by a bitonic merge (fewer operations than inserting the keys one by one). The
//! centre (the point's own cell, at distance 0) is one of the `K` nearest, with the `K - 1`
//! smallest keys of the other cells; the next key is kept too. The vote needs only the classes
//! of the `K` nearest, which the keys give wherever the last chosen key and the next differ in
//! truncated distance (then every chosen one is nearer than every other, exactly; and fewer
//! than `K` others tie with the centre). Where they share it, or a chosen one's truncated
//! distance is the cutoff's (a few lanes in a thousand on real scans), the block is taken again
//! with exact distances, kept beside their classes by compares and blends (ties stay with the
//! earlier cell, the scalar rule).

use std::arch::x86_64::*;

use super::lanes::{point_pass, scattered, window_starts, Block, CellWinners, Grid, Setup};
use super::vectors::{merge, sort, transpose, widen};
use super::{KnnParams, PointsInMap, Vote};
use crate::label::ClassId;
use crate::project::EMPTY;

/// Whether this machine runs the AVX2 path.
pub(super) fn available() -> bool {
    is_x86_feature_detected!("avx2")
}

/// Bits of a key below the distance's, for the class (at most 31 classes, and `nobody`).
const CLASS_BITS: u32 = 5;

#[cfg(test)]
thread_local! {
    /// Blocks voted for on this thread, and those of them the keys could not decide.
    pub(super) static BLOCKS: std::cell::Cell<(usize, usize)> = const { std::cell::Cell::new((0, 0)) };
}

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
    let grid = Grid::<u8>::new(m, pred, vote, S / 2, p.wrap_columns, 8);
    let k = Kernel::<S, N, K>::new(Setup::new(&grid, vote, p));
    let winners = cell_winners(&k, &grid, m);
    let others = points(m, &winners, out);
    scattered::<8>(m, &others, out, |block, ranges, used| {
        let Block::Scattered(lanes) = block else {
            unreachable!("the points behind a nearer one")
        };
        // SAFETY: this function runs with AVX2.
        unsafe {
            let r = _mm256_loadu_ps(ranges.as_ptr());
            let winners = k.vote(&grid, r, Cells(window_starts(&grid, m, lanes)), used);
            let mut w = [0i32; 8];
            _mm256_storeu_si256(w.as_mut_ptr() as *mut __m256i, winners);
            w
        }
    });
}

/// The winner of every cell's kept point ([`super::lanes::cell_winners`]'s result), eight
/// neighbouring cells of a row at a time, their ranges read from the padded grid. The lanes
/// past a row's end hold the padding: their winners land on the next row's first cells (each
/// of them written again after, where it holds a point) or in [`CellWinners::PAD`].
///
/// # Safety
/// The CPU must have AVX2; `grid` is `m`'s, padded by `S / 2` and 8 columns.
#[target_feature(enable = "avx2")]
unsafe fn cell_winners<const S: usize, const N: usize, const K: usize>(
    k: &Kernel<S, N, K>,
    grid: &Grid<u8>,
    m: &PointsInMap<'_>,
) -> CellWinners {
    let mut winners = vec![0 as ClassId; m.rows * m.cols + CellWinners::PAD];
    let (far, centre) = (grid.far.as_ptr(), S / 2 * grid.stride + S / 2);
    let inf = _mm256_set1_ps(f32::INFINITY);
    for row in 0..m.rows {
        for col0 in (0..m.cols).step_by(8) {
            let top = row * grid.stride + col0;
            // SAFETY: the grid has the centre's row and 8 columns from it (`grid`'s padding).
            let r = _mm256_loadu_ps(far.add(top + centre));
            let lanes = (1u32 << (m.cols - col0).min(8)) - 1;
            let used = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LT_OQ>(r, inf)) as u32 & lanes;
            if used == 0 {
                continue;
            }
            let won = k.vote(grid, r, Row(top), used);
            // 8 classes (0 to 31) to 8 bytes: 4 in each 128-bit half, then together.
            let bytes =
                _mm256_packus_epi16(_mm256_packus_epi32(won, won), _mm256_packus_epi32(won, won));
            let eight = (_mm256_cvtsi256_si32(bytes) as u32 as u64)
                | ((_mm256_extract_epi32::<4>(bytes) as u32 as u64) << 32);
            let at = row * m.cols + col0;
            // SAFETY: 8 bytes from a cell's lie in the winners (`CellWinners::PAD`).
            (winners.as_mut_ptr().add(at) as *mut u64).write_unaligned(eight.to_le());
        }
    }
    CellWinners(winners)
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
unsafe fn points(
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

/// Where the lanes' windows are.
trait Windows: Copy {
    /// Row `dy` of every lane's window, its first `S` cells (`S` at most 8): their ranges as
    /// the kNN compares them, and their classes.
    ///
    /// # Safety
    /// The CPU must have AVX2; the windows lie in `grid`, with 8 cells to read from each row's
    /// start.
    unsafe fn row<const S: usize>(self, grid: &Grid<u8>, dy: usize) -> ([__m256; S], [__m256i; S]);
}

/// Side by side from one grid index: the windows of neighbouring cells of a row.
#[derive(Clone, Copy)]
struct Row(usize);

/// Each lane's window from its own grid index.
#[derive(Clone, Copy)]
struct Cells([i32; 8]);

impl Windows for Row {
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn row<const S: usize>(self, grid: &Grid<u8>, dy: usize) -> ([__m256; S], [__m256i; S]) {
        let at = self.0 + dy * grid.stride;
        let (far, cls) = (grid.far.as_ptr().add(at), grid.cls.as_ptr().add(at));
        (
            std::array::from_fn(|x| _mm256_loadu_ps(far.add(x))),
            std::array::from_fn(|x| widen(cls.add(x))),
        )
    }
}

impl Windows for Cells {
    /// Each lane's row loaded whole (8 cells) and the eight transposed: plain loads and
    /// shuffles, where gathers cost several times more.
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn row<const S: usize>(self, grid: &Grid<u8>, dy: usize) -> ([__m256; S], [__m256i; S]) {
        let at = |l: usize| self.0[l] as usize + dy * grid.stride;
        // SAFETY (both): the lane's window lies in the grid (the caller's promise).
        let far = transpose(std::array::from_fn(|l| unsafe {
            _mm256_loadu_ps(grid.far.as_ptr().add(at(l)))
        }));
        let cls = transpose(std::array::from_fn(|l| unsafe {
            _mm256_castsi256_ps(widen(grid.cls.as_ptr().add(at(l))))
        }));
        (
            std::array::from_fn(|x| far[x]),
            std::array::from_fn(|x| _mm256_castps_si256(cls[x])),
        )
    }
}

/// The window's shape in the type: `S` x `S` = `N` cells, `K` nearest.
struct Kernel<const S: usize, const N: usize, const K: usize> {
    setup: Setup<N>,
    /// Each window cell's weight in every lane (the centre's unused: it is at distance 0).
    weight: [__m256; N],
}

impl<const S: usize, const N: usize, const K: usize> Kernel<S, N, K> {
    #[inline]
    #[target_feature(enable = "avx2")]
    fn new(setup: Setup<N>) -> Self {
        Kernel {
            weight: std::array::from_fn(|j| _mm256_set1_ps(setup.w[j])),
            setup,
        }
    }

    /// The winner of each lane (`used`: the lanes that hold a point, a bit mask): by keys, or
    /// by the exact distances where the keys are not sure.
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn vote(&self, grid: &Grid<u8>, r: __m256, at: impl Windows, used: u32) -> __m256i {
        let (winners, unsure) = self.vote_by_keys(grid, r, at);
        let undecided = unsure & used != 0;
        #[cfg(test)]
        BLOCKS.with(|b| {
            let (all, exact) = b.get();
            b.set((all + 1, exact + undecided as usize));
        });
        if !undecided {
            winners
        } else {
            self.vote_exact(grid, r, at)
        }
    }

    /// The signed difference times the weight of window cell `j`, from its ranges `far`.
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn weighted(&self, far: __m256, r: __m256, j: usize) -> __m256 {
        _mm256_mul_ps(_mm256_sub_ps(far, r), self.weight[j])
    }

    /// The keys of row `dy` of every lane's window (see the module), and the classes of its
    /// middle cell (the centre's, in the centre's row).
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn row_keys(
        &self,
        grid: &Grid<u8>,
        r: __m256,
        at: impl Windows,
        dy: usize,
        high: __m256i,
    ) -> ([__m256i; S], __m256i) {
        let (far, cls) = at.row::<S>(grid, dy);
        let mut keys = [high; S];
        for (x, key) in keys.iter_mut().enumerate() {
            let d = _mm256_castps_si256(self.weighted(far[x], r, dy * S + x));
            *key = _mm256_or_si256(_mm256_and_si256(d, high), cls[x]);
        }
        (keys, cls[S / 2])
    }

    /// The winner of each lane from its `K` smallest keys (see the module), and the lanes (bit
    /// mask) where the keys may have chosen otherwise than the exact distances.
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn vote_by_keys(&self, grid: &Grid<u8>, r: __m256, at: impl Windows) -> (__m256i, u32) {
        let high = _mm256_set1_epi32(!((1 << CLASS_BITS) - 1) & i32::MAX);
        // The `K - 1` nearest of the other cells and the next, sorted: the centre (at distance
        // 0, whatever its cell's range) is one of the `K` nearest unless `K` others tie with
        // it, which the doubt below covers (the next then ties with the last chosen). Each
        // row's keys are sorted, then merged into the kept ones (the first row's are the first
        // kept); the centre's row comes last, without the centre.
        let mut keys = [_mm256_set1_epi32(i32::MAX); K];
        let (mut row, _) = self.row_keys(grid, r, at, 0, high);
        sort(&mut row, S);
        for (kept, &k) in keys.iter_mut().zip(&row) {
            *kept = k;
        }
        for dy in (1..S).filter(|&dy| dy != S / 2) {
            let (mut row, _) = self.row_keys(grid, r, at, dy, high);
            sort(&mut row, S);
            merge(&mut keys, &row, S);
        }
        let (mut row, centre) = self.row_keys(grid, r, at, S / 2, high);
        for x in S / 2..S - 1 {
            row[x] = row[x + 1];
        }
        sort(&mut row, S - 1);
        merge(&mut keys, &row, S - 1);
        let truncated = |key: __m256i| _mm256_srli_epi32::<{ CLASS_BITS as i32 }>(key);
        let (kth, next) = (truncated(keys[K - 2]), truncated(keys[K - 1]));
        // With a cutoff, empty cells (infinitely far) vote for nobody whichever are chosen:
        // a tie there is no doubt. (Without one, -1: no truncated distance.)
        let inf = _mm256_set1_epi32(if self.setup.cutoff > 0.0 {
            (f32::INFINITY.to_bits() >> CLASS_BITS) as i32
        } else {
            -1
        });
        let mut unsure =
            _mm256_andnot_si256(_mm256_cmpeq_epi32(kth, inf), _mm256_cmpeq_epi32(kth, next));
        let class = _mm256_set1_epi32((1 << CLASS_BITS) - 1);
        let nobody = _mm256_set1_epi32(self.setup.nobody);
        // The centre's class (within any cutoff), then the others'.
        let mut c: [__m256i; K] = std::array::from_fn(|a| match a {
            0 => centre,
            _ => _mm256_and_si256(keys[a - 1], class),
        });
        if self.setup.cutoff > 0.0 {
            let cut = _mm256_set1_epi32((self.setup.cutoff.to_bits() >> CLASS_BITS) as i32);
            for a in 1..K {
                let t = truncated(keys[a - 1]);
                unsure = _mm256_or_si256(unsure, _mm256_cmpeq_epi32(t, cut));
                c[a] = _mm256_blendv_epi8(c[a], nobody, _mm256_cmpgt_epi32(t, cut));
            }
        }
        let unsure = _mm256_movemask_ps(_mm256_castsi256_ps(unsure)) as u32;
        (self.winner(&c), unsure)
    }

    /// The winner of each lane, its `K` nearest found by exact distance (bits, compared as
    /// integers) and class kept side by side: a candidate, coming after every kept one in
    /// window order, goes in front of the kept ones it is strictly nearer than.
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn vote_exact(&self, grid: &Grid<u8>, r: __m256, at: impl Windows) -> __m256i {
        // Nothing kept yet: every slot farther than anything (`i32::MAX`, above infinity).
        let mut bd = [_mm256_set1_epi32(i32::MAX); K];
        let mut bc = [_mm256_setzero_si256(); K];
        let abs = _mm256_set1_epi32(i32::MAX);
        for dy in 0..S {
            let (far, cls) = at.row::<S>(grid, dy);
            for x in 0..S {
                let d = _mm256_castps_si256(self.weighted(far[x], r, dy * S + x));
                // The centre at distance 0, whatever its cell's range.
                let d = if dy * S + x == N / 2 {
                    _mm256_setzero_si256()
                } else {
                    _mm256_and_si256(d, abs)
                };
                Self::insert(&mut bd, &mut bc, d, cls[x]);
            }
        }
        let nobody = _mm256_set1_epi32(self.setup.nobody);
        if self.setup.cutoff > 0.0 {
            let cutoff = _mm256_set1_ps(self.setup.cutoff);
            for a in 0..K {
                let far = _mm256_cmp_ps::<_CMP_GT_OQ>(_mm256_castsi256_ps(bd[a]), cutoff);
                bc[a] = _mm256_blendv_epi8(bc[a], nobody, _mm256_castps_si256(far));
            }
        }
        self.winner(&bc)
    }

    /// Keeps the candidate (distance bits `d`, class `cls`) among the `K` nearest: entry `i`
    /// becomes the median of entry `i - 1`, the candidate and entry `i` (all non-negative:
    /// signed minimum and maximum order them as their bits); classes follow the compares.
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn insert(bd: &mut [__m256i; K], bc: &mut [__m256i; K], d: __m256i, cls: __m256i) {
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

    /// Most votes among the classes `c` of the nearest (`nobody` for those past the cutoff)
    /// that may win, ties to the lower id; no vote: the first class that may win (the scalar
    /// `Vote::winner`). The votes are counted for all classes at once, bit `c` of three masks
    /// holding class `c`'s count (up to 7) in binary.
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn winner(&self, c: &[__m256i; K]) -> __m256i {
        let zero = _mm256_setzero_si256();
        let (one, may) = (
            _mm256_set1_epi32(1),
            _mm256_set1_epi32(self.setup.can_win as i32),
        );
        let mut count = [zero; 3];
        for ca in c {
            // nobody (31 at most) is not in the mask.
            let mut carry = _mm256_and_si256(_mm256_sllv_epi32(one, *ca), may);
            for bit in &mut count {
                let next = _mm256_and_si256(*bit, carry);
                *bit = _mm256_xor_si256(*bit, carry);
                carry = next;
            }
        }
        // The classes with most votes: from the count's highest bit down, those that have it
        // where any does.
        let mut best = _mm256_or_si256(_mm256_or_si256(count[0], count[1]), count[2]);
        for bit in count.iter().rev() {
            let have = _mm256_and_si256(best, *bit);
            best = _mm256_blendv_epi8(have, best, _mm256_cmpeq_epi32(have, zero));
        }
        // The lowest of them: its bit alone, as a float, whose exponent is its position.
        let lowest = _mm256_and_si256(best, _mm256_sub_epi32(zero, best));
        let exponent = _mm256_srli_epi32::<23>(_mm256_castps_si256(_mm256_cvtepi32_ps(lowest)));
        let id = _mm256_sub_epi32(exponent, _mm256_set1_epi32(127));
        let first = _mm256_set1_epi32(self.setup.first_winner);
        _mm256_blendv_epi8(id, first, _mm256_cmpeq_epi32(best, zero))
    }
}
