//! Per-stage and whole-frame benchmarks on real scans (criterion).
//!
//! Uses `../shared/kitti/raw` when present (30 scans), else `fixtures/raw` (3 scans). The
//! "floor" is reading the `.bin` plus decoding the PNG: what any converter must pay.

use std::hint::black_box;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use kitti2pgm::convert::labels::FrameLabels;
use kitti2pgm::convert::{convert_frame, process, ConvertOptions};
use kitti2pgm::format::npy::encode_f32;
use kitti2pgm::format::{atomic_write, Durability};
use kitti2pgm::label::{ClassMap, Labeller};
use kitti2pgm::plan::DrivePlan;
use kitti2pgm::project::camera::RgbOptions;
use kitti2pgm::project::camera::{CameraProjector, Sampling};
use kitti2pgm::project::{project, project_beams, project_cloud, Augment, Cloud, PgmSpec};
use kitti2pgm::source::bag::{Bag, MessageRef};
use kitti2pgm::source::kitti::calib::Calibration;
use kitti2pgm::source::kitti::camera::read_image;
use kitti2pgm::source::kitti::Drive;
use kitti2pgm::source::pointcloud2::{PointCloud2, TYPE_NAME};
use kitti2pgm::source::Scan;

/// The same allocator as the binary, so that stage costs match what `convert` pays (set up as
/// the binary sets it up: [`kitti2pgm::alloc::tune_mimalloc`], called by each group).
#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

/// The repository's root (this package is its `benches/` folder).
fn repo() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().unwrap()
}

fn raw_root() -> PathBuf {
    let shared = repo().join("../shared/kitti/raw");
    if shared.is_dir() {
        shared
    } else {
        repo().join("fixtures/raw")
    }
}

fn drive_0052() -> (DrivePlan, u32) {
    let dir = raw_root().join("2011_09_26/2011_09_26_drive_0052_sync");
    let drive = Drive::from_dir(&dir).unwrap();
    let calib = Arc::new(Calibration::read_dir(&drive.date_dir()).unwrap());
    (DrivePlan::load(drive, Some(calib)).unwrap(), 0)
}

fn stages(c: &mut Criterion) {
    kitti2pgm::alloc::tune_mimalloc();
    let (dp, f) = drive_0052();
    let scan_path = dp.drive.scan_path(f);
    let img_path = dp.drive.image_path(2, f);
    let scan = Scan::read(&scan_path).unwrap();
    let img = read_image(&img_path).unwrap();
    let classes = ClassMap::kitti_paper();
    let boxes = dp.label_boxes(f, &classes);
    let spec = PgmSpec::default();
    let cam = CameraProjector {
        velo_to_image: dp.camera(0, 2).unwrap().0,
        sampling: Sampling::Nearest,
    };
    let id = dp.drive.frame_id(f);
    // Labelling is part of processing a frame.
    let labelled = || FrameLabels::from_boxes(boxes.clone(), &scan, &classes);

    let map = kitti2pgm::provenance::MapParams {
        spec,
        class_map: classes.clone(),
        ..Default::default()
    };
    let mut g = c.benchmark_group("stage");
    g.throughput(Throughput::Elements(1));
    g.bench_function("read_bin", |b| {
        b.iter(|| Scan::read(black_box(&scan_path)).unwrap())
    });
    g.bench_function("decode_png", |b| {
        b.iter(|| read_image(black_box(&img_path)).unwrap())
    });
    g.bench_function("floor_bin_plus_png", |b| {
        b.iter(|| {
            (
                Scan::read(&scan_path).unwrap(),
                read_image(&img_path).unwrap(),
            )
        })
    });
    g.bench_function("label", |b| {
        b.iter(|| Labeller::new(black_box(&boxes), classes.background).label(&scan.points))
    });
    g.bench_function("project", |b| {
        b.iter(|| project(black_box(&scan.points), &spec))
    });
    g.bench_function("process_lidar", |b| {
        b.iter(|| process(&id, &scan, &labelled(), &map, None, None))
    });
    g.bench_function("process_rgb", |b| {
        b.iter(|| process(&id, &scan, &labelled(), &map, None, Some((&cam, &img))))
    });
    let out = process(&id, &scan, &labelled(), &map, None, Some((&cam, &img)));
    g.bench_function("encode_npy_9ch", |b| {
        b.iter(|| encode_f32(&[64, 512, 9], black_box(&out.pgm.data)))
    });
    let bytes = encode_f32(&[64, 512, 9], &out.pgm.data);
    let dir = tempfile::tempdir().unwrap();
    let target = dir.path().join("x.npy");
    g.bench_function("atomic_write_npy_9ch", |b| {
        b.iter(|| atomic_write(&target, &bytes, Durability::Renamed).unwrap())
    });
    g.bench_function("plain_write_npy_9ch", |b| {
        b.iter(|| std::fs::write(&target, &bytes).unwrap())
    });
    g.finish();

    // The Python module's projection (project_cloud), plain and augmented.
    let mut g = c.benchmark_group("cloud");
    g.throughput(Throughput::Elements(1));
    let labels = labelled().points;
    let cloud = Cloud {
        labels: Some(&labels.class),
        instance: Some(&labels.instance),
        ..Cloud::of_points(&scan.points, &scan.intensity)
    };
    let full = PgmSpec {
        cols: 2048,
        fov: kitti2pgm::geom::Degrees(360.0),
        ..PgmSpec::default()
    };
    let turn = Augment {
        rotate: 0.5,
        scale: 1.02,
        flip: true,
        ..Augment::default()
    };
    let all = Augment {
        jitter: 0.01,
        drop: 0.1,
        seed: 3,
        ..turn
    };
    for (name, sp, aug) in [
        ("512_plain", spec, None),
        ("2048_360_plain", full, None),
        ("512_rotate_scale_flip", spec, Some(turn)),
        ("512_all_augmentations", spec, Some(all)),
        ("2048_360_all_augmentations", full, Some(all)),
    ] {
        g.bench_function(name, |b| {
            b.iter(|| project_cloud(black_box(&cloud), &sp, aug.as_ref()).unwrap())
        });
    }
    g.finish();

    let mut g = c.benchmark_group("frame");
    g.throughput(Throughput::Elements(1));
    let mut opts = ConvertOptions::new(dir.path());
    std::fs::create_dir_all(dir.path().join("lidar_2d")).unwrap();
    std::fs::create_dir_all(dir.path().join("labels").join(dp.drive.name())).unwrap();
    g.bench_function("convert_lidar", |b| {
        b.iter(|| convert_frame(&dp, f, &opts).unwrap())
    });
    opts.params.map.rgb = Some(RgbOptions {
        camera: 2,
        sampling: Sampling::Nearest,
    });
    g.bench_function("convert_rgb", |b| {
        b.iter(|| convert_frame(&dp, f, &opts).unwrap())
    });
    g.finish();
}

/// RangeNet++'s kNN on a real SemanticKITTI scan (64 x 2048 over 360 degrees, predictions at
/// random), one thread: the scalar kernel and the lane kernels this machine runs (the same
/// classes).
fn knn(c: &mut Criterion) {
    kitti2pgm::alloc::tune_mimalloc();
    use kitti2pgm::project::unproject::{knn_with, KnnKernel, KnnParams, PointsInMap};
    use kitti2pgm::project::{norm, project_with_point_cells, MapPreset};
    let bin = repo().join("fixtures/semantickitti/sequences/00/velodyne/000000.bin");
    let scan = Scan::read(&bin).unwrap();
    let spec = MapPreset::Full.spec();
    let proj = project_with_point_cells(&scan.points, &spec);
    let point_range: Vec<f32> = scan.points.iter().map(norm).collect();
    let classes = ClassMap::semantic_kitti();
    let mut state = 7u64;
    let pred: Vec<u8> = (0..spec.rows * spec.cols)
        .map(|_| (kitti2pgm::rng::splitmix64(&mut state) % 20) as u8)
        .collect();
    let m = PointsInMap::of(&proj, &point_range);
    let p = KnnParams::default();
    let mut g = c.benchmark_group("knn");
    g.throughput(Throughput::Elements(1));
    for kernel in KnnKernel::available() {
        let name = format!("{kernel:?}").to_lowercase();
        g.bench_function(&name, |b| {
            b.iter(|| knn_with(black_box(&m), &pred, &p, &classes, kernel))
        });
    }
    g.finish();
}

/// Reading other sensors' files against KITTI's `.bin`, in points per second (issue 27's goal:
/// PCD binary at least 0.8x the `.bin` path).
fn read(c: &mut Criterion) {
    kitti2pgm::alloc::tune_mimalloc();
    let here = repo();
    let bin = drive_0052().0.drive.scan_path(0);
    let pcd = here.join("fixtures/lidars/hesai/Pandar40P_1673400149711850138.pcd");
    let nus = std::fs::read_dir(here.join("fixtures/lidars/nuscenes"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .next()
        .unwrap();
    let vlp16 = here.join("fixtures/lidars/velodyne/vlp16_1673400472138016708.pcd");
    let mut g = c.benchmark_group("read");
    for (name, path) in [
        ("kitti_bin", &bin),
        ("pcd_binary", &pcd),
        ("pcd_binary_vlp16", &vlp16),
        ("nuscenes_pcd_bin", &nus),
    ] {
        let n = kitti2pgm::source::points_in_file(path).unwrap();
        g.throughput(Throughput::Elements(n));
        g.bench_function(name, |b| {
            b.iter(|| kitti2pgm::source::read_file(black_box(path), None).unwrap())
        });
    }
    // Another sensor's beam rows from its table (no ring field: the Pandar40P scan, 40 beams).
    let scan = Scan::read(&pcd).unwrap();
    let model = kitti2pgm::sensor::presets::Sensor::Pandar40p.model_table();
    g.throughput(Throughput::Elements(scan.len() as u64));
    g.bench_function("assign_pandar40p", |b| {
        b.iter(|| model.assign(black_box(&scan.points)))
    });
    // Its projection, one row per beam, 40 x 1024 over 360 degrees (what `convert --sensor
    // pandar40p --cols 1024` does with the rows).
    let rows = model.assign(&scan.points).rows;
    let spec = PgmSpec {
        rows: 40,
        cols: 1024,
        fov: kitti2pgm::geom::Degrees(360.0),
        ..PgmSpec::default()
    };
    g.bench_function("project_pandar40p", |b| {
        b.iter(|| project_beams(black_box(&scan.points), &spec, &rows, 40, None))
    });
    // The fixture bag's /velodyne_points (the VLP-16 scan twice, one message big-endian, as
    // rosbags serialised them) alone in an uncompressed .mcap (rosbag2's default), read and
    // decoded as `kitti2pgm.read_bag` does; then its little-endian message twice (what drivers
    // on x86 and ARM write).
    let dir = tempfile::tempdir().unwrap();
    let fixture = here.join("fixtures/own_lidar_bag");
    let n = 2 * kitti2pgm::source::points_in_file(&vlp16).unwrap();
    g.throughput(Throughput::Elements(n));
    for (name, little_endian_only) in [("ros2_bag_vlp16", false), ("ros2_bag_vlp16_le", true)] {
        let bag = lidar_only_bag(&fixture, &dir.path().join(name), little_endian_only);
        let topic = bag.topic(Some("/velodyne_points"), TYPE_NAME).unwrap();
        g.bench_function(name, |b| {
            b.iter(|| {
                let mut points = 0;
                let mut messages = bag.messages(black_box(&topic));
                let what = std::path::Path::new("bag");
                let decode = |m: MessageRef<'_>| PointCloud2::decode(m.data, what)?.cloud(what);
                while let Some(cloud) = messages.next_with(decode) {
                    points += cloud.unwrap().message().unwrap().unwrap().len();
                }
                points
            })
        });
    }
    g.finish();
}

/// The `/velodyne_points` messages of `bag` copied into a bag of that topic alone at `out`;
/// with `little_endian_only`, its first little-endian message as many times as it has messages.
fn lidar_only_bag(bag: &Path, out: &Path, little_endian_only: bool) -> Bag {
    let bag = Bag::open(bag).unwrap();
    let topic = bag.topic(Some("/velodyne_points"), TYPE_NAME).unwrap();
    let mut messages: Vec<Vec<u8>> = (bag.messages(&topic))
        .map(|m| m.unwrap().message().unwrap().data)
        .collect();
    if little_endian_only {
        // CDR's encapsulation header: 0x00 0x01 is little-endian.
        let le = messages.iter().find(|m| m[..2] == [0, 1]).unwrap().clone();
        messages.fill(le);
    }
    let file = std::io::BufWriter::new(std::fs::File::create(out).unwrap());
    let mut w = mcap::WriteOptions::new()
        .compression(None)
        .create(file)
        .unwrap();
    let schema = w
        .add_schema("sensor_msgs/msg/PointCloud2", "ros2msg", b"")
        .unwrap();
    let ch = w
        .add_channel(schema, "/velodyne_points", "cdr", &Default::default())
        .unwrap();
    for (i, m) in messages.iter().enumerate() {
        let h = mcap::records::MessageHeader {
            channel_id: ch,
            sequence: i as u32,
            log_time: i as u64,
            publish_time: i as u64,
        };
        w.write_to_known_channel(&h, m).unwrap();
    }
    w.finish().unwrap();
    Bag::open(out).unwrap()
}

/// Labelling a real scan (drive 0052 frame 0) among `n` made-up cars scattered over 60 x 60 m
/// around the sensor: `label` (box by box in runs of points, up to `BY_BOX_MAX` boxes) against
/// the grid's point-by-point `label_point`.
fn labelling(c: &mut Criterion) {
    use kitti2pgm::geom::{na, Iso3, Vector3};
    use kitti2pgm::label::LabelBox;
    kitti2pgm::alloc::tune_mimalloc();
    let (dp, f) = drive_0052();
    let scan = Scan::read(&dp.drive.scan_path(f)).unwrap();
    let mut seed = 0x2545_f491_4f6c_dd1du64;
    let mut r = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f32 / (1u64 << 53) as f32
    };
    let mut g = c.benchmark_group("label");
    for n in [4usize, 64, 256, 512] {
        // Cars (4.3 x 1.8 x 1.5 m) standing on the road, 1.7 m below the sensor.
        let boxes: Vec<LabelBox> = (0..n)
            .map(|i| {
                let centre = na::Translation3::new(60.0 * r() - 30.0, 60.0 * r() - 30.0, -0.95);
                let yaw = na::UnitQuaternion::from_euler_angles(0.0, 0.0, 6.0 * r());
                let half = Vector3::new(2.15, 0.9, 0.75);
                let geometry = kitti2pgm::source::boxes::Box3 {
                    pose: Iso3::from_parts(centre, yaw),
                    half_extents: half,
                };
                LabelBox::of(&geometry, 1, i as u16 + 1)
            })
            .collect();
        let lab = Labeller::new(&boxes, 0);
        g.bench_function(format!("scan_{n}_boxes"), |b| {
            b.iter(|| lab.label(black_box(&scan.points)))
        });
        g.bench_function(format!("grid_{n}_boxes"), |b| {
            b.iter(|| {
                let pts = black_box(&scan.points);
                pts.iter().map(|p| lab.label_point(p)).collect::<Vec<_>>()
            })
        });
    }
    g.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(30).measurement_time(std::time::Duration::from_secs(3));
    targets = stages, knn, read, labelling
}
criterion_main!(benches);
