//! Mutation fuzzing of every parser, in process, for as long as you like (stable Rust, no
//! cargo-fuzz needed):
//!
//! ```sh
//! cargo run --release --example fuzz_parsers -- [SECONDS] [SEED]
//! ```
//!
//! Each round mutates one real fixture file (calibration text, tracklet XML, velodyne scan,
//! camera PNG, `.npy` map, `.label` file, shard; KITTI object labels and calibration,
//! SemanticKITTI labels and `calib.txt`, point shard) and hands it to its parser. A parser may refuse
//! the input with an error; it must never panic. A panicking input is saved as
//! `fuzz-crash-<kind>-<seed>-<round>` and the run ends with exit status 1.

mod mutate;

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use kitti2pgm::format::shard::Shard;
use kitti2pgm::format::{label_file, pgm};
use kitti2pgm::kitti::calib::CalibFile;
use kitti2pgm::kitti::camera::decode_image;
use kitti2pgm::kitti::tracklets::Tracklets;
use kitti2pgm::kitti::velodyne::Scan;
use kitti2pgm::label::ClassMap;
use mutate::{mutate, Rng};

type Parser = fn(&[u8], &Path);

fn via_file(bytes: &[u8], dir: &Path, name: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).expect("write the mutated file");
    p
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let seconds: u64 = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(60);
    let seed: u64 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(1);
    let fixtures = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures");
    let root = fixtures.join("raw/2011_09_26");
    let drive = root.join("2011_09_26_drive_0052_sync");
    let work = tempfile::tempdir().expect("temp dir");
    // Real outputs to mutate as well: a map, a .label file and a shard of the fixtures.
    let out = work.path().join("out");
    let status = std::process::Command::new(env!("CARGO"))
        .args([
            "run",
            "--quiet",
            "--release",
            "--",
            "--no-progress",
            "convert",
        ])
        .arg(&drive)
        .arg("--out")
        .arg(&out)
        .args(["--format", "npy,mcap,points", "--rgb"])
        .status()
        .expect("run kitti2pgm convert");
    assert!(status.success(), "convert failed");
    let read = |p: PathBuf| std::fs::read(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    let shard = std::fs::read_dir(out.join("shards"))
        .expect("shards")
        .map(|e| e.expect("entry").path())
        .find(|p| p.extension().is_some_and(|e| e == "mcap"))
        .expect("a shard");
    let point_shard = out.join("points/train-00000.mcap");
    let inputs: Vec<(&str, Vec<u8>, Parser)> = vec![
        ("calib", read(root.join("calib_cam_to_cam.txt")), |b, p| {
            let _ = CalibFile::parse(&String::from_utf8_lossy(b), p)
                .and_then(|f| kitti2pgm::kitti::calib::CamToCam::from_file(&f));
        }),
        (
            "tracklets",
            read(drive.join("tracklet_labels.xml")),
            |b, p| {
                let _ = Tracklets::parse(&String::from_utf8_lossy(b), p);
            },
        ),
        (
            "bin",
            read(drive.join("velodyne_points/data/0000000000.bin")),
            |b, p| {
                if let Ok(scan) = Scan::from_bytes(b, p) {
                    let _ = kitti2pgm::project::project(&scan.points, &Default::default());
                }
            },
        ),
        (
            "png",
            read(drive.join("image_02/data/0000000000.png")),
            |b, p| {
                let _ = decode_image(b, p);
            },
        ),
        (
            "npy",
            read(out.join("lidar_2d/2011_09_26_0052_0000000000.npy")),
            |b, p| {
                let f = via_file(b, p, "m.npy");
                if let Ok(m) = pgm::read(&f) {
                    let _ = m.into_frame(&ClassMap::kitti_paper(), &f);
                }
            },
        ),
        (
            "label",
            read(out.join("labels/2011_09_26_drive_0052_sync/0000000000.label")),
            |b, p| {
                let _ =
                    label_file::read_classes(&via_file(b, p, "m.label"), &ClassMap::kitti_paper());
            },
        ),
        ("shard", read(shard), |b, p| {
            if let Ok(s) = Shard::open(&via_file(b, p, "m.mcap")) {
                let _ = s.verify();
                let _ = s.metadata();
                let _ = s.frame_iter().count();
            }
        }),
        (
            "object-labels",
            read(fixtures.join("kitti_object/training/label_2/000001.txt")),
            |b, p| {
                let _ = kitti2pgm::kitti::object::parse(&String::from_utf8_lossy(b), p);
            },
        ),
        (
            "object-calib",
            read(fixtures.join("kitti_object/training/calib/000001.txt")),
            |b, p| {
                if let Ok(c) = kitti2pgm::kitti::calib::FrameCalib::read(&via_file(b, p, "c.txt")) {
                    if let Some(m) = c.velo_to_rect().try_inverse() {
                        let _ = kitti2pgm::geom::nearest_rotation(
                            &m.fixed_view::<3, 3>(0, 0).into_owned(),
                        );
                    }
                }
            },
        ),
        (
            "semantickitti-labels",
            read(fixtures.join("semantickitti/sequences/00/labels/000000.label")),
            |b, p| {
                if let Ok(raw) = label_file::read_raw(&via_file(b, p, "s.label")) {
                    let _ = ClassMap::semantic_kitti().classes_of_raw(&raw, p);
                }
            },
        ),
        (
            "semantickitti-calib",
            read(fixtures.join("semantickitti/sequences/00/calib.txt")),
            |b, p| {
                let _ = kitti2pgm::kitti::calib::FrameCalib::read(&via_file(b, p, "calib.txt"));
            },
        ),
        ("point-shard", read(point_shard), |b, p| {
            if let Ok(s) = Shard::open(&via_file(b, p, "p.mcap")) {
                let _ = s.verify();
                let _ = s.points();
            }
        }),
    ];
    std::panic::set_hook(Box::new(|_| {}));
    let mut rng = Rng(seed);
    let end = Instant::now() + Duration::from_secs(seconds);
    let mut rounds = 0u64;
    while Instant::now() < end {
        for (kind, original, parse) in &inputs {
            let bad = mutate(original, &mut rng);
            let dir = work.path();
            if catch_unwind(AssertUnwindSafe(|| parse(&bad, dir))).is_err() {
                let name = format!("fuzz-crash-{kind}-{seed}-{rounds}");
                std::fs::write(&name, &bad).expect("save the crashing input");
                eprintln!("{kind}: the parser panicked; input saved as {name}");
                std::process::exit(1);
            }
        }
        rounds += 1;
    }
    println!(
        "{rounds} rounds of {} parsers, seed {seed}: no panic",
        inputs.len()
    );
}
