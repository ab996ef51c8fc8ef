//! Mutation fuzzing of the whole tool on real inputs, bounded for CI (seconds): each input kind
//! (calibration text, tracklet XML, velodyne scan, camera PNG, shard) is mutated with a seeded
//! generator (bit flips, truncation, insertion, line deletion) and the binary run on it. No run
//! may panic or hang, and a run that exits 0 must have written outputs that are right for the
//! input it was given. `cargo run --release --example fuzz_parsers -- SECONDS` runs the parsers
//! in process for longer.

use std::path::Path;
use std::time::Duration;

#[path = "../../examples/fuzz_parsers/mutate.rs"]
mod mutate;

use kitti2pgm::format::npy::read_f32;
use mutate::{mutate, Rng};

use crate::util::*;

/// Runs the binary with a deadline; returns (exit code, stderr). Panics on a hang or a panic.
fn run_bounded(args: &[&str]) -> (i32, String) {
    let (code, err) =
        run_limited(args, Duration::from_secs(60)).unwrap_or_else(|| panic!("{args:?} hung"));
    assert!(!err.contains("panicked"), "{args:?} panicked: {err}");
    (code, err)
}

/// Checks that a conversion that exited 0 wrote outputs consistent with its input: one map and
/// one `.label` per scan, ranges the norms of the points, finite values, class ids, empty cells
/// zero, colours in [0, 1], one label per point of the `.bin`.
fn outputs_are_right(raw_drive: &Path, out: &Path) {
    let data = raw_drive.join("velodyne_points/data");
    for e in std::fs::read_dir(&data).unwrap() {
        let bin = e.unwrap().path();
        let stem = bin.file_stem().unwrap().to_str().unwrap().to_string();
        let id = format!("2011_09_26_0052_{stem}");
        let (shape, m) = read_f32(&out.join(format!("lidar_2d/{id}.npy"))).unwrap();
        assert_eq!(&shape[..2], &[64, 512]);
        let c = shape[2] as usize;
        for cell in m.chunks_exact(c) {
            assert!(cell.iter().all(|v| v.is_finite()), "{id}: {cell:?}");
            let r = (cell[0] * cell[0] + cell[1] * cell[1] + cell[2] * cell[2]).sqrt();
            assert!(
                (cell[4] - r).abs() <= 1e-3 * r.max(1.0),
                "{id}: range {cell:?}"
            );
            assert!([0.0, 1.0, 2.0, 3.0].contains(&cell[5]));
            if cell[4] == 0.0 {
                assert!(cell.iter().all(|v| *v == 0.0));
            }
            if c == 9 {
                assert!(cell[6..].iter().all(|v| (0.0..=1.0).contains(v)));
            }
        }
        let points = std::fs::metadata(&bin).unwrap().len() / 16;
        let labels =
            std::fs::read(out.join(format!("labels/2011_09_26_drive_0052_sync/{stem}.label")))
                .unwrap();
        assert_eq!(labels.len() as u64, points * 4, "{id}: one label per point");
        assert!(labels.chunks_exact(4).all(|w| w[0] <= 3 && w[1] == 0));
    }
}

#[test]
fn mutated_inputs_never_panic_hang_or_pass_wrong() {
    let t = tmp();
    let mut rng = Rng(2026);
    let kinds = [
        ("2011_09_26/calib_cam_to_cam.txt", "--rgb"),
        ("2011_09_26/calib_velo_to_cam.txt", "--rgb"),
        (
            "2011_09_26/2011_09_26_drive_0052_sync/tracklet_labels.xml",
            "--all-frames",
        ),
        (
            "2011_09_26/2011_09_26_drive_0052_sync/velodyne_points/data/0000000000.bin",
            "--all-frames",
        ),
        (
            "2011_09_26/2011_09_26_drive_0052_sync/image_02/data/0000000000.png",
            "--rgb",
        ),
    ];
    let mut run = 0;
    for (file, option) in kinds {
        let original = std::fs::read(fixtures().join(file)).unwrap();
        for _ in 0..12 {
            run += 1;
            let dir = t.path().join(format!("run{run}"));
            let root = fixture_copy(&dir);
            std::fs::write(root.join(file), mutate(&original, &mut rng)).unwrap();
            let drive = root.join("2011_09_26/2011_09_26_drive_0052_sync");
            let out = dir.join("out");
            let (code, err) = run_bounded(&[
                "--no-progress",
                "convert",
                s(&drive),
                "--out",
                s(&out),
                option,
            ]);
            assert!([0, 1, 3].contains(&code), "{file}: exit {code}: {err}");
            if code == 0 {
                outputs_are_right(&drive, &out);
            }
        }
    }
}

#[test]
fn mutated_shards_are_refused() {
    let t = tmp();
    let out = t.path().join("out");
    convert_fixtures(&out, &["--format", "mcap"]);
    let shard = out.join("shards/train-00000.mcap");
    let original = std::fs::read(&shard).unwrap();
    let mut rng = Rng(11);
    for k in 0..12 {
        let bad = mutate(&original, &mut rng);
        let path = t.path().join(format!("m{k}.mcap"));
        std::fs::write(&path, &bad).unwrap();
        let (code, err) = run_bounded(&["inspect", s(&path)]);
        assert_ne!(code, 0, "a mutated shard passed inspect");
        assert!(err.contains(&format!("m{k}.mcap")), "{err}");
        let (code, _) = run_bounded(&["score", "--gt", s(&path), "--pred", s(&shard)]);
        assert_ne!(code, 0, "a mutated shard was scored");
    }
}

#[test]
fn mutated_object_and_semantickitti_inputs_never_panic_hang_or_pass_wrong() {
    let t = tmp();
    let mut rng = Rng(2027);
    let kinds = [
        ("kitti_object", "training/label_2/000001.txt", "000001"),
        ("kitti_object", "training/calib/000001.txt", "000001"),
        ("kitti_object", "training/velodyne/000001.bin", "000001"),
        (
            "semantickitti",
            "sequences/00/labels/000000.label",
            "000000",
        ),
        ("semantickitti", "sequences/00/calib.txt", "000000"),
    ];
    let mut run = 0;
    for (source, file, frame) in kinds {
        let original = std::fs::read(copy_of(source, &t.path().join("orig")).join(file)).unwrap();
        for _ in 0..8 {
            run += 1;
            let dir = t.path().join(format!("run{run}"));
            let root = copy_of(source, &dir);
            std::fs::write(root.join(file), mutate(&original, &mut rng)).unwrap();
            let out = dir.join("out");
            let (code, err) = run_bounded(&[
                "--no-progress",
                "convert",
                s(&root),
                "--out",
                s(&out),
                "--rgb",
            ]);
            assert!([0, 1, 3].contains(&code), "{file}: exit {code}: {err}");
            if code == 0 {
                // One label per point of the (possibly mutated) scan.
                let (bin, labels) = if source == "kitti_object" {
                    (
                        root.join(format!("training/velodyne/{frame}.bin")),
                        out.join(format!("labels/object/{frame}.label")),
                    )
                } else {
                    (
                        root.join(format!("sequences/00/velodyne/{frame}.bin")),
                        out.join(format!("labels/00/{frame}.label")),
                    )
                };
                let points = std::fs::metadata(&bin).unwrap().len() / 16;
                let n = std::fs::metadata(&labels).unwrap().len();
                assert_eq!(n, points * 4, "{file}: one label per point");
            }
        }
    }
}

#[test]
fn mutated_predictions_and_point_shards_never_panic_or_pass() {
    let t = tmp();
    let out = t.path().join("out");
    convert_fixtures(&out, &["--format", "npy,points"]);
    let mut rng = Rng(31);
    // Point shards: every mutation refused by inspect.
    let shard = out.join("points/train-00000.mcap");
    let original = std::fs::read(&shard).unwrap();
    for k in 0..10 {
        let path = t.path().join(format!("p{k}.mcap"));
        std::fs::write(&path, mutate(&original, &mut rng)).unwrap();
        let (code, err) = run_bounded(&["inspect", s(&path)]);
        assert_ne!(code, 0, "a mutated point shard passed inspect");
        assert!(err.contains(&format!("p{k}.mcap")), "{err}");
    }
    // Map predictions (.npy) and per-point .label predictions: refused or scored, never a
    // panic or a hang.
    let npy = out.join("lidar_2d/2011_09_26_0052_0000000000.npy");
    let label = out.join("labels/2011_09_26_drive_0052_sync/0000000000.label");
    for (k, (src, ext)) in [(npy, "npy"), (label, "label")]
        .into_iter()
        .cycle()
        .take(16)
        .enumerate()
    {
        let pred = t.path().join(format!("pred{k}"));
        let bytes = mutate(&std::fs::read(&src).unwrap(), &mut rng);
        let args: Vec<String> = if ext == "npy" {
            std::fs::create_dir_all(&pred).unwrap();
            std::fs::write(pred.join(src.file_name().unwrap()), bytes).unwrap();
            vec![
                "score".into(),
                "--gt".into(),
                s(&out).into(),
                "--pred".into(),
                s(&pred).into(),
                "--missing-as-background".into(),
            ]
        } else {
            let d = pred.join("2011_09_26_drive_0052_sync");
            std::fs::create_dir_all(&d).unwrap();
            std::fs::write(d.join(src.file_name().unwrap()), bytes).unwrap();
            vec![
                "score".into(),
                "--gt".into(),
                s(&out).into(),
                "--pred".into(),
                s(&pred).into(),
                "--points".into(),
                "--raw".into(),
                s(&fixtures()).into(),
                "--missing-as-background".into(),
            ]
        };
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let (code, err) = run_bounded(&args);
        assert!([0, 1].contains(&code), "{ext}: exit {code}: {err}");
    }
}

#[test]
fn mutated_journals_never_keep_a_wrong_frame() {
    // The inputs change after a conversion (a tracklet's class, a scan's points); whatever the
    // journal then says after a mutation (a hash, a size, a frame id, the root or the
    // parameters garbled, lines lost or doubled), the re-run ends with exactly a fresh
    // conversion's files of the changed inputs, exit 0.
    let t = tmp();
    let root = fixture_copy(t.path());
    let done = t.path().join("done");
    let (code, _, e) = convert_json(&root, &done, &[]);
    assert_eq!(code, 0, "{e}");
    let original = std::fs::read(done.join(".kitti2pgm-frames")).unwrap();
    let xml = root.join("2011_09_26/2011_09_26_drive_0001_sync/tracklet_labels.xml");
    let text = std::fs::read_to_string(&xml).unwrap();
    std::fs::write(
        &xml,
        text.replace("<objectType>Car<", "<objectType>Cyclist<"),
    )
    .unwrap();
    let bin =
        root.join("2011_09_26/2011_09_26_drive_0052_sync/velodyne_points/data/0000000000.bin");
    let mut scan = std::fs::read(&bin).unwrap();
    for p in scan.chunks_exact_mut(16) {
        p[7] ^= 0x80;
    }
    std::fs::write(&bin, &scan).unwrap();
    let fresh = t.path().join("fresh");
    let (code, _, e) = convert_json(&root, &fresh, &[]);
    assert_eq!(code, 0, "{e}");
    let expected = (
        tree_bytes(&fresh.join("lidar_2d")),
        tree_bytes(&fresh.join("labels")),
    );
    let mut rng = Rng(26);
    for k in 0..16 {
        let out = t.path().join(format!("j{k}"));
        copy_tree(&done, &out);
        std::fs::write(out.join(".kitti2pgm-frames"), mutate(&original, &mut rng)).unwrap();
        let (code, err) = run_bounded(&["--no-progress", "convert", s(&root), "--out", s(&out)]);
        assert_eq!(code, 0, "journal mutation {k}: {err}");
        let got = (
            tree_bytes(&out.join("lidar_2d")),
            tree_bytes(&out.join("labels")),
        );
        assert!(got == expected, "journal mutation {k} kept a wrong frame");
    }
}

#[test]
fn mutated_submission_folders_pass_only_when_valid() {
    use kitti2pgm::label::ClassMap;
    let t = tmp();
    let sk = fixture("semantickitti");
    let truth = std::fs::read(sk.join("sequences/00/labels/000000.label")).unwrap();
    let points = std::fs::metadata(sk.join("sequences/00/velodyne/000000.bin"))
        .unwrap()
        .len()
        / 16;
    let map = ClassMap::named_or_file(Path::new("semantic-kitti")).unwrap();
    let mut rng = Rng(2626);
    for k in 0..16 {
        let pred = t.path().join(format!("s{k}"));
        let dir = pred.join("sequences/00/predictions");
        std::fs::create_dir_all(&dir).unwrap();
        let bytes = mutate(&truth, &mut rng);
        std::fs::write(dir.join("000000.label"), &bytes).unwrap();
        // Every few runs a stray file beside it, as an unfinished tool leaves one.
        if k % 4 == 3 {
            std::fs::write(dir.join(".tmp-partial"), b"x").unwrap();
        }
        let zip = t.path().join(format!("s{k}.zip"));
        let (code, err) = run_bounded(&["submission", s(&pred), "--gt", s(&sk), "--zip", s(&zip)]);
        let valid = k % 4 != 3
            && bytes.len() as u64 == points * 4
            && bytes.chunks_exact(4).all(|w| {
                map.class_of_raw(u32::from_le_bytes([w[0], w[1], w[2], w[3]]) & 0xFFFF)
                    .is_some()
            });
        assert_eq!(
            code == 0,
            valid,
            "submission mutation {k}: exit {code}: {err}"
        );
        assert_eq!(zip.exists(), valid, "submission mutation {k}: the archive");
        if valid {
            let mut z = zip::ZipArchive::new(std::fs::File::open(&zip).unwrap()).unwrap();
            assert_eq!(z.len(), 2, "description and the one prediction");
            let mut packed = Vec::new();
            std::io::Read::read_to_end(
                &mut z.by_name("sequences/00/predictions/000000.label").unwrap(),
                &mut packed,
            )
            .unwrap();
            assert_eq!(packed, bytes);
        }
    }
}

/// Issue 47: mutated bags (uncompressed chunks, rosbag2's default, and zstd ones), unpacked:
/// never a panic or a hang, and every frame written is byte for byte the clean bag's frame of
/// the same number (a damaged chunk fails its frames, it never gives other points), all of them
/// when the exit status is 0.
#[test]
fn mutated_bags_unpack_byte_for_byte_or_fail() {
    let t = tmp();
    let pc2 = kitti2pgm::source::pointcloud2::TYPE_NAME;
    // Messages of different sizes: a frame given another message's points would show.
    let messages: Vec<(&str, Vec<u8>)> = (0..6)
        .map(|i| (pc2, super::bags::cdr_cloud(40 + 7 * i as u32, 16, i)))
        .collect();
    let mut rng = Rng(47);
    for (name, compression) in [("plain", None), ("zstd", Some(mcap::Compression::Zstd))] {
        let bag = t.path().join(format!("{name}.mcap"));
        let options = mcap::WriteOptions::new()
            .compression(compression)
            .chunk_size(Some(1));
        super::bags::write_typed(&bag, &messages, options);
        let clean = t.path().join(format!("{name}-clean"));
        let (code, err) =
            run_bounded(&["unpack", s(&bag), "--topic", "/points", "--out", s(&clean)]);
        assert_eq!(code, 0, "{err}");
        let scan = |root: &Path, i: usize| {
            std::fs::read(root.join(format!("sequences/00/velodyne/{i:06}.pcd"))).ok()
        };
        let original = std::fs::read(&bag).unwrap();
        for k in 0..16 {
            let path = t.path().join(format!("{name}-{k}.mcap"));
            std::fs::write(&path, mutate(&original, &mut rng)).unwrap();
            let root = t.path().join(format!("{name}-{k}"));
            let (code, err) =
                run_bounded(&["unpack", s(&path), "--topic", "/points", "--out", s(&root)]);
            assert!([0, 1, 3].contains(&code), "{name} {k}: exit {code}: {err}");
            for i in 0..messages.len() {
                if let Some(got) = scan(&root, i) {
                    assert!(got == scan(&clean, i).unwrap(), "{name} {k}: frame {i}");
                } else {
                    assert_ne!(code, 0, "{name} {k}: frame {i} missing with exit 0");
                }
            }
        }
    }
}
