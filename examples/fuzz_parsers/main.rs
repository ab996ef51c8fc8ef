//! Mutation fuzzing of every parser, in process, for as long as you like (stable Rust, no
//! cargo-fuzz needed):
//!
//! ```sh
//! cargo run --release --example fuzz_parsers -- [SECONDS] [SEED]
//! ```
//!
//! Each round mutates one real fixture file (calibration text, tracklet XML, velodyne scan,
//! camera PNG, `.npy` map, `.label` file, shard; KITTI object labels and calibration,
//! SemanticKITTI labels and `calib.txt`, point shard; a PCD scan, a PointCloud2 message (whose
//! PCD, as `unpack` writes it, must read as the message does), a ROS 2 bag with zstd chunks and
//! one with uncompressed chunks, the Velodyne, Hesai and Ouster calibration tables) and hands it
//! to its parser. A parser may refuse
//! the input with an error; it must never panic. A panicking input is saved as
//! `fuzz-crash-<kind>-<seed>-<round>` and the run ends with exit status 1.

mod mutate;

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use kitti2pgm::format::shard::Shard;
use kitti2pgm::format::{label_file, pgm};
use kitti2pgm::label::ClassMap;
use kitti2pgm::source::bag::Bag;
use kitti2pgm::source::kitti::calib::CalibFile;
use kitti2pgm::source::kitti::camera::decode_image;
use kitti2pgm::source::kitti::tracklets::Tracklets;
use kitti2pgm::source::pcd;
use kitti2pgm::source::pointcloud2::PointCloud2;
use mutate::{mutate, Rng};

type Parser = fn(&[u8], &Path);

fn via_file(bytes: &[u8], dir: &Path, name: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).expect("write the mutated file");
    p
}

/// Every message of every topic of the bag file `b` read (at most 64 a topic).
fn read_bag(b: &[u8], p: &Path) {
    let f = via_file(b, p, "b.mcap");
    let Ok(bag) = Bag::open(&f) else { return };
    for t in bag.topics().unwrap_or_default() {
        for m in bag.messages(&t).take(64) {
            if m.is_err() {
                break;
            }
        }
    }
}

/// The fixture bag's first point cloud message, and the fixture bag written again with
/// uncompressed chunks of about one message each (rosbag2's default chunks are uncompressed).
fn bag_inputs(fixtures: &Path, work: &Path) -> (Vec<u8>, Vec<u8>) {
    let bag = Bag::open(&fixtures.join("own_lidar_bag")).expect("the fixture bag");
    let topic = bag
        .topic(
            Some("/velodyne_points"),
            kitti2pgm::source::pointcloud2::TYPE_NAME,
        )
        .expect("its point cloud topic");
    let messages: Vec<Vec<u8>> = (bag.messages(&topic))
        .filter_map(|m| m.ok()?.message().map(|m| m.data))
        .collect();
    let path = work.join("plain.mcap");
    let file = std::io::BufWriter::new(std::fs::File::create(&path).expect("plain.mcap"));
    let options = mcap::WriteOptions::new()
        .compression(None)
        .chunk_size(Some(1));
    let mut w = options.create(file).expect("a writer");
    let schema = w
        .add_schema(&topic.type_name, "ros2msg", b"")
        .expect("a schema");
    let ch = w
        .add_channel(schema, &topic.name, "cdr", &Default::default())
        .expect("a channel");
    for (i, m) in messages.iter().enumerate() {
        let header = mcap::records::MessageHeader {
            channel_id: ch,
            sequence: i as u32,
            log_time: i as u64,
            publish_time: i as u64,
        };
        w.write_to_known_channel(&header, m).expect("a message");
    }
    w.finish().expect("the bag's end");
    drop(w);
    let plain = std::fs::read(&path).expect("plain.mcap");
    (messages[0].clone(), plain)
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
    let lidars = fixtures.join("lidars");
    let (first_message, plain_bag) = bag_inputs(&fixtures, work.path());
    let inputs: Vec<(&str, Vec<u8>, Parser)> = vec![
        ("calib", read(root.join("calib_cam_to_cam.txt")), |b, p| {
            let _ = CalibFile::parse(&String::from_utf8_lossy(b), p)
                .and_then(|f| kitti2pgm::source::kitti::calib::CamToCam::from_file(&f));
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
                if let Ok(scan) = kitti2pgm::source::kitti::velodyne::decode(b, p) {
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
                let _ = kitti2pgm::source::kitti::object::parse(&String::from_utf8_lossy(b), p);
            },
        ),
        (
            "object-calib",
            read(fixtures.join("kitti_object/training/calib/000001.txt")),
            |b, p| {
                if let Ok(c) =
                    kitti2pgm::source::kitti::calib::FrameCalib::read(&via_file(b, p, "c.txt"))
                {
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
                let _ =
                    kitti2pgm::source::kitti::calib::FrameCalib::read(&via_file(b, p, "calib.txt"));
            },
        ),
        ("point-shard", read(point_shard), |b, p| {
            if let Ok(s) = Shard::open(&via_file(b, p, "p.mcap")) {
                let _ = s.verify();
                let _ = s.points();
            }
        }),
        (
            "pcd",
            read(lidars.join("velodyne/vlp16_1673400472138016708.pcd")),
            |b, p| {
                let _ = pcd::decode(b, &p.join("s.pcd"));
            },
        ),
        ("pointcloud2", first_message.clone(), |b, p| {
            // What unpack writes decodes to what read_bag reads, whatever the message.
            if let Ok(m) = PointCloud2::decode(b, p) {
                let (layout, records) = m.packed();
                let file = pcd::encode(&layout, m.width, m.height, &records);
                if let (Ok(a), Ok(b)) = (m.cloud(p), pcd::decode(&file, p)) {
                    assert_eq!(a, b, "unpack's PCD reads as the message");
                }
            }
        }),
        (
            "bag",
            read(fixtures.join("own_lidar_bag/own_lidar_bag.mcap")),
            read_bag,
        ),
        ("bag-plain", plain_bag, read_bag),
        (
            "velodyne-yaml",
            read(lidars.join("velodyne/VLP16.yaml")),
            |b, p| {
                let _ = kitti2pgm::sensor::read_calibration(&via_file(b, p, "c.yaml"));
            },
        ),
        (
            "hesai-csv",
            read(lidars.join("hesai/Pandar40P.csv")),
            |b, p| {
                let _ = kitti2pgm::sensor::read_calibration(&via_file(b, p, "c.csv"));
            },
        ),
        (
            "ouster-json",
            read(lidars.join("ouster/OS-1-32-G_v2.1.1_1024x10.json")),
            |b, p| {
                let _ = kitti2pgm::sensor::read_calibration(&via_file(b, p, "c.json"));
            },
        ),
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
