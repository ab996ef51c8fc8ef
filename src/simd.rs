//! Runtime dispatch to wider vectors for the passes over every point.
//!
//! The library is built for baseline x86-64, whose SSE2 leaves four lanes (or none: no `floor`,
//! no blends) to the loops over every point. [`with_simd`] runs a closure compiled for the widest
//! [`Level`] the CPU has (AVX-512, else AVX2); the results are the same bit for bit, since Rust
//! never fuses a multiply and an add and these loops are exact integer and IEEE operations
//! (tested: every path on real scans, and the binary's pinned output hashes on each path, chosen
//! by `KITTI2PGM_NO_AVX512=1` and `KITTI2PGM_NO_AVX2=1`).

use std::cell::Cell;

/// The instruction sets [`with_simd`] compiles its closure for, narrowest first.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Level {
    /// The build's own (SSE2 on x86-64).
    Baseline,
    /// AVX2.
    Avx2,
    /// AVX-512 (F, BW, VL and DQ).
    Avx512,
}

impl Level {
    /// The widest this process runs: what the CPU has, narrowed by `KITTI2PGM_NO_AVX512`
    /// (AVX2 at most) or `KITTI2PGM_NO_AVX2` (the baseline).
    pub fn widest() -> Level {
        #[cfg(target_arch = "x86_64")]
        {
            use std::sync::OnceLock;
            static WIDEST: OnceLock<Level> = OnceLock::new();
            *WIDEST.get_or_init(|| {
                let off = |var: &str| std::env::var_os(var).is_some();
                let avx512 = std::is_x86_feature_detected!("avx512f")
                    && std::is_x86_feature_detected!("avx512bw")
                    && std::is_x86_feature_detected!("avx512vl")
                    && std::is_x86_feature_detected!("avx512dq");
                if !std::is_x86_feature_detected!("avx2") || off("KITTI2PGM_NO_AVX2") {
                    Level::Baseline
                } else if avx512 && !off("KITTI2PGM_NO_AVX512") {
                    Level::Avx512
                } else {
                    Level::Avx2
                }
            })
        }
        #[cfg(not(target_arch = "x86_64"))]
        Level::Baseline
    }

    /// The levels this process runs, narrowest first (the tests compare them).
    pub fn available() -> Vec<Level> {
        [Level::Baseline, Level::Avx2, Level::Avx512]
            .into_iter()
            .filter(|&l| l <= Level::widest())
            .collect()
    }
}

/// The level [`with_simd`] takes on this thread now (the CPU's widest, narrowed by
/// [`at_most`]): for the passes written with a level's own instructions.
pub fn level() -> Level {
    Level::widest().min(LIMIT.with(Cell::get))
}

thread_local! {
    /// The widest level [`with_simd`] takes on this thread ([`at_most`]).
    static LIMIT: Cell<Level> = const { Cell::new(Level::Avx512) };
}

/// Runs `f` compiled for the widest [`Level`] the CPU has, else as built. Give it an
/// `#[inline(always)]` closure whose captures are by value (`move`), or references that the
/// loop only reads, so that the closure's body is compiled inside the wider function.
#[inline(always)]
pub fn with_simd<R>(f: impl FnOnce() -> R) -> R {
    run_at_most(Level::Avx512, f)
}

/// [`with_simd`] with AVX2 at most: for the loops that AVX-512 runs slower (measured: where the
/// compiler builds a mask register bit by bit, as from `Option<u8>` tags).
#[inline(always)]
pub fn with_avx2<R>(f: impl FnOnce() -> R) -> R {
    run_at_most(Level::Avx2, f)
}

#[inline(always)]
fn run_at_most<R>(most: Level, f: impl FnOnce() -> R) -> R {
    #[cfg(target_arch = "x86_64")]
    {
        #[target_feature(enable = "avx2")]
        fn avx2<R>(f: impl FnOnce() -> R) -> R {
            f()
        }
        #[target_feature(enable = "avx512f,avx512bw,avx512vl,avx512dq")]
        fn avx512<R>(f: impl FnOnce() -> R) -> R {
            f()
        }
        match Level::widest().min(LIMIT.with(Cell::get)).min(most) {
            // SAFETY: the CPU has AVX-512 (`Level::widest`).
            Level::Avx512 => return unsafe { avx512(f) },
            // SAFETY: the CPU has AVX2 (`Level::widest`).
            Level::Avx2 => return unsafe { avx2(f) },
            Level::Baseline => {}
        }
    }
    f()
}

/// The index of the first of `values` that is `bad`: one branch-free pass over all of them
/// ([`with_simd`]), the search for the culprit only when there is one (a search per value does
/// not vectorise). `bad` should not branch itself (`&` and `|`, not `&&` and `||`).
#[inline(always)]
pub fn first_where<T>(values: &[T], bad: impl Fn(&T) -> bool + Copy) -> Option<usize> {
    let any = with_simd(
        #[inline(always)]
        move || values.iter().fold(false, |any, v| any | bad(v)),
    );
    if any {
        values.iter().position(bad)
    } else {
        None
    }
}

/// Runs `f` with every [`with_simd`] on this thread taking `level` at most (tests compare the
/// paths with it).
pub fn at_most<R>(level: Level, f: impl FnOnce() -> R) -> R {
    struct Restore(Level);
    impl Drop for Restore {
        fn drop(&mut self) {
            LIMIT.with(|l| l.set(self.0));
        }
    }
    let _restore = Restore(LIMIT.with(|l| l.replace(level)));
    f()
}

/// Runs `f` with every [`with_simd`] on this thread taking the baseline path.
pub fn baseline<R>(f: impl FnOnce() -> R) -> R {
    at_most(Level::Baseline, f)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The limit in force inside `with_simd` on this thread.
    fn limit() -> Level {
        LIMIT.with(Cell::get)
    }

    #[test]
    fn the_levels_run_narrowest_first_up_to_the_widest() {
        let levels = Level::available();
        assert_eq!(levels.first(), Some(&Level::Baseline));
        assert_eq!(levels.last(), Some(&Level::widest()));
        assert!(levels.is_sorted());
    }

    /// `at_most` narrows for the closure alone, nested or unwinding, and every path computes
    /// the same bits (a sum of square roots: no multiply-add fused, whatever the vectors).
    #[test]
    fn at_most_narrows_for_its_closure_and_restores() {
        let values: Vec<f32> = (0..1000).map(|i| i as f32 * 0.37).collect();
        let sum = || with_simd(|| values.iter().map(|v| v.sqrt() * 1.5 + 0.25).sum::<f32>());
        let want = baseline(sum);
        for level in Level::available() {
            at_most(level, || {
                assert_eq!(limit(), level);
                assert_eq!(sum().to_bits(), want.to_bits(), "{level:?}");
                assert_eq!(with_avx2(sum).to_bits(), want.to_bits(), "{level:?}");
                baseline(|| assert_eq!(limit(), Level::Baseline));
                assert_eq!(limit(), level);
            });
        }
        assert_eq!(limit(), Level::Avx512);
        let unwound = std::panic::catch_unwind(|| baseline(|| panic!("inside")));
        assert!(unwound.is_err());
        assert_eq!(limit(), Level::Avx512, "restored after a panic");
    }
}
