//! What the kNN's lane kernels are written in: [`Simd`], the lane operations of one instruction
//! set (AVX2's eight lanes, AVX-512's sixteen), and the sorting networks the kernel runs on keys
//! (a row of the window sorted, and merged into the kept keys, the `K` smallest so far).

/// The lane operations of an instruction set, `L` points at a time: floats `F`, 32-bit integers
/// `I` (keys, classes) and lane masks `M`. The kernel ([`super::keys`]) is written once in them.
///
/// Every method is `unsafe`: the CPU must have the instruction set. Each implementation enables
/// its instruction set on its methods (`#[target_feature]`), and so does the kernel built on it
/// ([`super::keys::kernel`]), so that every operation is inlined to its instruction.
pub(super) trait Simd: Copy {
    /// Lanes.
    const L: usize;
    type F: Copy;
    type I: Copy;
    type M: Copy;
    unsafe fn splat_f(x: f32) -> Self::F;
    unsafe fn splat(x: i32) -> Self::I;
    /// `L` floats from `p`.
    unsafe fn load_f(p: *const f32) -> Self::F;
    /// `L` bytes from `p`, one a lane.
    unsafe fn load_bytes(p: *const u8) -> Self::I;
    /// Each lane's lowest byte (its value below 256) to `p`, `L` bytes.
    unsafe fn store_bytes(v: Self::I, p: *mut u8);
    /// The lanes to `p`, `L` integers.
    unsafe fn store(v: Self::I, p: *mut i32);
    unsafe fn sub_f(a: Self::F, b: Self::F) -> Self::F;
    unsafe fn mul_f(a: Self::F, b: Self::F) -> Self::F;
    /// The floats' bits.
    unsafe fn bits(a: Self::F) -> Self::I;
    /// The floats of these bits.
    unsafe fn from_bits(a: Self::I) -> Self::F;
    /// The integers as floats (rounded).
    unsafe fn to_f(a: Self::I) -> Self::F;
    unsafe fn and(a: Self::I, b: Self::I) -> Self::I;
    unsafe fn or(a: Self::I, b: Self::I) -> Self::I;
    unsafe fn xor(a: Self::I, b: Self::I) -> Self::I;
    unsafe fn sub(a: Self::I, b: Self::I) -> Self::I;
    /// Signed minimum.
    unsafe fn min(a: Self::I, b: Self::I) -> Self::I;
    /// Signed maximum.
    unsafe fn max(a: Self::I, b: Self::I) -> Self::I;
    /// `a` shifted left by each lane's `n` (0 from 32 on).
    unsafe fn sllv(a: Self::I, n: Self::I) -> Self::I;
    /// `a` shifted right by `N`, zeros in.
    unsafe fn srli<const N: i32>(a: Self::I) -> Self::I;
    unsafe fn eq(a: Self::I, b: Self::I) -> Self::M;
    /// Signed `a > b`.
    unsafe fn gt(a: Self::I, b: Self::I) -> Self::M;
    /// `a > b`, false where either is NaN.
    unsafe fn gt_f(a: Self::F, b: Self::F) -> Self::M;
    /// `b` in the lanes of `m`, `a` in the others.
    unsafe fn select(m: Self::M, a: Self::I, b: Self::I) -> Self::I;
    unsafe fn mask_or(a: Self::M, b: Self::M) -> Self::M;
    /// `b` and not `a`.
    unsafe fn mask_andnot(a: Self::M, b: Self::M) -> Self::M;
    /// Bit `l` set for lane `l` in the mask.
    unsafe fn mask_bits(m: Self::M) -> u32;
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
