//! Runtime dispatch to AVX2 for the passes over every point.
//!
//! The library is built for baseline x86-64, whose SSE2 leaves four lanes (or none: no `floor`,
//! no blends) to the loops over every point. [`with_avx2`] runs a closure compiled with AVX2
//! where the CPU has it; the results are the same bit for bit, since Rust never fuses a multiply
//! and an add and these loops are exact integer and IEEE operations (tested: both paths on real
//! scans, and the binary's pinned output hashes with `KITTI2PGM_NO_AVX2=1`).

use std::cell::Cell;

thread_local! {
    static BASELINE: Cell<bool> = const { Cell::new(false) };
}

/// Runs `f` compiled with AVX2 where the CPU has it, else as built. Give it an
/// `#[inline(always)]` closure whose captures are by value (`move`), or references that the
/// loop only reads, so that the closure's body is compiled inside the AVX2 function.
#[inline(always)]
pub fn with_avx2<R>(f: impl FnOnce() -> R) -> R {
    #[cfg(target_arch = "x86_64")]
    {
        #[target_feature(enable = "avx2")]
        fn avx2<R>(f: impl FnOnce() -> R) -> R {
            f()
        }
        if avx2_available() && !BASELINE.with(Cell::get) {
            // SAFETY: the CPU has AVX2.
            return unsafe { avx2(f) };
        }
    }
    f()
}

/// The index of the first of `values` that is `bad`: one branch-free pass over all of them
/// ([`with_avx2`]), the search for the culprit only when there is one (a search per value does
/// not vectorise). `bad` should not branch itself (`&` and `|`, not `&&` and `||`).
#[inline(always)]
pub fn first_where<T>(values: &[T], bad: impl Fn(&T) -> bool + Copy) -> Option<usize> {
    let any = with_avx2(
        #[inline(always)]
        move || values.iter().fold(false, |any, v| any | bad(v)),
    );
    if any {
        values.iter().position(bad)
    } else {
        None
    }
}

/// Whether [`with_avx2`] takes the AVX2 path on this machine: false off x86-64, or where the
/// environment sets `KITTI2PGM_NO_AVX2` (the baseline path of the same build, for checks).
pub fn avx2_available() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        use std::sync::OnceLock;
        static AVAILABLE: OnceLock<bool> = OnceLock::new();
        *AVAILABLE.get_or_init(|| {
            std::is_x86_feature_detected!("avx2") && std::env::var_os("KITTI2PGM_NO_AVX2").is_none()
        })
    }
    #[cfg(not(target_arch = "x86_64"))]
    false
}

/// Runs `f` with every [`with_avx2`] on this thread taking the baseline path (tests compare
/// the two paths with it).
pub fn baseline<R>(f: impl FnOnce() -> R) -> R {
    struct Restore(bool);
    impl Drop for Restore {
        fn drop(&mut self) {
            BASELINE.with(|b| b.set(self.0));
        }
    }
    let _restore = Restore(BASELINE.with(|b| b.replace(true)));
    f()
}
