//! Everything after `convert` works on another sensor's data as on KITTI's: a labelled VLP-16
//! root in point_labeler's layout (the real scan, labels by region) through `split`, `stats`,
//! `check`, `score` (cells and points), `unproject` (cell and kNN) and `preview`. Carrying map
//! predictions back to points must project each scan as its conversion did (the sensor's beam
//! rows and pose): with KITTI's scan-order rows instead, only 82% of the points got their own
//! label back.

use std::path::{Path, PathBuf};

use super::util::{convert_json, run_text, s, tmp};

/// Raw SemanticKITTI ids by region (azimuth, elevation), so that neighbouring points mostly
/// share a class: building, road, car, person.
fn label_of(x: f32, y: f32, z: f32) -> u32 {
    let az = (y as f64).atan2(x as f64).to_degrees();
    let el = (z as f64).atan2((x as f64).hypot(y as f64)).to_degrees();
    match () {
        _ if el < -6.0 && az < -100.0 => 30,
        _ if el > 0.0 && az < -30.0 => 10,
        _ if az > 60.0 => 40,
        _ => 50,
    }
}

/// A root of sequences `seqs`, each holding the VLP-16 scan (moved up by `lift` metres, then
/// written as x, y, z, intensity without its ring field; as the driver wrote it when 0) and its
/// labels by region of the unmoved points.
fn labelled_root(dir: &Path, seqs: &[&str], lift: f32) -> PathBuf {
    let vlp = super::util::fixture("own_lidar/sequences/00/velodyne/000000.pcd");
    let cloud = kitti2pgm::source::read_file(&vlp, None).unwrap();
    let root = dir.join("root");
    for seq in seqs {
        let d = root.join("sequences").join(seq);
        std::fs::create_dir_all(d.join("velodyne")).unwrap();
        std::fs::create_dir_all(d.join("labels")).unwrap();
        let scan = d.join("velodyne/000000.pcd");
        if lift == 0.0 {
            std::fs::copy(&vlp, &scan).unwrap();
        } else {
            let n = cloud.points.len();
            let mut body = format!(
                "VERSION 0.7\nFIELDS x y z intensity\nSIZE 4 4 4 4\nTYPE F F F F\nCOUNT 1 1 1 1\n\
                 WIDTH {n}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {n}\nDATA binary\n"
            )
            .into_bytes();
            for (p, i) in cloud.points.iter().zip(&cloud.intensity) {
                for v in [p.x, p.y, p.z + lift, *i] {
                    body.extend_from_slice(&v.to_le_bytes());
                }
            }
            std::fs::write(&scan, body).unwrap();
        }
        let labels: Vec<u8> = cloud
            .points
            .iter()
            .flat_map(|p| label_of(p.x, p.y, p.z).to_le_bytes())
            .collect();
        std::fs::write(d.join("labels/000000.label"), labels).unwrap();
    }
    root
}

/// Runs the binary (with --no-progress), which must succeed; its stdout.
fn ok(args: &[&str]) -> String {
    let mut a = args.to_vec();
    a.push("--no-progress");
    let (code, out, err) = run_text(&a);
    assert_eq!(code, 0, "{a:?}: {err}");
    out
}

/// Each converted map's label channel as an H x W uint8 prediction under `dir`.
fn predictions_from_maps(conv: &Path, dir: &Path) {
    std::fs::create_dir_all(dir).unwrap();
    for e in std::fs::read_dir(conv.join("lidar_2d")).unwrap() {
        let path = e.unwrap().path();
        let (shape, data) = kitti2pgm::format::npy::read_f32(&path).unwrap();
        let labels: Vec<u8> = data
            .chunks_exact(shape[2] as usize)
            .map(|v| v[5] as u8)
            .collect();
        let header = format!(
            "{{'descr': '|u1', 'fortran_order': False, 'shape': ({}, {}), }}",
            shape[0], shape[1]
        );
        let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
        let pad = (64 - (10 + header.len() + 1) % 64) % 64;
        let header = format!("{header}{}\n", " ".repeat(pad));
        bytes.extend_from_slice(&(header.len() as u16).to_le_bytes());
        bytes.extend_from_slice(header.as_bytes());
        bytes.extend_from_slice(&labels);
        std::fs::write(dir.join(path.file_name().unwrap()), bytes).unwrap();
    }
}

/// `score --json ARGS`: (accuracy, elements scored).
fn score(args: &[&str]) -> (f64, u64) {
    let mut a = vec!["score", "--json"];
    a.extend_from_slice(args);
    let j: serde_json::Value = serde_json::from_str(&ok(&a)).unwrap();
    (
        j["accuracy"].as_f64().unwrap(),
        j["elements"].as_u64().unwrap(),
    )
}

/// `unproject` of the predictions `pred` of the conversion `conv` of `root` into `up` by
/// `method`, then `score` of `up` against `root`'s labels: (accuracy, points scored).
fn carried_back(conv: &Path, pred: &Path, root: &Path, up: &Path, method: &str) -> (f64, u64) {
    ok(&[
        "unproject",
        "--gt",
        s(conv),
        "--pred",
        s(pred),
        "--raw",
        s(root),
        "--out",
        s(up),
        "--method",
        method,
    ]);
    score(&["--gt", s(root), "--pred", s(up)])
}

#[test]
fn split_stats_check_score_unproject_and_preview_work_on_another_sensor_s_root() {
    let t = tmp();
    let root = labelled_root(t.path(), &["00", "01"], 0.0);
    let conv = t.path().join("conv");
    let (code, j, err) = convert_json(
        &root,
        &conv,
        &["--sensor", "vlp16", "--all-frames", "--cols", "1024"],
    );
    assert_eq!(code, 0, "{err}");
    assert_eq!(
        (j["frames_converted"].as_u64(), j["off_model"].as_u64()),
        (Some(2), Some(0))
    );
    let split = t.path().join("split");
    ok(&[
        "split",
        s(&root),
        "--out",
        s(&split),
        "--all-frames",
        "--val-sequences",
        "01",
    ]);
    let val = std::fs::read_to_string(split.join("ImageSet/val.txt")).unwrap();
    assert_eq!(val.trim(), "01_000000");
    let stats: serde_json::Value =
        serde_json::from_str(&ok(&["stats", s(&conv), "--json"])).unwrap();
    assert_eq!(
        (stats["rows"].as_u64(), stats["cols"].as_u64()),
        (Some(16), Some(1024))
    );
    let check: serde_json::Value =
        serde_json::from_str(&ok(&["check", s(&root), "--sensor", "vlp16", "--json"])).unwrap();
    let errors = check["findings"].as_array().unwrap().iter();
    assert_eq!(
        errors.filter(|f| f["severity"] == "error").count(),
        0,
        "{check}"
    );
    // The maps' own labels as predictions: every cell right.
    let pred = t.path().join("pred");
    predictions_from_maps(&conv, &pred);
    assert_eq!(score(&["--gt", s(&conv), "--pred", s(&pred)]).0, 1.0);
    // Per point: a point takes its cell's label; only the points that lost their cell to a
    // nearer one of another class can be wrong.
    let (acc, n) = score(&[
        "--gt",
        s(&conv),
        "--pred",
        s(&pred),
        "--points",
        "--raw",
        s(&root),
    ]);
    assert_eq!(n, 2 * 14_831);
    assert!(acc > 0.999, "{acc}");
    for (method, least) in [("cell", 0.999), ("knn", 0.97)] {
        let up = t.path().join(method);
        let (acc, n) = carried_back(&conv, &pred, &root, &up, method);
        assert_eq!(n, 2 * 14_831);
        assert!(acc > least, "{method}: {acc}");
    }
    let png = t.path().join("p.png");
    ok(&[
        "preview",
        s(&conv.join("lidar_2d/00_000000.npy")),
        "--out",
        s(&png),
    ]);
    let img = kitti2pgm::raster::read(&png).unwrap();
    assert!(img.width() >= 1024);
}

#[test]
fn unproject_moves_the_points_by_the_sensor_pose_as_convert_did() {
    let t = tmp();
    let root = labelled_root(t.path(), &["00"], 1.8);
    let conv = t.path().join("conv");
    let args = [
        "--sensor",
        "vlp16",
        "--sensor-pose",
        "0,0,1.8",
        "--all-frames",
        "--cols",
        "1024",
    ];
    let (code, j, err) = convert_json(&root, &conv, &args);
    assert_eq!(code, 0, "{err}");
    assert_eq!(
        (j["beam_table_frames"].as_u64(), j["off_model"].as_u64()),
        (Some(1), Some(0))
    );
    let pred = t.path().join("pred");
    predictions_from_maps(&conv, &pred);
    let up = t.path().join("up");
    let (acc, n) = carried_back(&conv, &pred, &root, &up, "cell");
    assert_eq!(n, 14_831);
    assert!(acc > 0.999, "{acc}");
}

/// The declared layout of [`flat_root`]'s records.
const FLAT_FIELDS: &str = "x,y,z:f32,intensity:u8,_:u8,ring:u16";

/// A root holding the VLP-16 scan as 16-byte records of [`FLAT_FIELDS`] (x, y, z f32, intensity
/// u8, a pad byte, ring u16): the size of KITTI's records, and not KITTI's; `wide`: 4 bytes of
/// padding more a record ([`FLAT_FIELDS`] then `,_:u32`), a size KITTI's records do not divide.
fn flat_root(dir: &Path, wide: bool) -> PathBuf {
    let vlp = super::util::fixture("own_lidar/sequences/00/velodyne/000000.pcd");
    let cloud = kitti2pgm::source::read_file(&vlp, None).unwrap();
    let rings = cloud.ring.clone().unwrap();
    let mut bytes = Vec::new();
    for ((p, i), r) in cloud.points.iter().zip(&cloud.intensity).zip(&rings) {
        for v in [p.x, p.y, p.z] {
            bytes.extend_from_slice(&v.to_le_bytes());
        }
        bytes.extend_from_slice(&[*i as u8, 0]);
        bytes.extend_from_slice(&r.to_le_bytes());
        if wide {
            bytes.extend_from_slice(&[0; 4]);
        }
    }
    let root = dir.join("flat");
    std::fs::create_dir_all(root.join("sequences/00/velodyne")).unwrap();
    std::fs::write(root.join("sequences/00/velodyne/000000.bin"), &bytes).unwrap();
    root
}

/// The VLP-16 scan's PCD alone in a root.
fn pcd_root(dir: &Path) -> PathBuf {
    let vlp = super::util::fixture("own_lidar/sequences/00/velodyne/000000.pcd");
    let root = dir.join("pcd");
    std::fs::create_dir_all(root.join("sequences/00/velodyne")).unwrap();
    std::fs::copy(&vlp, root.join("sequences/00/velodyne/000000.pcd")).unwrap();
    root
}

/// Issue 49: `preview --raw` read a declared-layout `.bin` as KITTI's records (the layout the
/// conversion recorded ignored): it now reads every scan as its conversion did, so the same
/// predictions drawn over the flat root and over the PCD root give the same picture.
#[test]
fn preview_raw_reads_a_declared_layout_bin_as_its_conversion_did() {
    let t = tmp();
    let base = ["--sensor", "vlp16", "--all-frames", "--cols", "1024"];
    let mut pictures = Vec::new();
    let wide = format!("{FLAT_FIELDS},_:u32");
    for (name, root, extra) in [
        (
            "flat",
            flat_root(t.path(), true),
            &["--fields", wide.as_str()][..],
        ),
        ("pcd", pcd_root(t.path()), &[][..]),
    ] {
        let conv = t.path().join(format!("{name}-conv"));
        let (code, _, err) = convert_json(&root, &conv, &[&base[..], extra].concat());
        assert_eq!(code, 0, "{err}");
        let pred = t.path().join(format!("{name}-pred"));
        predictions_from_maps(&conv, &pred);
        let up = t.path().join(format!("{name}-up"));
        ok(&[
            "unproject",
            "--gt",
            s(&conv),
            "--pred",
            s(&pred),
            "--raw",
            s(&root),
            "--out",
            s(&up),
        ]);
        let pics = t.path().join(format!("{name}-pics"));
        ok(&[
            "preview",
            s(&up),
            "--raw",
            s(&root),
            "--gt",
            s(&conv),
            "--out",
            s(&pics),
        ]);
        pictures.push(std::fs::read(pics.join("00_000000.png")).unwrap());
    }
    assert!(
        pictures[0] == pictures[1],
        "the flat root's picture differs from the PCD's"
    );
}

#[test]
fn flat_bin_scans_of_a_declared_layout_convert_as_their_pcd() {
    let t = tmp();
    let vlp = super::util::fixture("own_lidar/sequences/00/velodyne/000000.pcd");
    let root = flat_root(t.path(), false);
    let fields = FLAT_FIELDS;
    let base = ["--sensor", "vlp16", "--all-frames", "--cols", "1024"];
    let (code, j, err) = convert_json(
        &root,
        &t.path().join("o"),
        &[&base[..], &["--fields", fields]].concat(),
    );
    assert_eq!(code, 0, "{err}");
    assert_eq!(
        (j["ring_field_frames"].as_u64(), j["points"].as_u64()),
        (Some(1), Some(14_831))
    );
    assert_eq!(
        j["params"]["map"]["sensor"]["fields"],
        "x:f32,y:f32,z:f32,intensity:u8,_:u8,ring:u16"
    );
    let pcd_root = t.path().join("pcd");
    std::fs::create_dir_all(pcd_root.join("sequences/00/velodyne")).unwrap();
    std::fs::copy(&vlp, pcd_root.join("sequences/00/velodyne/000000.pcd")).unwrap();
    let (code, _, err) = convert_json(&pcd_root, &t.path().join("p"), &base);
    assert_eq!(code, 0, "{err}");
    let npy = |d: &str| std::fs::read(t.path().join(d).join("lidar_2d/00_000000.npy")).unwrap();
    assert_eq!(npy("o"), npy("p"));
    // check counts the records of the declared layout (no read error), and knows the rows.
    let (code, out, err) = run_text(&[
        "check",
        s(&root),
        "--sensor",
        "vlp16",
        "--fields",
        fields,
        "--json",
        "--no-progress",
    ]);
    assert_eq!(code, 0, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert!(
        v["findings"]
            .as_array()
            .unwrap()
            .iter()
            .all(|f| f["severity"] != "error"),
        "{v}"
    );
    // Without --fields the file is taken as KITTI's 16-byte records: garbage, which the beam
    // model reports; a layout whose records do not divide the file is a read error naming it.
    let (code, _, err) = convert_json(
        &root,
        &t.path().join("bad"),
        &[&base[..], &["--fields", "x,y,z,i:f32,pad:u8"]].concat(),
    );
    assert_eq!(code, 1);
    assert!(err.contains("000000.bin"), "{err}");
    for bad in [
        &["--fields", "x,y,intensity"][..],
        &["--fields", "x,y,z:f16"],
    ] {
        let (code, _, err) = convert_json(&root, &t.path().join("bad"), &[&base[..], bad].concat());
        assert_eq!(code, 2, "{bad:?}: {err}");
        assert!(err.contains("--fields"), "{err}");
    }
    let (code, _, err) = convert_json(
        &root,
        &t.path().join("bad"),
        &["--all-frames", "--fields", fields],
    );
    assert_eq!(code, 2);
    assert!(err.contains("--fields needs the sensor"), "{err}");
}

/// Issue 47, defect 1: a `--sensor-pose` that is no mounting (1e30 m, 600 m) is a usage error;
/// a plausible one applies the range limit in the sensor's frame: points it carries past 500 m
/// are dropped and counted, and the map holds none of them.
#[test]
fn the_range_limit_holds_after_the_sensor_pose() {
    let t = tmp();
    let root = super::util::fixture("own_lidar");
    for far in ["1e30,0,0", "600,0,0", "0,0,0,0,0,1e9"] {
        let v = super::util::fails_with(
            &[
                "convert",
                s(&root),
                "--out",
                s(&t.path().join("far")),
                "--sensor",
                "vlp16",
                "--all-frames",
                "--sensor-pose",
                far,
            ],
            "config",
        );
        assert_eq!(v["exit"], 2, "{far}: {v}");
        assert!(
            v["message"].as_str().unwrap().contains("--sensor-pose"),
            "{v}"
        );
    }
    // Three points 450 m ahead and two near ones; the sensor 90 m behind the points' origin
    // sees the far ones at 540 m.
    let seq = t.path().join("root/sequences/00/velodyne");
    std::fs::create_dir_all(&seq).unwrap();
    let pts = [
        [450.0f32, 0.0, 0.0],
        [10.0, 1.0, 0.0],
        [450.0, 5.0, 1.0],
        [-20.0, 3.0, -1.0],
        [449.0, -3.0, 0.0],
    ];
    let mut body = b"VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 5\n\
         HEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 5\nDATA binary\n"
        .to_vec();
    body.extend(pts.iter().flatten().flat_map(|v| v.to_le_bytes()));
    std::fs::write(seq.join("000000.pcd"), body).unwrap();
    let out = t.path().join("out");
    let (code, j, err) = convert_json(
        &t.path().join("root"),
        &out,
        &[
            "--sensor",
            "vlp16",
            "--all-frames",
            "--sensor-pose",
            "-90,0,0",
            "--cols",
            "512",
        ],
    );
    assert_eq!(code, 0, "{err} {j}");
    assert_eq!(j["dropped_out_of_range"], 3, "{j}");
    let map = kitti2pgm::format::pgm::read(&out.join("lidar_2d/00_000000.npy")).unwrap();
    let r = map
        .channels
        .index(kitti2pgm::project::Channel::Range)
        .unwrap();
    let max = (0..map.cells())
        .map(|i| map.cell(i)[r])
        .fold(0.0f32, f32::max);
    assert!(max > 50.0 && max <= 500.0, "{max}");
}

/// Issue 47, defect 9: the calibration table and a class map file are inputs too: an output
/// folder over them (the table's folder, the table itself) is refused before anything is
/// written, as an output over the dataset is.
#[test]
fn the_calibration_table_and_class_map_are_inputs_the_output_may_not_cover() {
    let t = tmp();
    let root = super::util::fixture("own_lidar");
    let cal_dir = t.path().join("cal");
    std::fs::create_dir(&cal_dir).unwrap();
    let yaml = cal_dir.join("VLP16.yaml");
    std::fs::copy(super::util::fixture("lidars/velodyne/VLP16.yaml"), &yaml).unwrap();
    for out in [&cal_dir, &yaml, &t.path().join("x/..").join("cal")] {
        let v = super::util::fails_with(
            &[
                "convert",
                s(&root),
                "--out",
                s(out),
                "--all-frames",
                "--sensor-calibration",
                s(&yaml),
            ],
            "output_over_input",
        );
        assert_eq!(v["exit"], 2, "{v}");
        assert!(
            v["message"]
                .as_str()
                .unwrap()
                .contains("sensor calibration"),
            "{v}"
        );
    }
    assert_eq!(std::fs::read_dir(&cal_dir).unwrap().count(), 1);
    let map = t.path().join("map.yaml");
    std::fs::copy(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("src/label/semantic-kitti.yaml"),
        &map,
    )
    .unwrap();
    let v = super::util::fails_with(
        &[
            "convert",
            s(&root),
            "--out",
            s(&map),
            "--all-frames",
            "--sensor",
            "vlp16",
            "--class-map",
            s(&map),
        ],
        "output_over_input",
    );
    assert_eq!(v["exit"], 2, "{v}");
}
