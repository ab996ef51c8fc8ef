//! The kNN vote `L` points at a time, written once in the lane operations of [`Simd`] (AVX2's
//! eight lanes, AVX-512's sixteen): the same result as the scalar code bit for bit (tested
//! against it on real scans).
//!
//! Each lane is a point. The window's ranges and classes come from a copy of the map padded with
//! the window's half-width on every side ([`Grid`]: zero-range padding voting for the padding's
//! class, or the columns wrapped), so that no window needs a bounds test. The first point of each
//! cell is taken `L` neighbouring cells at a time, their windows read by plain vector loads
//! ([`Row`]); the points that share a cell with a nearer one are taken `L` at a time, each
//! lane's window read from its own place ([`Cells`], by the instruction set's own loads).
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

use super::lanes::{Grid, Setup};
use super::vectors::Simd;

/// Bits of a key below the distance's, for the class (at most 31 classes, and `nobody`).
pub(super) const CLASS_BITS: i32 = 5;

#[cfg(test)]
thread_local! {
    /// Blocks voted for on this thread, and those of them the keys could not decide.
    pub(super) static BLOCKS: std::cell::Cell<(usize, usize)> = const { std::cell::Cell::new((0, 0)) };
}

/// Where the lanes' windows are.
pub(super) trait Windows<V: Simd>: Copy {
    /// Row `dy` of every lane's window, its first `S` cells (`S` at most 8): their ranges as
    /// the kNN compares them, and their classes.
    ///
    /// # Safety
    /// As [`Simd`]'s methods; the windows lie in `grid`, with `L` cells to read from each row's
    /// start.
    unsafe fn row<const S: usize>(self, grid: &Grid, dy: usize) -> ([V::F; S], [V::I; S]);
}

/// Side by side from one grid index: the windows of neighbouring cells of a row.
#[derive(Clone, Copy)]
pub(super) struct Row(pub usize);

/// Each lane's window from its own grid index (read by each instruction set its own way).
#[derive(Clone, Copy)]
pub(super) struct Cells<const L: usize>(pub [i32; L]);

/// The window's shape in the type: `S` x `S` = `N` cells, `K` nearest, on the lanes of `V`.
pub(super) struct Kernel<V: Simd, const S: usize, const N: usize, const K: usize> {
    pub setup: Setup<N>,
    /// Each window cell's weight in every lane (the centre's unused: it is at distance 0).
    pub weight: [V::F; N],
}

/// The kernel's methods for the lanes `$V`, compiled for `$feature` (every method, so that
/// each lane operation is inlined to its instruction: generic code without the feature called
/// them, costing five times the time): `kernel!(Avx2, "avx2")` in the instruction set's module.
macro_rules! kernel {
    ($V:ty, $feature:literal) => {
        const _: () = {
            use $crate::label::ClassId;
            #[cfg(test)]
            use $crate::project::unproject::keys::BLOCKS;
            use $crate::project::unproject::keys::{Cells, Kernel, Row, Windows, CLASS_BITS};
            use $crate::project::unproject::lanes::{
                scattered, window_starts, CellWinners, Grid, Setup,
            };
            use $crate::project::unproject::vectors::{bitonic, network, Simd};
            use $crate::project::unproject::PointsInMap;

            type V = $V;
            type F = <V as Simd>::F;
            type I = <V as Simd>::I;

            impl Windows<V> for Row {
                #[inline]
                #[target_feature(enable = $feature)]
                unsafe fn row<const S: usize>(self, grid: &Grid, dy: usize) -> ([F; S], [I; S]) {
                    let at = self.0 + dy * grid.stride;
                    let (far, cls) = (grid.far.as_ptr().add(at), grid.cls.as_ptr().add(at));
                    let (mut f, mut c) = ([V::splat_f(0.0); S], [V::splat(0); S]);
                    for x in 0..S {
                        f[x] = V::load_f(far.add(x));
                        c[x] = V::load_bytes(cls.add(x));
                    }
                    (f, c)
                }
            }

            impl<const S: usize, const N: usize, const K: usize> Kernel<V, S, N, K> {
                /// # Safety
                /// As [`Simd`]'s methods.
                #[inline]
                #[target_feature(enable = $feature)]
                pub unsafe fn new(setup: Setup<N>) -> Self {
                    let mut weight = [V::splat_f(0.0); N];
                    for (w, &s) in weight.iter_mut().zip(&setup.w) {
                        *w = V::splat_f(s);
                    }
                    Kernel { setup, weight }
                }

                /// The winner of every cell's kept point ([`super::lanes::point_pass`]'s input),
                /// `L` neighbouring cells of a row at a time, their ranges read from the padded
                /// grid. The lanes past a row's end hold the padding: their winners land on the
                /// next row's first cells (each of them written again after, where it holds a
                /// point) or in [`CellWinners::PAD`].
                ///
                /// # Safety
                /// As [`Simd`]'s methods; `grid` is `m`'s, padded by `S / 2` and `L` columns; `L`
                /// is `V::L`, at most [`CellWinners::PAD`] + 1.
                #[inline]
                #[target_feature(enable = $feature)]
                pub unsafe fn cell_winners<const L: usize>(
                    &self,
                    grid: &Grid,
                    m: &PointsInMap<'_>,
                ) -> CellWinners {
                    debug_assert!(L == V::L && L <= CellWinners::PAD + 1);
                    let mut winners = vec![0 as ClassId; m.rows * m.cols + CellWinners::PAD];
                    let (far, centre) = (grid.far.as_ptr(), S / 2 * grid.stride + S / 2);
                    let inf = V::splat_f(f32::INFINITY);
                    for row in 0..m.rows {
                        for col0 in (0..m.cols).step_by(L) {
                            let top = row * grid.stride + col0;
                            let r = V::load_f(far.add(top + centre));
                            let lanes = (1u32 << (m.cols - col0).min(L)) - 1;
                            let used = V::mask_bits(V::gt_f(inf, r)) & lanes;
                            if used == 0 {
                                continue;
                            }
                            let won = self.vote(grid, r, Row(top), used);
                            V::store_bytes(won, winners.as_mut_ptr().add(row * m.cols + col0));
                        }
                    }
                    CellWinners(winners)
                }

                /// The points `others` (behind a nearer one in their cell), `L` at a time: their
                /// classes into `out`.
                ///
                /// # Safety
                /// As [`Simd`]'s methods; `grid` is `m`'s, padded by `S / 2` and `L` columns; `L`
                /// is `V::L`.
                #[inline]
                #[target_feature(enable = $feature)]
                pub unsafe fn scattered<const L: usize>(
                    &self,
                    grid: &Grid,
                    m: &PointsInMap<'_>,
                    others: &[u32],
                    out: &mut [Option<ClassId>],
                ) where
                    Cells<L>: Windows<V>,
                {
                    debug_assert!(L == V::L);
                    scattered::<L>(m, others, out, |lanes, ranges, used| {
                        // SAFETY: as this function's.
                        unsafe {
                            let r = V::load_f(ranges.as_ptr());
                            let winners =
                                self.vote(grid, r, Cells(window_starts(grid, m, lanes)), used);
                            let mut w = [0i32; L];
                            V::store(winners, w.as_mut_ptr());
                            w
                        }
                    });
                }

                /// The winner of each lane (`used`: the lanes that hold a point, a bit mask): by
                /// keys, or by the exact distances where the keys are not sure.
                #[inline]
                #[target_feature(enable = $feature)]
                unsafe fn vote(&self, grid: &Grid, r: F, at: impl Windows<V>, used: u32) -> I {
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

                /// The signed difference times the weight of window cell `j`, from its ranges
                /// `far`.
                #[inline]
                #[target_feature(enable = $feature)]
                unsafe fn weighted(&self, far: F, r: F, j: usize) -> F {
                    V::mul_f(V::sub_f(far, r), self.weight[j])
                }

                /// The keys of row `dy` of every lane's window (see the module), and the classes of
                /// its middle cell (the centre's, in the centre's row).
                #[inline]
                #[target_feature(enable = $feature)]
                unsafe fn row_keys(
                    &self,
                    grid: &Grid,
                    r: F,
                    at: impl Windows<V>,
                    dy: usize,
                    high: I,
                ) -> ([I; S], I) {
                    let (far, cls) = at.row::<S>(grid, dy);
                    let mut keys = [high; S];
                    for (x, key) in keys.iter_mut().enumerate() {
                        let d = V::bits(self.weighted(far[x], r, dy * S + x));
                        *key = V::or(V::and(d, high), cls[x]);
                    }
                    (keys, cls[S / 2])
                }

                /// The winner of each lane from its `K` smallest keys (see the module), and the
                /// lanes (bit mask) where the keys may have chosen otherwise than the exact
                /// distances.
                #[inline]
                #[target_feature(enable = $feature)]
                unsafe fn vote_by_keys(&self, grid: &Grid, r: F, at: impl Windows<V>) -> (I, u32) {
                    let high = V::splat(!((1 << CLASS_BITS) - 1) & i32::MAX);
                    // The `K - 1` nearest of the other cells and the next, sorted: the centre (at
                    // distance 0, whatever its cell's range) is one of the `K` nearest unless `K`
                    // others tie with it, which the doubt below covers (the next then ties with the
                    // last chosen). Each row's keys are sorted, then merged into the kept ones (the
                    // first row's are the first kept); the centre's row comes last, without the
                    // centre.
                    let mut keys = [V::splat(i32::MAX); K];
                    let (mut row, _) = self.row_keys(grid, r, at, 0, high);
                    Self::sort(&mut row, S);
                    for (kept, &k) in keys.iter_mut().zip(&row) {
                        *kept = k;
                    }
                    for dy in (1..S).filter(|&dy| dy != S / 2) {
                        let (mut row, _) = self.row_keys(grid, r, at, dy, high);
                        Self::sort(&mut row, S);
                        Self::merge(&mut keys, &row, S);
                    }
                    let (mut row, centre) = self.row_keys(grid, r, at, S / 2, high);
                    for x in S / 2..S - 1 {
                        row[x] = row[x + 1];
                    }
                    Self::sort(&mut row, S - 1);
                    Self::merge(&mut keys, &row, S - 1);
                    let (kth, next) = (
                        V::srli::<CLASS_BITS>(keys[K - 2]),
                        V::srli::<CLASS_BITS>(keys[K - 1]),
                    );
                    // With a cutoff, empty cells (infinitely far) vote for nobody whichever are
                    // chosen: a tie there is no doubt. (Without one, -1: no truncated distance.)
                    let inf = V::splat(if self.setup.cutoff > 0.0 {
                        (f32::INFINITY.to_bits() >> CLASS_BITS) as i32
                    } else {
                        -1
                    });
                    let mut unsure = V::mask_andnot(V::eq(kth, inf), V::eq(kth, next));
                    let class = V::splat((1 << CLASS_BITS) - 1);
                    let nobody = V::splat(self.setup.nobody);
                    // The centre's class (within any cutoff), then the others'.
                    let mut c = [centre; K];
                    for a in 1..K {
                        c[a] = V::and(keys[a - 1], class);
                    }
                    if self.setup.cutoff > 0.0 {
                        let cut = V::splat((self.setup.cutoff.to_bits() >> CLASS_BITS) as i32);
                        for a in 1..K {
                            let t = V::srli::<CLASS_BITS>(keys[a - 1]);
                            unsure = V::mask_or(unsure, V::eq(t, cut));
                            c[a] = V::select(V::gt(t, cut), c[a], nobody);
                        }
                    }
                    (self.winner(&c), V::mask_bits(unsure))
                }

                /// The winner of each lane, its `K` nearest found by exact distance (bits, compared
                /// as integers) and class kept side by side: a candidate, coming after every kept
                /// one in window order, goes in front of the kept ones it is strictly nearer than.
                #[inline]
                #[target_feature(enable = $feature)]
                unsafe fn vote_exact(&self, grid: &Grid, r: F, at: impl Windows<V>) -> I {
                    // Nothing kept yet: every slot farther than anything (`i32::MAX`, above
                    // infinity).
                    let mut bd = [V::splat(i32::MAX); K];
                    let mut bc = [V::splat(0); K];
                    let abs = V::splat(i32::MAX);
                    for dy in 0..S {
                        let (far, cls) = at.row::<S>(grid, dy);
                        for x in 0..S {
                            let d = V::bits(self.weighted(far[x], r, dy * S + x));
                            // The centre at distance 0, whatever its cell's range.
                            let d = if dy * S + x == N / 2 {
                                V::splat(0)
                            } else {
                                V::and(d, abs)
                            };
                            Self::insert(&mut bd, &mut bc, d, cls[x]);
                        }
                    }
                    let nobody = V::splat(self.setup.nobody);
                    if self.setup.cutoff > 0.0 {
                        let cutoff = V::splat_f(self.setup.cutoff);
                        for a in 0..K {
                            let far = V::gt_f(V::from_bits(bd[a]), cutoff);
                            bc[a] = V::select(far, bc[a], nobody);
                        }
                    }
                    self.winner(&bc)
                }

                /// Keeps the candidate (distance bits `d`, class `cls`) among the `K` nearest:
                /// entry `i` becomes the median of entry `i - 1`, the candidate and entry `i` (all
                /// non-negative: signed minimum and maximum order them as their bits); classes
                /// follow the compares.
                #[inline]
                #[target_feature(enable = $feature)]
                unsafe fn insert(bd: &mut [I; K], bc: &mut [I; K], d: I, cls: I) {
                    let mut lt = V::gt(bd[K - 1], d);
                    for i in (1..K).rev() {
                        let lt_prev = V::gt(bd[i - 1], d);
                        let from_c = V::select(lt_prev, cls, bc[i - 1]);
                        bc[i] = V::select(lt, bc[i], from_c);
                        bd[i] = V::min(bd[i], V::max(bd[i - 1], d));
                        lt = lt_prev;
                    }
                    bd[0] = V::min(bd[0], d);
                    bc[0] = V::select(lt, bc[0], cls);
                }

                /// Most votes among the classes `c` of the nearest (`nobody` for those past the
                /// cutoff) that may win, ties to the lower id; no vote: the first class that may
                /// win (the scalar `Vote::winner`). The votes are counted for all classes at once,
                /// bit `c` of three masks holding class `c`'s count (up to 7) in binary.
                #[inline]
                #[target_feature(enable = $feature)]
                unsafe fn winner(&self, c: &[I; K]) -> I {
                    let zero = V::splat(0);
                    let (one, may) = (V::splat(1), V::splat(self.setup.can_win as i32));
                    let mut count = [zero; 3];
                    for &ca in c {
                        // nobody (31 at most) is not in the mask.
                        let mut carry = V::and(V::sllv(one, ca), may);
                        for bit in &mut count {
                            let next = V::and(*bit, carry);
                            *bit = V::xor(*bit, carry);
                            carry = next;
                        }
                    }
                    // The classes with most votes: from the count's highest bit down, those that
                    // have it where any does.
                    let mut best = V::or(V::or(count[0], count[1]), count[2]);
                    for &bit in count.iter().rev() {
                        let have = V::and(best, bit);
                        best = V::select(V::eq(have, zero), have, best);
                    }
                    // The lowest of them: its bit alone, as a float, whose exponent is its
                    // position.
                    let lowest = V::and(best, V::sub(zero, best));
                    let exponent = V::srli::<23>(V::bits(V::to_f(lowest)));
                    let id = V::sub(exponent, V::splat(127));
                    V::select(V::eq(best, zero), id, V::splat(self.setup.first_winner))
                }

                /// Sorts the first `n` keys of `v` (in every lane, signed order) by an optimal
                /// sorting network.
                #[inline]
                #[target_feature(enable = $feature)]
                unsafe fn sort<const M: usize>(v: &mut [I; M], n: usize) {
                    for &(i, j) in network(n) {
                        let (a, b) = (v[i as usize], v[j as usize]);
                        v[i as usize] = V::min(a, b);
                        v[j as usize] = V::max(a, b);
                    }
                }

                /// The `K` smallest of the sorted `kept` and the first `n` of `add` (sorted),
                /// sorted, into `kept`: the smaller of each kept key and the added key opposite it
                /// (`add` reversed) are the `K` smallest, in an order rising then falling, which a
                /// bitonic sorter orders.
                #[inline]
                #[target_feature(enable = $feature)]
                unsafe fn merge(kept: &mut [I; K], add: &[I; S], n: usize) {
                    for (i, k) in kept.iter_mut().enumerate() {
                        if K - 1 - i < n {
                            *k = V::min(*k, add[K - 1 - i]);
                        }
                    }
                    for &(i, j) in bitonic(K) {
                        let (a, b) = (kept[i as usize], kept[j as usize]);
                        kept[i as usize] = V::min(a, b);
                        kept[j as usize] = V::max(a, b);
                    }
                }
            }
        };
    };
}
pub(super) use kernel;
