//! Nothing lost silently: one test per defect of the hostile audit (issue "Nothing lost
//! silently"), on the real fixtures.

use std::path::{Path, PathBuf};

use crate::util::*;

/// A tiny seeded generator (splitmix64), so that every run mutates the same bytes.
pub struct Rng(pub u64);

impl Rng {
    pub fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    pub fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
}

fn shard_of(out: &Path) -> PathBuf {
    out.join("shards/train-00000.mcap")
}

#[test]
fn every_bit_flip_in_a_shard_is_caught() {
    let t = tmp();
    let out = t.path().join("out");
    convert_fixtures(&out, &["--format", "mcap", "--viz"]);
    let shard = shard_of(&out);
    let good = std::fs::read(&shard).unwrap();
    assert_eq!(run_text(&["inspect", s(&shard)]).0, 0);
    let mut rng = Rng(7);
    for k in 0..40 {
        let mut bad = good.clone();
        let at = rng.below(bad.len());
        bad[at] ^= 1 << rng.below(8);
        let copy = t.path().join(format!("flip{k}.mcap"));
        std::fs::write(&copy, &bad).unwrap();
        let (code, _, stderr) = run_text(&["inspect", s(&copy)]);
        assert_ne!(code, 0, "flip at byte {at} of {} went unnoticed", bad.len());
        assert!(stderr.contains(&format!("flip{k}.mcap")), "{stderr}");
        let (code, _, _) = run_text(&["score", "--gt", s(&copy), "--pred", s(&shard)]);
        assert_ne!(code, 0, "score read a shard flipped at byte {at}");
    }
    // A re-run rewrites a corrupted shard instead of keeping it as complete and intact.
    let mut bad = good.clone();
    bad[good.len() / 2] ^= 0x10;
    std::fs::write(&shard, &bad).unwrap();
    convert_fixtures(&out, &["--format", "mcap", "--viz"]);
    assert_eq!(std::fs::read(&shard).unwrap(), good);
}

#[test]
fn inspect_names_a_folder() {
    let t = tmp();
    let (code, _, stderr) = run_text(&["inspect", s(t.path())]);
    assert_ne!(code, 0);
    assert!(stderr.contains("a folder, not a shard"), "{stderr}");
}
