//! Ground truth in every form it comes in (issue: the redesign): a convert folder, its
//! `lidar_2d` folder, a bare folder of SqueezeSeg-style maps (float64 as well), shards. `score`,
//! `stats` and `preview` read all of them, with the map parameters recorded or stated as assumed.

use std::path::Path;

use kitti2pgm::format::npy::read_f32;
use kitti2pgm::report::truth::{GroundTruth, Provenance, Source};

use crate::util::*;

/// A float64 `.npy` (NumPy format 1.0), as `np.save` writes one.
fn encode_f64(shape: &[u64], data: &[f64]) -> Vec<u8> {
    let dims: Vec<String> = shape.iter().map(u64::to_string).collect();
    let mut header = format!(
        "{{'descr': '<f8', 'fortran_order': False, 'shape': ({}), }}",
        dims.join(", ")
    );
    let unpadded = 10 + header.len() + 1;
    header.extend(std::iter::repeat_n(
        ' ',
        unpadded.next_multiple_of(64) - unpadded,
    ));
    header.push('\n');
    let mut out = b"\x93NUMPY\x01\x00".to_vec();
    out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    for v in data {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out
}

/// A folder of the fixtures' maps as SqueezeSeg publishes them: `<id>.npy`, float64, nothing else.
fn squeezeseg_folder(lidar_2d: &Path, dst: &Path) {
    std::fs::create_dir_all(dst).unwrap();
    for e in std::fs::read_dir(lidar_2d).unwrap() {
        let p = e.unwrap().path();
        let (shape, data) = read_f32(&p).unwrap();
        let wide: Vec<f64> = data.iter().map(|v| *v as f64).collect();
        std::fs::write(dst.join(p.file_name().unwrap()), encode_f64(&shape, &wide)).unwrap();
    }
}

fn json(args: &[&str]) -> (serde_json::Value, String) {
    let (code, stdout, stderr) = run_text(args);
    assert_eq!(code, 0, "{args:?}: {stderr}");
    (serde_json::from_str(&stdout).unwrap(), stderr)
}

#[test]
fn score_reads_every_form_of_ground_truth() {
    let t = tmp();
    let raw = fixtures();
    let out = t.path().join("out");
    let (code, _, e) = run_text(&["convert", s(&raw), "--out", s(&out), "--format", "npy,mcap"]);
    assert_eq!(code, 0, "{e}");
    let l2d = out.join("lidar_2d");
    let official = t.path().join("squeezeseg/lidar_2d");
    squeezeseg_folder(&l2d, &official);
    let (reference, _) = json(&["score", "--gt", s(&out), "--pred", s(&l2d), "--json"]);
    assert_eq!(reference["classes"]["car"]["iou"], 1.0);
    for gt in [&l2d, &official, &out.join("shards")] {
        let (j, stderr) = json(&["score", "--gt", s(gt), "--pred", s(&l2d), "--json"]);
        assert_eq!(j, reference, "--gt {}", gt.display());
        // Only the bare folder carries no provenance, and says what it assumes.
        assert_eq!(
            stderr.contains("assuming SqueezeSeg's map"),
            gt == &official,
            "{stderr}"
        );
    }
    // The official maps scored as predictions too (float64 label channel).
    let (j, _) = json(&["score", "--gt", s(&out), "--pred", s(&official), "--json"]);
    assert_eq!(j["classes"]["car"]["iou"], 1.0);
}

#[test]
fn provenance_is_read_back_typed() {
    let t = tmp();
    let raw = fixtures();
    let out = t.path().join("out");
    convert_fixtures(&out, &["--fov-deg", "360", "--cols", "1024"]);
    for path in [out.clone(), out.join("lidar_2d")] {
        let gt = GroundTruth::open(&path).unwrap();
        assert_eq!(
            gt.provenance,
            Provenance::Recorded(out.join("convert_summary.json"))
        );
        assert_eq!(gt.params.spec.fov.0, 360.0);
        assert_eq!(gt.params.spec.cols, 1024);
        assert_eq!(gt.frames.len(), 3);
        assert!(matches!(gt.source, Source::Npy(_)));
        assert_eq!(gt.dir.as_ref().unwrap().root, out);
    }
    // The point protocol re-projects the scans with the recorded 360-degree map: the same
    // figures through the folder and through its lidar_2d.
    let points = |gt: &Path| {
        json(&[
            "score",
            "--gt",
            s(gt),
            "--pred",
            s(&out.join("labels")),
            "--points",
            "--raw",
            s(&raw),
            "--json",
        ])
        .0
    };
    let a = points(&out);
    assert_eq!(a, points(&out.join("lidar_2d")));
    assert_eq!(a["classes"]["car"]["iou"], 1.0);
    // A bare folder states its assumption (90 degrees, rows and columns from the files).
    let bare = t.path().join("bare");
    copy_tree(&out.join("lidar_2d"), &bare);
    let gt = GroundTruth::open(&bare).unwrap();
    assert_eq!(gt.provenance, Provenance::Assumed);
    assert_eq!((gt.params.spec.rows, gt.params.spec.cols), (64, 1024));
    assert!(gt
        .provenance_note()
        .contains("assuming SqueezeSeg's map (64x1024 over 90 deg"));
    // Nothing to read: named.
    let e = GroundTruth::open(t.path()).unwrap_err().to_string();
    assert!(
        e.contains(s(t.path())) && e.contains("neither a convert output folder"),
        "{e}"
    );
}

#[test]
fn stats_reads_shards_only_and_bare_folders() {
    let t = tmp();
    let raw = fixtures();
    let npy = t.path().join("npy");
    let mcap = t.path().join("mcap");
    for (out, format) in [(&npy, "npy"), (&mcap, "mcap,labels")] {
        let (code, _, e) = run_text(&[
            "convert",
            s(&raw),
            "--out",
            s(out),
            "--rgb",
            "--format",
            format,
        ]);
        assert_eq!(code, 0, "{e}");
    }
    assert!(!mcap.join("lidar_2d").exists());
    let (a, _) = json(&["stats", s(&npy), "--json"]);
    let (b, _) = json(&["stats", s(&mcap), "--json"]);
    for key in ["normalisation", "class_weights", "class_map"] {
        assert_eq!(a[key], b[key], "{key}");
    }
    assert_eq!(a["splits"]["all"]["cells"], b["splits"]["all"]["cells"]);
    assert_eq!(a["splits"]["all"]["points"], b["splits"]["all"]["points"]);
    assert_eq!(
        a["splits"]["all"]["row_fill"],
        b["splits"]["all"]["row_fill"]
    );
    let official = t.path().join("official");
    squeezeseg_folder(&npy.join("lidar_2d"), &official);
    let (c, stderr) = json(&["stats", s(&official), "--json"]);
    assert!(stderr.contains("assuming SqueezeSeg's map"), "{stderr}");
    assert_eq!(a["normalisation"], c["normalisation"]);
    assert_eq!(c["splits"]["all"]["points"], serde_json::Value::Null);
}

#[test]
fn preview_draws_folders_and_shards() {
    let t = tmp();
    let out = t.path().join("out");
    convert_fixtures(&out, &["--format", "npy,mcap", "--rgb"]);
    for (input, dir) in [
        (out.join("shards"), "from_shards"),
        (out.join("lidar_2d"), "from_npy"),
    ] {
        let pics = t.path().join(dir);
        let (code, _, e) = run_text(&["preview", s(&input), "--out", s(&pics)]);
        assert_eq!(code, 0, "{e}");
        let png = pics.join("2011_09_26_0001_0000000000.png");
        let img = kitti2pgm::raster::read(&png).unwrap();
        assert_eq!((img.width(), img.height()), (512, 4 * 128 + 3 * 4));
    }
    // The same frame drawn from a shard and from its .npy: the same picture.
    let a = std::fs::read(t.path().join("from_shards/2011_09_26_0052_0000000000.png")).unwrap();
    let b = std::fs::read(t.path().join("from_npy/2011_09_26_0052_0000000000.png")).unwrap();
    assert_eq!(a, b);
}

#[test]
fn files_in_the_old_spelling_still_read() {
    // Summaries and shard metadata written before the JSON used the CLI's names spelled the
    // values as Rust's identifiers ("Rings", "Raw", "LeftOut", "Nearest", "Lz4"): they read to
    // the same typed parameters.
    use kitti2pgm::format::shard::ShardMetadata;
    use kitti2pgm::format::summary;
    let t = tmp();
    let out = t.path().join("out");
    convert_fixtures(&out, &["--rgb", "--format", "npy,mcap"]);
    let path = out.join("convert_summary.json");
    let new = summary::read(&path).unwrap().unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    for name in [
        "\"row_mode\": \"rings\"",
        "\"source\": \"raw\"",
        "\"sampling\": \"nearest\"",
        "\"compression\": \"lz4\"",
        "\"absent_in_miou\": \"left_out\"",
    ] {
        assert!(text.contains(name), "{name} written: {text}");
    }
    let old_text = text
        .replace("\"rings\"", "\"Rings\"")
        .replace("\"raw\"", "\"Raw\"")
        .replace("\"nearest\"", "\"Nearest\"")
        .replace("\"lz4\"", "\"Lz4\"")
        .replace("\"left_out\"", "\"LeftOut\"");
    std::fs::write(&path, old_text).unwrap();
    assert_eq!(summary::read(&path).unwrap().unwrap(), new);
    let gt = GroundTruth::open(&out).unwrap();
    assert_eq!(gt.params, new.params.map);
    // Shard metadata.
    let shard =
        kitti2pgm::format::shard::Shard::open(&out.join("shards/train-00000.mcap")).unwrap();
    let md = shard.metadata().unwrap();
    let mut map = md.to_map();
    let params = map["params"]
        .replace("\"rings\"", "\"Rings\"")
        .replace("\"lz4\"", "\"Lz4\"");
    map.insert("params".into(), params);
    assert_eq!(
        ShardMetadata::from_map(&map, Path::new("old.mcap")).unwrap(),
        md
    );
    // An unknown value is named with the names it may take.
    map.insert(
        "params".into(),
        map["params"].replace("\"Rings\"", "\"Bins\""),
    );
    let e = ShardMetadata::from_map(&map, Path::new("odd.mcap")).unwrap_err();
    assert!(
        e.to_string()
            .contains("unknown row mode `Bins` (one of: rings, elevation)"),
        "{e}"
    );
}
