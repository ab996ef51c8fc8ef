//! MCAP shards: round trip against the `.npy` output, metadata, viz topics, corruption,
//! interruption and re-runs.

use std::path::{Path, PathBuf};

use kitti2pgm::format::npy::read_f32;
use kitti2pgm::format::shard::{Shard, FRAME_TOPIC};

use crate::util::*;

fn convert_both(out: &Path, extra: &[&str]) -> serde_json::Value {
    let root = fixtures();
    let mut a = vec![
        "convert",
        s(&root),
        "--out",
        s(out),
        "--format",
        "npy,mcap",
        "--rgb",
        "--json",
    ];
    a.extend_from_slice(extra);
    let (code, stdout, stderr) = run_text(&a);
    assert_eq!(code, 0, "{stderr}");
    serde_json::from_str(&stdout).unwrap()
}

#[test]
fn shards_hold_exactly_the_npy_frames() {
    let t = tmp();
    let out = t.path().join("out");
    let j = convert_both(&out, &["--val-drives", "52"]);
    assert_eq!(j["shards_written"], 2);
    let train = Shard::open(&out.join("shards/train-00000.mcap")).unwrap();
    let val = Shard::open(&out.join("shards/val-00000.mcap")).unwrap();
    let (tf, e) = train.frames();
    assert!(e.is_none());
    let (vf, e) = val.frames();
    assert!(e.is_none());
    assert_eq!(
        tf.iter().map(|f| f.id.as_str()).collect::<Vec<_>>(),
        ["2011_09_26_0001_0000000000", "2011_09_26_0001_0000000045"]
    );
    assert_eq!(vf.len(), 1);
    for f in tf.iter().chain(&vf) {
        let (shape, npy) = read_f32(&out.join(format!("lidar_2d/{}.npy", f.id))).unwrap();
        assert_eq!(shape, vec![64, 512, 9]);
        assert_eq!((f.height, f.width), (64, 512));
        assert_eq!(
            f.channels,
            ["x", "y", "z", "intensity", "range", "r", "g", "b"]
        );
        let tensor = f.clone().into_frame(Path::new("shard")).unwrap().data;
        for (cell, (n, s8)) in npy.chunks_exact(9).zip(tensor.chunks_exact(8)).enumerate() {
            let expect: Vec<u32> = [0, 1, 2, 3, 4, 6, 7, 8]
                .iter()
                .map(|&c| n[c].to_bits())
                .collect();
            assert_eq!(
                s8.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
                expect,
                "cell {cell} of {}",
                f.id
            );
            assert_eq!(f.label[cell] as f32, n[5]);
            assert_eq!(f.mask[cell], (n[4] > 0.0) as u8);
        }
        assert_eq!(f.rgb_valid.len(), 64 * 512);
        assert!(f
            .instance
            .chunks_exact(2)
            .any(|w| u16::from_le_bytes([w[0], w[1]]) > 0));
    }
    // Frame 0 of drive 0001 has timestamps; drive 0052 has none (0).
    assert!(tf[0].timestamp_ns > 1_300_000_000_000_000_000);
    assert_eq!(vf[0].timestamp_ns, 0);
    assert_eq!(vf[0].split, "val");
    let md = train.metadata().unwrap();
    assert_eq!(md.version, env!("CARGO_PKG_VERSION"));
    assert_eq!(md.split, kitti2pgm::plan::split::Split::Train);
    assert_eq!(
        md.drives,
        ["2011_09_26_drive_0001_sync", "2011_09_26_drive_0052_sync"]
    );
    assert_eq!(md.frames.len(), 2);
    assert_eq!(md.params.map.spec.rows, 64);
    assert_eq!(
        md.params.map.class_map,
        kitti2pgm::label::ClassMap::kitti_paper()
    );
    let sh = md.params.shards.as_ref().unwrap();
    assert_eq!(sh.compression, kitti2pgm::provenance::ShardCompression::Lz4);
    // Chunk indexes and a summary are present: a reader can seek.
    let summary = train.summary().unwrap();
    assert!(summary.chunk_indexes.len() >= 2);
    assert!(summary
        .channels
        .values()
        .any(|c| c.topic == FRAME_TOPIC && c.message_encoding == "protobuf"));
    assert!(summary
        .schemas
        .values()
        .any(|s| s.name == "kitti2pgm.Frame" && s.encoding == "protobuf"));
}

#[test]
fn shard_size_compression_and_inspect() {
    let t = tmp();
    let out = t.path().join("out");
    convert_both(
        &out,
        &["--shard-frames", "1", "--compression", "zstd", "--viz"],
    );
    let names: Vec<String> = {
        let mut v: Vec<String> = std::fs::read_dir(out.join("shards"))
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .collect();
        v.sort();
        v
    };
    assert_eq!(
        names,
        ["train-00000.mcap", "train-00001.mcap", "train-00002.mcap"],
        "SqueezeSeg's split: all fixture drives are train"
    );
    let (code, stdout, stderr) =
        run_text(&["inspect", "--json", s(&out.join("shards/train-00001.mcap"))]);
    assert_eq!(code, 0, "{stderr}");
    let j: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    let i = &j[0];
    assert_eq!(i["frames"], 1);
    assert_eq!(i["first_frame"], "2011_09_26_0001_0000000045");
    assert_eq!(i["compression"], serde_json::json!(["zstd"]));
    assert!(i["compression_ratio"].as_f64().unwrap() > 1.2);
    for topic in [
        "/kitti2pgm/frame",
        "/kitti2pgm/viz/points",
        "/kitti2pgm/viz/boxes",
        "/kitti2pgm/viz/image",
    ] {
        assert_eq!(i["topics"][topic], 1, "{topic}");
    }
    // Class counts agree with the .npy.
    let (_, npy) = read_f32(&out.join("lidar_2d/2011_09_26_0001_0000000045.npy")).unwrap();
    let cars = npy
        .chunks_exact(9)
        .filter(|c| c[4] > 0.0 && c[5] == 1.0)
        .count();
    assert_eq!(i["class_cells"]["car"], cars);
    let (code, stdout, _) = run_text(&["inspect", s(&out.join("shards/train-00000.mcap"))]);
    assert_eq!(code, 0);
    assert!(
        stdout.contains("ratio") && stdout.contains("class cells"),
        "{stdout}"
    );
}

#[test]
fn viz_topics_are_foxglove_protobuf() {
    let t = tmp();
    let out = t.path().join("out");
    convert_both(&out, &["--viz"]);
    let shard = Shard::open(&out.join("shards/train-00000.mcap")).unwrap();
    let mut seen = std::collections::BTreeMap::new();
    for m in mcap::MessageStream::new(shard.bytes()).unwrap() {
        let m = m.unwrap();
        if m.channel.topic == FRAME_TOPIC {
            continue;
        }
        use foxglove::schemas::{CompressedImage, PointCloud, SceneUpdate};
        use prost::Message as _;
        let schema = m.channel.schema.as_ref().unwrap();
        assert_eq!(schema.encoding, "protobuf");
        assert_eq!(m.channel.message_encoding, "protobuf");
        match schema.name.as_str() {
            "foxglove.PointCloud" => {
                let v = PointCloud::decode(&m.data[..]).unwrap();
                assert_eq!(v.point_stride, 21);
                assert_eq!(v.fields.len(), 9);
                assert_eq!(v.data.len() % 21, 0);
                assert!(v.data.len() / 21 > 100_000, "the whole scan");
            }
            "foxglove.SceneUpdate" => {
                let v = SceneUpdate::decode(&m.data[..]).unwrap();
                assert!(!v.entities[0].cubes.is_empty());
            }
            "foxglove.CompressedImage" => {
                let v = CompressedImage::decode(&m.data[..]).unwrap();
                assert_eq!(v.format, "png");
                assert!(v.data.starts_with(b"\x89PNG"));
            }
            other => panic!("unexpected schema {other}"),
        }
        *seen.entry(schema.name.clone()).or_insert(0) += 1;
    }
    assert_eq!(seen.len(), 3);
    assert!(seen.values().all(|&n| n == 3));
}

#[test]
fn truncated_shard_names_the_shard_and_the_frame() {
    let t = tmp();
    let out = t.path().join("out");
    convert_both(&out, &[]);
    let path = out.join("shards/train-00000.mcap");
    let bytes = std::fs::read(&path).unwrap();
    let cut = t.path().join("cut.mcap");
    // Keep the first frame's chunk and part of the second.
    let shard = Shard::open(&path).unwrap();
    let chunks = shard.summary().unwrap().chunk_indexes;
    let second = chunks
        .iter()
        .map(|c| c.chunk_start_offset)
        .filter(|&o| o > chunks[0].chunk_start_offset)
        .min()
        .unwrap();
    std::fs::write(&cut, &bytes[..second as usize + 1000]).unwrap();
    let s2 = Shard::open(&cut).unwrap();
    assert!(s2.summary().unwrap_err().to_string().contains("cut.mcap"));
    let (frames, err) = s2.frames();
    assert_eq!(frames.len(), 1, "the frame before the cut stays readable");
    let e = err.unwrap().to_string();
    assert!(
        e.contains("cut.mcap") && e.contains("frame #1 after frame 2011_09_26_0001_0000000000"),
        "{e}"
    );
    let (code, _, stderr) = run_text(&["inspect", s(&cut)]);
    assert_eq!(code, 1);
    assert!(stderr.contains("cut.mcap"), "{stderr}");
    // Corrupted bytes inside a chunk: the CRC or the decoder catches it.
    let mut bad = bytes.clone();
    let mid = (chunks[0].chunk_start_offset + chunks[0].chunk_length / 2) as usize;
    for b in &mut bad[mid..mid + 64] {
        *b ^= 0x5a;
    }
    let corrupt = t.path().join("corrupt.mcap");
    std::fs::write(&corrupt, &bad).unwrap();
    let (_, err) = Shard::open(&corrupt).unwrap().frames();
    assert!(err.unwrap().to_string().contains("corrupt.mcap"));
}

#[test]
fn reruns_skip_intact_shards_and_rewrite_the_rest() {
    let t = tmp();
    let out = t.path().join("out");
    let first = convert_both(&out, &["--shard-frames", "2"]);
    assert_eq!(first["shards_written"], 2);
    let again = convert_both(&out, &["--shard-frames", "2"]);
    assert_eq!(again["shards_written"], 0);
    assert_eq!(again["shards_skipped"], 2);
    assert_eq!(
        again["frames_skipped"]["already in a complete, intact shard"],
        3
    );
    // A truncated shard (an interrupted copy, a full disk) is rewritten; so is one made with
    // other parameters.
    let p = out.join("shards/train-00001.mcap");
    let len = std::fs::metadata(&p).unwrap().len();
    std::fs::OpenOptions::new()
        .write(true)
        .open(&p)
        .unwrap()
        .set_len(len / 2)
        .unwrap();
    let third = convert_both(&out, &["--shard-frames", "2"]);
    assert_eq!(third["shards_written"], 1);
    assert_eq!(third["shards_skipped"], 1);
    assert!(Shard::open(&p).unwrap().summary().is_ok());
    let other = convert_both(&out, &["--shard-frames", "2", "--compression", "none"]);
    assert_eq!(other["shards_written"], 2);
    // No temporary file is left behind.
    assert!(std::fs::read_dir(out.join("shards")).unwrap().all(|e| !e
        .unwrap()
        .file_name()
        .to_string_lossy()
        .starts_with(".tmp-")));
}

#[test]
fn failed_frames_are_left_out_and_recorded() {
    let t = tmp();
    let root = fixture_copy(t.path());
    std::fs::write(
        root.join("2011_09_26/2011_09_26_drive_0001_sync/velodyne_points/data/0000000045.bin"),
        b"bad",
    )
    .unwrap();
    let out = t.path().join("out");
    let (code, stdout, _) = run_text(&[
        "convert",
        s(&root),
        "--out",
        s(&out),
        "--format",
        "mcap",
        "--json",
    ]);
    assert_eq!(code, 3);
    let j: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(j["frames_converted"], 2);
    assert!(
        !out.join("lidar_2d").exists(),
        "--format mcap writes no .npy"
    );
    let shard = Shard::open(&out.join("shards/train-00000.mcap")).unwrap();
    let md = shard.metadata().unwrap();
    assert_eq!(
        md.failed,
        ["2011_09_26_0001_0000000045"
            .parse::<kitti2pgm::source::kitti::FrameId>()
            .unwrap()]
    );
    assert_eq!(shard.frames().0.len(), 2);
    // A shard with failed frames is not "intact": the re-run tries again.
    let (_, stdout, _) = run_text(&[
        "convert",
        s(&root),
        "--out",
        s(&out),
        "--format",
        "mcap",
        "--json",
    ]);
    let j: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(j["shards_written"], 1);
}

#[test]
fn shards_are_identical_whatever_the_thread_count() {
    let t = tmp();
    let (a, b) = (t.path().join("a"), t.path().join("b"));
    for (dir, threads) in [(&a, "1"), (&b, "3")] {
        let (code, _, stderr) = run_text(&[
            "--threads",
            threads,
            "convert",
            s(&fixtures()),
            "--out",
            s(dir),
            "--format",
            "mcap",
            "--rgb",
            "--viz",
        ]);
        assert_eq!(code, 0, "{stderr}");
    }
    let read = |d: &Path| std::fs::read(d.join("shards/train-00000.mcap")).unwrap();
    assert!(
        read(&a) == read(&b),
        "shards differ between 1 and 3 threads"
    );
}

/// The library's seeded generator (splitmix64), so that every run mutates the same bytes.
pub struct Rng(pub u64);

impl Rng {
    pub fn next(&mut self) -> u64 {
        kitti2pgm::rng::splitmix64(&mut self.0)
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
        // In process: what inspect and score read the shard with.
        let e = kitti2pgm::report::inspect::inspect(&copy)
            .expect_err(&format!(
                "flip at byte {at} of {} went unnoticed",
                bad.len()
            ))
            .to_string();
        assert!(e.contains(&format!("flip{k}.mcap")), "{e}");
        let truth = kitti2pgm::report::truth::GroundTruth::open(&copy);
        let scored = truth.and_then(|gt| {
            let preds = kitti2pgm::report::score::Predictions::index(&shard)?;
            let opts = kitti2pgm::report::score::ScoreOptions {
                protocol: kitti2pgm::report::score::Protocol::Cells,
                missing_as_background: false,
                raw: None,
                unproject: kitti2pgm::project::unproject::Method::Cell,
            };
            let none = Default::default();
            kitti2pgm::report::score::score(&gt, None, &preds, &opts, &none, &|_| {})
        });
        assert!(scored.is_err(), "score read a shard flipped at byte {at}");
        // The command says so too (exit status, the shard named): once is enough.
        if k == 0 {
            let (code, _, stderr) = run_text(&["inspect", s(&copy)]);
            assert_ne!(code, 0);
            assert!(stderr.contains("flip0.mcap"), "{stderr}");
        }
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
    assert!(stderr.contains("a folder, not a regular file"), "{stderr}");
}

#[test]
fn point_shards_with_viz_are_readable_and_kept() {
    let t = tmp();
    let out = t.path().join("out");
    convert_fixtures(&out, &["--format", "points", "--viz"]);
    let shard = out.join("points/train-00000.mcap");
    let (code, stdout, e) = run_text(&["inspect", s(&shard)]);
    assert_eq!(code, 0, "{e}");
    assert!(stdout.contains("/kitti2pgm/viz/points"), "{stdout}");
    let before = std::fs::read(&shard).unwrap();
    let (code, j, e) = convert_json(&fixtures(), &out, &["--format", "points", "--viz"]);
    assert_eq!(code, 0, "{e}");
    assert_eq!(j["shards_skipped"], 1, "the intact shard is kept: {j}");
    assert_eq!(std::fs::read(&shard).unwrap(), before);
    let frames: Vec<_> = kitti2pgm::format::shard::Shard::open_verified(&shard)
        .unwrap()
        .points()
        .unwrap();
    assert_eq!(frames.len(), 3);
}

#[test]
fn a_damaged_chunk_names_its_own_frame_whatever_the_compression() {
    let t = tmp();
    for compression in ["none", "lz4", "zstd"] {
        let out = t.path().join(compression);
        convert_fixtures(
            &out,
            &[
                "--format",
                "mcap",
                "--shard-frames",
                "3",
                "--compression",
                compression,
            ],
        );
        let shard = out.join("shards/train-00000.mcap");
        let opened = kitti2pgm::format::shard::Shard::open(&shard).unwrap();
        let summary = opened.summary().unwrap();
        let md = opened.metadata().unwrap();
        let good = std::fs::read(&shard).unwrap();
        // Chunks in file order: frame k's chunk is the k-th (one frame a chunk).
        let mut chunks: Vec<_> = summary.chunk_indexes.iter().collect();
        chunks.sort_by_key(|c| c.chunk_start_offset);
        for (k, c) in chunks.iter().enumerate() {
            let mut bad = good.clone();
            let at = (c.chunk_start_offset + c.chunk_length * 2 / 3) as usize;
            bad[at] ^= 0x08;
            let path = t.path().join(format!("{compression}{k}.mcap"));
            std::fs::write(&path, &bad).unwrap();
            let (code, _, e) = run_text(&["inspect", s(&path)]);
            assert_ne!(code, 0);
            let want = format!("frame #{k} ({})", md.frames[k]);
            assert!(e.contains(&want), "{compression}: {want} in {e}");
        }
    }
}
