//! Seeded mutations of real input files: bit flips, truncation, insertion, line deletion.
//! Shared by `examples/fuzz_parsers` (long runs) and the mutation test in `tests/it/fuzz.rs`.

/// A seeded generator (splitmix64, as the split rule's): the same seed, the same mutations.
pub struct Rng(pub u64);

impl Rng {
    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        kitti2pgm::plan::split::splitmix64(&mut self.0)
    }

    /// A number in `0..n` (`n > 0`).
    pub fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }
}

/// One mutation of `input`: a few bit flips, a truncation, an insertion of random bytes, or
/// (for text) the deletion or duplication of a line. Never returns the input unchanged.
pub fn mutate(input: &[u8], rng: &mut Rng) -> Vec<u8> {
    let mut out = input.to_vec();
    let text = std::str::from_utf8(input).is_ok();
    loop {
        match rng.below(if text { 5 } else { 3 }) {
            0 => {
                for _ in 0..1 + rng.below(3) {
                    if !out.is_empty() {
                        let at = rng.below(out.len());
                        out[at] ^= 1 << rng.below(8);
                    }
                }
            }
            1 => {
                let keep = rng.below(out.len().max(1));
                out.truncate(keep);
            }
            2 => {
                let at = rng.below(out.len() + 1);
                let n = 1 + rng.below(16);
                let bytes: Vec<u8> = (0..n).map(|_| rng.next_u64() as u8).collect();
                out.splice(at..at, bytes);
            }
            k => {
                let s = String::from_utf8_lossy(&out).into_owned();
                let mut lines: Vec<&str> = s.lines().collect();
                if !lines.is_empty() {
                    let i = rng.below(lines.len());
                    if k == 3 {
                        lines.remove(i);
                    } else {
                        lines.insert(i, lines[i]);
                    }
                }
                out = (lines.join("\n") + "\n").into_bytes();
            }
        }
        if out != input {
            return out;
        }
    }
}
