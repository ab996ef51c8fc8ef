//! PROJECT: the map's six LiDAR channels, class, instance and mask of sixteen cells at a time
//! with AVX-512 ([`super::frame`]'s loop over the cells, the same bytes): each kept point's
//! values gathered by its index (an empty cell's lanes masked to zero), the six channels
//! interleaved by permutes, each output stored whole.

use std::mem::MaybeUninit;

use super::EMPTY;
use crate::geom::Point3;
use crate::label::ClassId;

/// What the cells read: the points' values and each cell's kept point and range.
#[derive(Clone, Copy)]
pub(super) struct Kept<'a> {
    pub points: &'a [Point3],
    pub intensity: &'a [f32],
    pub class: &'a [ClassId],
    pub instance: &'a [u16],
    /// The point each cell keeps ([`EMPTY`] for none), and its range (0 for none).
    pub cell_point: &'a [u32],
    pub cell_range: &'a [f32],
}

/// What the cells write, each slot once: six channels a cell, then a value a cell.
pub(super) struct Out<'a> {
    pub data: &'a mut [MaybeUninit<f32>],
    pub label: &'a mut [MaybeUninit<ClassId>],
    pub instance: &'a mut [MaybeUninit<u16>],
    pub mask: &'a mut [MaybeUninit<u8>],
}

/// Writes the cells of the whole groups of sixteen from the first on, where the CPU runs
/// AVX-512 ([`crate::simd::level`]); returns how many it wrote (0 otherwise), the rest being
/// the caller's.
pub(super) fn cells(values: Kept<'_>, out: Out<'_>) -> usize {
    let n = values.points.len();
    // Each gather reads four bytes at or below the point's own class (instance) value: four
    // points at least; indices times three within an i32.
    let fits = (4..=i32::MAX as usize / 3).contains(&n);
    #[cfg(target_arch = "x86_64")]
    if fits && crate::simd::level() == crate::simd::Level::Avx512 {
        // SAFETY: the CPU has AVX-512 F, BW, VL and DQ (`simd::level`).
        return unsafe { avx512::cells(values, out) };
    }
    let _ = (fits, values, out);
    0
}

#[cfg(target_arch = "x86_64")]
mod avx512 {
    use std::arch::x86_64::*;

    use super::{Kept, Out, EMPTY};

    /// Slot `t` of output vector `o % 3` (of a half of the sixteen cells) as (pair, which):
    /// the interleaved pairs (x, y), (z, intensity), (range, class) of the half's eight cells.
    const fn slot(o: usize, t: usize) -> (i64, i64) {
        let s = 8 * (o % 3) + t;
        ((s / 3) as i64, (s % 3) as i64)
    }

    /// The two permutes of output vector `o` (0-2) of a half: from (x, y) and (z, i) pairs,
    /// then (range, class) pairs put in.
    const fn permutes(o: usize) -> ([i64; 8], [i64; 8]) {
        let (mut first, mut second) = ([0; 8], [0; 8]);
        let mut t = 0;
        while t < 8 {
            let (j, which) = slot(o, t);
            first[t] = if which == 1 { 8 + j } else { j };
            second[t] = if which == 2 { 8 + j } else { t as i64 };
            t += 1;
        }
        (first, second)
    }

    const PERMUTES: [([i64; 8], [i64; 8]); 3] = [permutes(0), permutes(1), permutes(2)];

    /// The pass's constants: the empty-cell marker, the point count, the pairing and the
    /// permutes of the interleave.
    #[derive(Clone, Copy)]
    struct Consts {
        empty: __m512i,
        count: __m512i,
        pairs: [__m512i; 2],
        perm: [(__m512i, __m512i); 3],
    }

    /// Sixteen cells' values, gathered: which lanes keep a point and are valid, the (x, y),
    /// (z, intensity), (range, class) pairs of cells 0-7 and 8-15 as f64 lanes, class and
    /// instance.
    struct Group {
        valid: __mmask16,
        halves: [[__m512d; 3]; 2],
        class: __m512i,
        inst: __m512i,
    }

    /// [`super::cells`] on AVX-512.
    ///
    /// # Safety
    /// The CPU has AVX-512 F, BW, VL and DQ; there are 4 to `i32::MAX / 3` points.
    #[target_feature(enable = "avx512f,avx512bw,avx512vl,avx512dq")]
    pub(super) unsafe fn cells(v: Kept<'_>, out: Out<'_>) -> usize {
        let (n, cells) = (v.points.len(), v.cell_point.len());
        assert!(
            v.intensity.len() == n && v.class.len() == n && v.instance.len() == n,
            "a value a point"
        );
        assert!(v.cell_range.len() == cells && out.label.len() == cells);
        assert!(out.instance.len() == cells && out.mask.len() == cells);
        assert_eq!(out.data.len(), cells * 6, "six channels a cell");
        let groups = cells / 16;
        let zero = _mm512_setzero_si512();
        let pairs_lo = _mm512_setr_epi32(0, 16, 1, 17, 2, 18, 3, 19, 4, 20, 5, 21, 6, 22, 7, 23);
        let mut k = Consts {
            empty: _mm512_set1_epi32(EMPTY as i32),
            count: _mm512_set1_epi32(n as i32),
            pairs: [pairs_lo, _mm512_add_epi32(pairs_lo, _mm512_set1_epi32(8))],
            perm: [(zero, zero); 3],
        };
        for (p, (a, b)) in k.perm.iter_mut().zip(&PERMUTES) {
            // SAFETY: eight i64 are 64 bytes.
            *p = unsafe {
                (
                    _mm512_loadu_si512(a.as_ptr().cast()),
                    _mm512_loadu_si512(b.as_ptr().cast()),
                )
            };
        }
        let mut out = out;
        for g in 0..groups {
            // SAFETY: cells g * 16..g * 16 + 16 are within every per-cell slice (groups * 16 <=
            // cells, asserted with the outputs' lengths above).
            unsafe {
                let group = gather(&v, g * 16, &k);
                store(&mut out, g * 16, &group, &k);
            }
        }
        groups * 16
    }

    /// The values of cells `c0..c0 + 16`, gathered from their kept points.
    ///
    /// # Safety
    /// As [`cells`]; the cells are within `v`'s per-cell slices.
    #[target_feature(enable = "avx512f,avx512bw,avx512vl,avx512dq")]
    #[inline]
    unsafe fn gather(v: &Kept<'_>, c0: usize, k: &Consts) -> Group {
        let zero = _mm512_setzero_si512();
        let (one, three) = (_mm512_set1_epi32(1), _mm512_set1_epi32(3));
        // SAFETY: the caller's.
        let (cp, range) = unsafe {
            (
                _mm512_loadu_si512(v.cell_point.as_ptr().add(c0).cast()),
                _mm512_loadu_ps(v.cell_range.as_ptr().add(c0)),
            )
        };
        let keep = _mm512_cmpneq_epi32_mask(cp, k.empty);
        assert_eq!(
            _mm512_mask_cmplt_epu32_mask(keep, cp, k.count),
            keep,
            "a cell keeps one of the points"
        );
        let i = _mm512_maskz_mov_epi32(keep, cp);
        let i3 = _mm512_add_epi32(i, _mm512_add_epi32(i, i));
        // The class byte from the four bytes ending at it (from the first, for the first three
        // points), the instance from the two values ending at it.
        let class_at = _mm512_sub_epi32(_mm512_max_epu32(i, three), three);
        let inst_at = _mm512_sub_epi32(_mm512_max_epu32(i, one), one);
        let xyz = v.points.as_ptr().cast::<f32>();
        // SAFETY: every kept index is below n (asserted), an empty lane reads nothing; the
        // class reads bytes class_at..class_at + 4 <= max(i + 1, 4) <= n, the instance values
        // inst_at..inst_at + 2 <= max(i + 1, 2) <= n.
        let nothing = _mm512_setzero_ps();
        let (x, y, z, it, class, inst) = unsafe {
            (
                _mm512_mask_i32gather_ps::<4>(nothing, keep, i3, xyz.cast()),
                _mm512_mask_i32gather_ps::<4>(nothing, keep, i3, xyz.add(1).cast()),
                _mm512_mask_i32gather_ps::<4>(nothing, keep, i3, xyz.add(2).cast()),
                _mm512_mask_i32gather_ps::<4>(nothing, keep, i, v.intensity.as_ptr().cast()),
                _mm512_mask_i32gather_epi32::<1>(zero, keep, class_at, v.class.as_ptr().cast()),
                _mm512_mask_i32gather_epi32::<2>(zero, keep, inst_at, v.instance.as_ptr().cast()),
            )
        };
        let class = _mm512_srlv_epi32(class, _mm512_slli_epi32::<3>(_mm512_sub_epi32(i, class_at)));
        let class = _mm512_and_si512(class, _mm512_set1_epi32(0xff));
        let inst = _mm512_srlv_epi32(inst, _mm512_slli_epi32::<4>(_mm512_sub_epi32(i, inst_at)));
        let inst = _mm512_and_si512(inst, _mm512_set1_epi32(0xffff));
        let range = _mm512_maskz_mov_ps(keep, range);
        let valid = keep & _mm512_cmp_ps_mask::<_CMP_GT_OQ>(range, _mm512_setzero_ps());
        let class_f = _mm512_cvtepi32_ps(class);
        let mut halves = [[_mm512_setzero_pd(); 3]; 2];
        for (half, idx) in halves.iter_mut().zip(k.pairs) {
            for (p, (a, b)) in half.iter_mut().zip([(x, y), (z, it), (range, class_f)]) {
                *p = _mm512_castps_pd(_mm512_permutex2var_ps(a, idx, b));
            }
        }
        Group {
            valid,
            halves,
            class,
            inst,
        }
    }

    /// Writes cells `c0..c0 + 16`: the six channels interleaved, then label, instance, mask.
    ///
    /// # Safety
    /// As [`cells`]; the cells are within `out`'s slices.
    #[target_feature(enable = "avx512f,avx512bw,avx512vl,avx512dq")]
    #[inline]
    unsafe fn store(out: &mut Out<'_>, c0: usize, g: &Group, k: &Consts) {
        // SAFETY: the caller's.
        unsafe {
            let data = out.data.as_mut_ptr().add(c0 * 6).cast::<f64>();
            for (h, [xy, zi, rc]) in g.halves.into_iter().enumerate() {
                for (o, (first, second)) in k.perm.iter().enumerate() {
                    let t = _mm512_permutex2var_pd(xy, *first, zi);
                    let t = _mm512_permutex2var_pd(t, *second, rc);
                    _mm512_storeu_pd(data.add(8 * (3 * h + o)), t);
                }
            }
            _mm_storeu_si128(
                out.label.as_mut_ptr().add(c0).cast(),
                _mm512_cvtepi32_epi8(g.class),
            );
            _mm256_storeu_si256(
                out.instance.as_mut_ptr().add(c0).cast(),
                _mm512_cvtepi32_epi16(g.inst),
            );
            _mm_storeu_si128(
                out.mask.as_mut_ptr().add(c0).cast(),
                _mm_maskz_mov_epi8(g.valid, _mm_set1_epi8(1)),
            );
        }
    }
}
