//! The bytes `convert` writes are pinned: every `.npy` and `.label` of the fixtures (with and
//! without colour), and a digest of the 30 shared scans' outputs where `../shared` is present.
//! A refactoring that changes one byte of the training data fails here first.

use std::path::Path;

use sha2::{Digest, Sha256};

use crate::util::*;

fn hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// (relative path, SHA-256) of every file under `lidar_2d/` and `labels/`, sorted.
fn hashes(out: &Path) -> Vec<(String, String)> {
    tree_bytes(out)
        .into_iter()
        .filter(|(p, _)| p.starts_with("lidar_2d") || p.starts_with("labels"))
        .map(|(p, bytes)| (p, hex(&bytes)))
        .collect()
}

/// One digest of a whole output tree: SHA-256 over `path hash` lines.
fn tree_digest(out: &Path) -> String {
    let lines: String = hashes(out)
        .iter()
        .map(|(p, h)| format!("{p} {h}\n"))
        .collect();
    hex(lines.as_bytes())
}

fn convert(raw: &Path, out: &Path, extra: &[&str]) {
    convert_on(raw, out, extra, CodePath::Widest);
}

/// Which of the binary's code paths runs ([`kitti2pgm::simd`]).
#[derive(Debug, Clone, Copy)]
enum CodePath {
    /// The widest vectors the CPU has (as users run it).
    Widest,
    /// AVX2 at most (`KITTI2PGM_NO_AVX512=1`).
    Avx2,
    /// The baseline x86-64 build (`KITTI2PGM_NO_AVX2=1`).
    Baseline,
}

fn convert_on(raw: &Path, out: &Path, extra: &[&str], path: CodePath) {
    let mut args = vec![
        "convert",
        s(raw),
        "--out",
        s(out),
        "--all-frames",
        "--no-progress",
    ];
    args.extend_from_slice(extra);
    let mut cmd = std::process::Command::new(env!("CARGO_BIN_EXE_kitti2pgm"));
    match path {
        CodePath::Widest => {}
        CodePath::Avx2 => {
            cmd.env("KITTI2PGM_NO_AVX512", "1");
        }
        CodePath::Baseline => {
            cmd.env("KITTI2PGM_NO_AVX2", "1");
        }
    }
    let o = cmd.args(&args).output().expect("run kitti2pgm");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

const LABELS: [(&str, &str); 3] = [
    (
        "labels/2011_09_26_drive_0001_sync/0000000000.label",
        "b9fdeb0ef5f1002595797ee0c9dd08c66002a82fe0371ccc432d6d851d4e930d",
    ),
    (
        "labels/2011_09_26_drive_0001_sync/0000000045.label",
        "3765206d885c1f2c1b1e6e6b47c4e833b5e6a88695a42f671996d95c162fecc0",
    ),
    (
        "labels/2011_09_26_drive_0052_sync/0000000000.label",
        "988eabcb92ed9514ad6cbf1cb3f2ed9fa7f322a5a630d41306835a75da8a9d89",
    ),
];

#[test]
fn fixture_outputs_are_pinned() {
    let lidar = [
        (
            "lidar_2d/2011_09_26_0001_0000000000.npy",
            "0e2abd0c221164d2668523d4e685f14e9a5614fe62d2c5483487f564ae594b87",
        ),
        (
            "lidar_2d/2011_09_26_0001_0000000045.npy",
            "8c53543b84d890d16c2f2f005c6f3c535fafc6b3ed7438663e1dc8d0b409fc2b",
        ),
        (
            "lidar_2d/2011_09_26_0052_0000000000.npy",
            "3f79d62dee27558ff0d5b262d60fa0f84af4296baba242cfc9688ae717d9e544",
        ),
    ];
    let rgb = [
        (
            "lidar_2d/2011_09_26_0001_0000000000.npy",
            "82fae8e3bff18292f4ed891e3f00d8312254555f9c2199aca848c90c5e70a37c",
        ),
        (
            "lidar_2d/2011_09_26_0001_0000000045.npy",
            "c85f25e931e1c4c9914418e049b31241817f568424898621fb876f3f534528d1",
        ),
        (
            "lidar_2d/2011_09_26_0052_0000000000.npy",
            "c532a4c2c3b4a32270d990b94c7be7760c73414983e3723a26ae71cd167c94d4",
        ),
    ];
    // Every code path: the same bytes (where the CPU lacks a path's vectors, it runs the
    // narrower one).
    let paths = [CodePath::Widest, CodePath::Avx2, CodePath::Baseline];
    let runs = paths
        .into_iter()
        .flat_map(|path| [(&[][..], lidar, path), (&["--rgb"][..], rgb, path)]);
    for (extra, npys, path) in runs {
        let t = tmp();
        let out = t.path().join("out");
        convert_on(&fixtures(), &out, extra, path);
        let mut want: Vec<(String, String)> = LABELS
            .iter()
            .chain(npys.iter())
            .map(|(p, h)| (p.to_string(), h.to_string()))
            .collect();
        want.sort();
        assert_eq!(
            hashes(&out),
            want,
            "outputs with {extra:?} changed ({path:?})"
        );
    }
}

#[test]
#[ignore = "needs ../shared"]
fn shared_outputs_are_pinned() {
    let shared = needs_shared("kitti");
    for (extra, digest) in [
        (
            &[][..],
            "73709c1d65aae8b8824dab9ce3b146582d1bfc750ad6ae4e6d622756ba6cb092",
        ),
        (
            &["--rgb"][..],
            "f565929c8f4f0ac9fca515cd5edb7e5a086e4f5abef75ab542f195bf5f3f9ead",
        ),
    ] {
        let t = tmp();
        let out = t.path().join("out");
        convert(&shared.join("raw"), &out, extra);
        assert_eq!(
            tree_digest(&out),
            digest,
            "outputs of ../shared/kitti with {extra:?} changed"
        );
    }
}
