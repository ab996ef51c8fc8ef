//! A tiny, fully specified random generator (splitmix64), so that a seed gives the same split
//! and the same augmentation with every version of this tool (a library generator may change
//! its stream between releases).

/// The increment of splitmix64's state per value.
const GAMMA: u64 = 0x9E37_79B9_7F4A_7C15;

/// One step of splitmix64: advances `state` and returns the next value.
pub fn splitmix64(state: &mut u64) -> u64 {
    *state = state.wrapping_add(GAMMA);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// A seeded stream of splitmix64 values.
#[derive(Debug, Clone)]
pub struct SplitMix(u64);

impl SplitMix {
    /// The stream of `seed`.
    pub fn new(seed: u64) -> SplitMix {
        SplitMix(seed)
    }

    /// The next 64 random bits.
    #[inline]
    pub fn next_u64(&mut self) -> u64 {
        splitmix64(&mut self.0)
    }

    /// Skips `n` values: the stream then continues as if they had been drawn.
    #[inline]
    pub fn skip(&mut self, n: u64) {
        self.0 = self.0.wrapping_add(n.wrapping_mul(GAMMA));
    }

    /// Zero-mean noise of unit variance, bell-shaped and bounded: the sum of the four 16-bit
    /// uniforms of one draw (Irwin-Hall with n = 4), scaled to unit variance. Within
    /// +-2 sqrt(3) (about 3.46), no outliers; one draw per value, several times cheaper than an
    /// exact normal.
    #[inline]
    pub fn bell(&mut self) -> f32 {
        let v = self.next_u64();
        let sum = (v & 0xFFFF) + ((v >> 16) & 0xFFFF) + ((v >> 32) & 0xFFFF) + (v >> 48);
        // Four uniforms on [0, 1): mean 2, variance 4/12; sum / 65536 - 2 scaled by sqrt(3).
        ((sum as f32 + 2.0) * (1.0 / 65536.0) - 2.0) * 1.732_050_8
    }

    /// True with probability `p` (in [0, 1]).
    #[inline]
    pub fn chance(&mut self, p: f64) -> bool {
        // p * 2^64, saturating at the top: p = 1 is always true but for one value in 2^64.
        let threshold = (p * 18_446_744_073_709_551_616.0) as u64;
        self.next_u64() < threshold
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stream_is_pinned() {
        // The reference values of splitmix64 with seed 0 (Vigna's C implementation).
        let mut r = SplitMix::new(0);
        assert_eq!(r.next_u64(), 0xE220_A839_7B1D_CDAF);
        assert_eq!(r.next_u64(), 0x6E78_9E6A_A1B9_65F4);
    }

    #[test]
    fn bell_moments_and_bounds() {
        let mut r = SplitMix::new(7);
        let n = 200_000;
        let (mut s, mut s2, mut max) = (0.0f64, 0.0f64, 0.0f32);
        for _ in 0..n {
            let a = r.bell();
            s += a as f64;
            s2 += (a * a) as f64;
            max = max.max(a.abs());
        }
        let mean = s / n as f64;
        let var = s2 / n as f64 - mean * mean;
        assert!(
            mean.abs() < 0.01 && (var - 1.0).abs() < 0.01,
            "{mean} {var}"
        );
        assert!(max <= 2.0 * 3f32.sqrt() + 1e-4 && max > 2.5, "{max}");
        let hits = (0..n).filter(|_| r.chance(0.25)).count() as f64 / n as f64;
        assert!((hits - 0.25).abs() < 0.01, "{hits}");
        assert!(!r.chance(0.0));
        let (mut a, mut b) = (SplitMix::new(3), SplitMix::new(3));
        a.skip(5);
        (0..5).for_each(|_| {
            b.next_u64();
        });
        assert_eq!(a.next_u64(), b.next_u64());
    }
}
