//! The AVX2 kernel's building blocks on whole vectors, every lane its own point: sorting
//! networks on keys (a row of the kNN's window sorted, and merged into the kept keys, the `K`
//! smallest so far), bytes widened to lanes, and eight vectors transposed.

use std::arch::x86_64::*;

/// Sorts the first `n` keys of `v` (in every lane, signed order) by an optimal sorting network.
#[inline]
#[target_feature(enable = "avx2")]
pub(super) fn sort<const S: usize>(v: &mut [__m256i; S], n: usize) {
    for &(i, j) in network(n) {
        let (a, b) = (v[i as usize], v[j as usize]);
        v[i as usize] = _mm256_min_epi32(a, b);
        v[j as usize] = _mm256_max_epi32(a, b);
    }
}

/// The `K` smallest of the sorted `kept` and the first `n` of `add` (sorted), sorted, into
/// `kept`: the smaller of each kept key and the added key opposite it (`add` reversed) are the
/// `K` smallest, in an order rising then falling, which a bitonic sorter orders.
#[inline]
#[target_feature(enable = "avx2")]
pub(super) fn merge<const K: usize, const S: usize>(
    kept: &mut [__m256i; K],
    add: &[__m256i; S],
    n: usize,
) {
    for (i, k) in kept.iter_mut().enumerate() {
        if K - 1 - i < n {
            *k = _mm256_min_epi32(*k, add[K - 1 - i]);
        }
    }
    for &(i, j) in bitonic(K) {
        let (a, b) = (kept[i as usize], kept[j as usize]);
        kept[i as usize] = _mm256_min_epi32(a, b);
        kept[j as usize] = _mm256_max_epi32(a, b);
    }
}

/// The comparators of an optimal sorting network of `n` inputs, 0 to 8 (Knuth, TAOCP 5.3.4;
/// the tests check each on every 0-1 input).
#[rustfmt::skip]
pub(super) const fn network(n: usize) -> &'static [(u8, u8)] {
    match n {
        0 | 1 => &[],
        2 => &[(0, 1)],
        3 => &[(1, 2), (0, 2), (0, 1)],
        4 => &[(0, 1), (2, 3), (0, 2), (1, 3), (1, 2)],
        5 => &[
            (0, 1), (3, 4), (2, 4), (2, 3), (0, 3), (0, 2), (1, 4), (1, 3), (1, 2),
        ],
        6 => &[
            (1, 2), (4, 5), (0, 2), (3, 5), (0, 1), (3, 4), (2, 5), (0, 3), (1, 4), (2, 4),
            (1, 3), (2, 3),
        ],
        7 => &[
            (1, 2), (3, 4), (5, 6), (0, 2), (3, 5), (4, 6), (0, 1), (4, 5), (2, 6), (0, 4),
            (1, 5), (0, 3), (2, 5), (1, 3), (2, 4), (2, 3),
        ],
        8 => &[
            (0, 2), (1, 3), (4, 6), (5, 7), (0, 4), (1, 5), (2, 6), (3, 7), (0, 1), (2, 3),
            (4, 5), (6, 7), (2, 4), (3, 5), (1, 4), (3, 6), (1, 2), (3, 4), (5, 6),
        ],
        _ => panic!("sorting networks of at most 8 inputs"),
    }
}

/// The comparators that sort `n` keys (0 to 8) rising, then falling: a bitonic sorter of the
/// next power of two inputs, its first ones below every key (they stay in front, so their
/// compares are dropped; the tests check each on every such 0-1 input).
#[rustfmt::skip]
pub(super) const fn bitonic(n: usize) -> &'static [(u8, u8)] {
    match n {
        0 | 1 => &[],
        2 => &[(0, 1)],
        3 => &[(0, 2), (1, 2)],
        4 => &[(0, 2), (1, 3), (0, 1), (2, 3)],
        5 => &[(0, 4), (1, 3), (2, 4), (1, 2), (3, 4)],
        6 => &[(0, 4), (1, 5), (2, 4), (3, 5), (0, 1), (2, 3), (4, 5)],
        7 => &[
            (0, 4), (1, 5), (2, 6), (0, 2), (3, 5), (4, 6), (1, 2), (3, 4), (5, 6),
        ],
        8 => &[
            (0, 4), (1, 5), (2, 6), (3, 7), (0, 2), (1, 3), (4, 6), (5, 7), (0, 1), (2, 3),
            (4, 5), (6, 7),
        ],
        _ => panic!("bitonic sorters of at most 8 inputs"),
    }
}

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
