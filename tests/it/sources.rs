//! SemanticKITTI and the KITTI object set as label sources, on their real fixtures (and
//! `../shared` where present): labels checked against independent computations, the
//! 360-degree preset against elevation binning, and their bad inputs.

use std::path::Path;

use kitti2pgm::format::npy::read_f32;
use kitti2pgm::geom::na;
use kitti2pgm::label::ClassMap;
use kitti2pgm::source::kitti::calib::FrameCalib;
use kitti2pgm::source::kitti::object;

use crate::util::*;

fn points(bin: &Path) -> Vec<[f32; 4]> {
    std::fs::read(bin)
        .unwrap()
        .chunks_exact(16)
        .map(|c| {
            std::array::from_fn(|k| f32::from_le_bytes(c[4 * k..4 * k + 4].try_into().unwrap()))
        })
        .collect()
}

#[test]
fn semantickitti_cells_carry_the_learning_mapped_label_of_their_point() {
    let t = tmp();
    let root = fixture("semantickitti");
    let out = t.path().join("out");
    let (code, j, stderr) = convert_json(&root, &out, &["--fov-deg", "360", "--cols", "2048"]);
    assert_eq!(code, 0, "{stderr}");
    assert_eq!(j["params"]["map"]["class_map"]["name"], "semantic-kitti");
    assert_eq!(j["frames_converted"], 1);
    assert_eq!(j["ring_fallbacks"], 0, "64 rings found in the scan order");
    let map = ClassMap::semantic_kitti();
    let seq = root.join("sequences/00");
    let pts = points(&seq.join("velodyne/000000.bin"));
    let raw: Vec<u32> = std::fs::read(seq.join("labels/000000.label"))
        .unwrap()
        .chunks_exact(4)
        .map(|c| u32::from_le_bytes(c.try_into().unwrap()))
        .collect();
    // Every point's class, by its exact coordinates (distinct points of a scan).
    let mut by_xyz = std::collections::HashMap::new();
    for (p, l) in pts.iter().zip(&raw) {
        let key = [p[0].to_bits(), p[1].to_bits(), p[2].to_bits()];
        by_xyz.insert(key, map.class_of_raw(l & 0xffff).unwrap());
    }
    let (shape, data) = read_f32(&out.join("lidar_2d/00_000000.npy")).unwrap();
    assert_eq!(shape, [64, 2048, 6]);
    let mut checked = 0;
    for cell in data.chunks_exact(6).filter(|c| c[4] > 0.0) {
        let key = [cell[0].to_bits(), cell[1].to_bits(), cell[2].to_bits()];
        assert_eq!(
            cell[5], by_xyz[&key] as f32,
            "cell label = learning_map(point label)"
        );
        checked += 1;
    }
    assert!(checked > 100_000, "{checked}");
    // The .label output: class ids (learning-mapped) and the dataset's instances, point by point.
    let ours = std::fs::read(out.join("labels/00/000000.label")).unwrap();
    for (k, w) in ours.chunks_exact(4).enumerate() {
        let v = u32::from_le_bytes(w.try_into().unwrap());
        assert_eq!(
            v & 0xffff,
            map.class_of_raw(raw[k] & 0xffff).unwrap() as u32
        );
        assert_eq!(v >> 16, raw[k] >> 16);
    }
    // The point protocol finds the scans of a SemanticKITTI root.
    let (code, stdout, e) = run_text(&[
        "score",
        "--gt",
        s(&out),
        "--pred",
        s(&out.join("labels")),
        "--points",
        "--raw",
        s(&root),
        "--json",
    ]);
    assert_eq!(code, 0, "{e}");
    let j: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(j["classes"]["car"]["iou"], 1.0);
}

#[test]
fn the_360_preset_fills_clearly_more_than_elevation_binning() {
    let t = tmp();
    let root = fixture("semantickitti");
    let fill = |mode: &str| {
        let out = t.path().join(mode);
        let args = ["--fov-deg", "360", "--cols", "2048", "--row-mode", mode];
        let (code, j, e) = convert_json(&root, &out, &args);
        assert_eq!(code, 0, "{e}");
        j["filled_cells"].as_f64().unwrap() / j["total_cells"].as_f64().unwrap()
    };
    let (rings, binned) = (fill("rings"), fill("elevation"));
    assert!(
        rings > binned + 0.05,
        "rings {rings:.3}, elevation bins {binned:.3}"
    );
}

/// The classes an independent computation gives an object frame's points: each point taken to
/// the rectified camera frame with R0_rect * Tr_velo_to_cam, tested against each box in the
/// box's own axes there. `None` for a point within 2 cm of a box face (left to rounding).
fn object_classes(root: &Path, frame: &str) -> Vec<Option<u32>> {
    let calib = FrameCalib::read(&root.join(format!("calib/{frame}.txt"))).unwrap();
    let m = calib.velo_to_rect();
    let objects = object::read(&root.join(format!("label_2/{frame}.txt"))).unwrap();
    let map = ClassMap::kitti_paper();
    points(&root.join(format!("velodyne/{frame}.bin")))
        .iter()
        .map(|p| {
            let q = m * na::Vector4::new(p[0] as f64, p[1] as f64, p[2] as f64, 1.0);
            let mut class = 0u32;
            let mut smallest = f64::INFINITY;
            for o in &objects {
                let c = map.class_of_object(&o.kind) as u32;
                let [h, w, l] = o.hwl;
                let d = na::Vector3::new(q.x, q.y, q.z) - o.location.coords;
                let (s, co) = o.rotation_y.sin_cos();
                // Box axes in the rectified frame: x = (cos, 0, -sin), y = down, z = (sin, 0, cos).
                let (x, y, z) = (co * d.x - s * d.z, d.y, s * d.x + co * d.z);
                let margin = (l / 2.0 - x.abs())
                    .min(w / 2.0 - z.abs())
                    .min((-y).min(h + y));
                if margin.abs() < 0.02 && c != 0 {
                    return None;
                }
                if margin > 0.0 && c != 0 && h * w * l < smallest {
                    smallest = h * w * l;
                    class = c;
                }
            }
            Some(class)
        })
        .collect()
}

#[test]
fn object_labels_agree_with_an_independent_point_in_box_test() {
    let t = tmp();
    let root = fixture("kitti_object");
    let out = t.path().join("out");
    let (code, j, stderr) = convert_json(&root, &out, &["--rgb"]);
    assert_eq!(code, 0, "{stderr}");
    assert_eq!(j["frames_converted"], 2);
    let split = root.join("training");
    let mut inside = 0;
    for frame in ["000000", "000001"] {
        let want = object_classes(&split, frame);
        let got: Vec<u32> = std::fs::read(out.join(format!("labels/object/{frame}.label")))
            .unwrap()
            .chunks_exact(4)
            .map(|w| u32::from_le_bytes(w.try_into().unwrap()) & 0xffff)
            .collect();
        assert_eq!(got.len(), want.len());
        for (k, (g, w)) in got.iter().zip(&want).enumerate() {
            if let Some(w) = w {
                assert_eq!(g, w, "frame {frame} point {k}");
                inside += (*w != 0) as usize;
            }
        }
        let (shape, _) = read_f32(&out.join(format!("lidar_2d/{frame}.npy"))).unwrap();
        assert_eq!(shape, [64, 512, 9]);
    }
    assert!(inside > 200, "points in object boxes: {inside}");
    // Frame 000001's truck, car and cyclist are all labelled (DontCare stays background).
    let cells = &j["labelled_points"];
    assert!(
        cells["car"].as_u64().unwrap() > 0 && cells["cyclist"].as_u64().unwrap() > 0,
        "{cells}"
    );
    assert!(
        cells["pedestrian"].as_u64().unwrap() > 0,
        "frame 000000's pedestrian"
    );
}

#[test]
fn scans_without_labels_convert_as_unlabelled_and_say_so() {
    let t = tmp();
    let root = t.path().join("sk");
    copy_tree(&fixture("semantickitti"), &root);
    std::fs::remove_dir_all(root.join("sequences/00/labels")).unwrap();
    let (code, j, stderr) = convert_json(&root, &t.path().join("out"), &[]);
    assert_eq!(code, 0, "{stderr}");
    assert_eq!(j["frames_without_labels"], 1);
    assert!(
        stderr.contains("1 frame(s) have no labels: converted with every point unlabeled"),
        "{stderr}"
    );
}

#[test]
fn bad_source_inputs_name_the_file() {
    let t = tmp();
    // A .label whose length differs from the scan's.
    let sk = t.path().join("sk");
    copy_tree(&fixture("semantickitti"), &sk);
    let label = sk.join("sequences/00/labels/000000.label");
    let good = std::fs::read(&label).unwrap();
    std::fs::write(&label, &good[..good.len() - 8]).unwrap();
    let (code, j, _) = convert_json(&sk, &t.path().join("o1"), &[]);
    assert_eq!(code, 1);
    let f = j["failures"].to_string();
    assert!(
        f.contains("000000.label") && f.contains("labels, but the scan"),
        "{f}"
    );
    // An unknown label id.
    let mut bad = good.clone();
    bad[40..44].copy_from_slice(&7u32.to_le_bytes());
    std::fs::write(&label, &bad).unwrap();
    let (_, j, _) = convert_json(&sk, &t.path().join("o2"), &[]);
    let f = j["failures"].to_string();
    assert!(f.contains("point 10 has label id 7"), "{f}");
    // Colour through P2 and Tr of calib.txt; then a calibration without Tr (needed for colour).
    std::fs::write(&label, &good).unwrap();
    std::fs::create_dir_all(sk.join("sequences/00/image_2")).unwrap();
    let img =
        kitti2pgm::raster::RgbImage::from_pixel(1241, 376, kitti2pgm::raster::Rgb([255, 128, 0]));
    kitti2pgm::format::png::write(&sk.join("sequences/00/image_2/000000.png"), &img).unwrap();
    let (code, j, e) = convert_json(&sk, &t.path().join("rgb"), &["--rgb"]);
    assert_eq!(code, 0, "{e}");
    let coloured = j["rgb_cells"].as_u64().unwrap();
    assert!(
        coloured > 10_000 && coloured < j["filled_cells"].as_u64().unwrap(),
        "{coloured}"
    );
    let (_, m) = read_f32(&t.path().join("rgb/lidar_2d/00_000000.npy")).unwrap();
    assert!(m
        .chunks_exact(9)
        .any(|c| c[6..] == [1.0, 128.0 / 255.0, 0.0]));
    let calib = sk.join("sequences/00/calib.txt");
    let text = std::fs::read_to_string(&calib).unwrap();
    let no_tr: String = text
        .lines()
        .filter(|l| !l.starts_with("Tr"))
        .map(|l| format!("{l}\n"))
        .collect();
    std::fs::write(&calib, no_tr).unwrap();
    std::fs::create_dir_all(sk.join("sequences/00/image_2")).unwrap();
    kitti2pgm::format::png::write(
        &sk.join("sequences/00/image_2/000000.png"),
        &kitti2pgm::raster::RgbImage::new(1241, 376),
    )
    .unwrap();
    let (_, j, _) = convert_json(&sk, &t.path().join("o3"), &["--rgb"]);
    let f = j["failures"].to_string();
    assert!(
        f.contains("calib.txt") && f.contains("missing key `Tr`"),
        "{f}"
    );
    // A label_2 line with too few fields.
    let ko = t.path().join("ko");
    copy_tree(&fixture("kitti_object"), &ko);
    std::fs::write(
        ko.join("training/label_2/000000.txt"),
        "Pedestrian 0.00 0 -0.20 712.40\n",
    )
    .unwrap();
    let (code, j, _) = convert_json(&ko, &t.path().join("o4"), &[]);
    assert_eq!(code, 3);
    let f = j["failures"].to_string();
    assert!(
        f.contains("label_2/000000.txt:1") && f.contains("5 fields, expected 15"),
        "{f}"
    );
}

#[test]
#[ignore = "needs ../shared"]
fn shared_semantickitti_scans_convert_with_every_ring() {
    let root = needs_shared("semantickitti");
    let t = tmp();
    let (code, j, e) = convert_json(
        &root,
        &t.path().join("out"),
        &["--fov-deg", "360", "--cols", "2048"],
    );
    assert_eq!(code, 0, "{e}");
    assert_eq!(j["frames_converted"], 3);
    assert_eq!(j["ring_fallbacks"], 0);
}

fn split_json(root: &Path, out: &Path, extra: &[&str]) -> serde_json::Value {
    let mut args = vec!["split", s(root), "--out", s(out), "--json"];
    args.extend_from_slice(extra);
    let (code, stdout, stderr) = run_text(&args);
    assert_eq!(code, 0, "{stderr}");
    serde_json::from_str(&stdout).unwrap()
}

#[test]
fn splits_follow_each_dataset() {
    let t = tmp();
    // SemanticKITTI: the dataset's own split (sequence 00 is train); scans without labels: test.
    let sk = t.path().join("sk");
    copy_tree(&fixture("semantickitti"), &sk);
    let j = split_json(&sk, &t.path().join("a"), &[]);
    assert_eq!((j["train"].as_u64(), j["val"].as_u64()), (Some(1), Some(0)));
    let j = split_json(&sk, &t.path().join("b"), &["--val-sequences", "0"]);
    assert_eq!(j["val"], 1);
    let val = std::fs::read_to_string(t.path().join("b/ImageSet/val.txt")).unwrap();
    assert_eq!(val, "00_000000\n");
    std::fs::remove_dir_all(sk.join("sequences/00/labels")).unwrap();
    let j = split_json(&sk, &t.path().join("c"), &[]);
    assert_eq!(
        (j["train"].as_u64(), j["test"].as_u64()),
        (Some(0), Some(1))
    );
    // KITTI object: a seeded frame split, the same for the same seed, or a given list.
    let ko = fixture("kitti_object");
    let a = split_json(
        &ko,
        &t.path().join("d"),
        &["--random-val", "0.5", "--seed", "3"],
    );
    assert_eq!((a["train"].as_u64(), a["val"].as_u64()), (Some(1), Some(1)));
    let read =
        |d: &str| std::fs::read_to_string(t.path().join(d).join("ImageSet/val.txt")).unwrap();
    split_json(
        &ko,
        &t.path().join("e"),
        &["--random-val", "0.5", "--seed", "3"],
    );
    assert_eq!(read("d"), read("e"));
    let list = t.path().join("val.txt");
    std::fs::write(&list, "000001\n").unwrap();
    split_json(&ko, &t.path().join("f"), &["--val-list", s(&list)]);
    assert_eq!(read("f"), "000001\n");
}

#[test]
fn shards_stats_and_previews_take_twenty_classes() {
    let t = tmp();
    let out = t.path().join("out");
    let args = ["--fov-deg", "360", "--cols", "2048", "--format", "npy,mcap"];
    let (code, _, e) = convert_json(&fixture("semantickitti"), &out, &args);
    assert_eq!(code, 0, "{e}");
    // The shard carries the class map; sequence 00 is train.
    let shard = out.join("shards/train-00000.mcap");
    let md = kitti2pgm::format::shard::Shard::open(&shard)
        .unwrap()
        .metadata()
        .unwrap();
    assert_eq!(md.params.map.class_map, ClassMap::semantic_kitti());
    let (code, stdout, e) = run_text(&["stats", s(&out), "--json"]);
    assert_eq!(code, 0, "{e}");
    let j: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(
        j["class_weights"]["inverse_frequency"]
            .as_array()
            .unwrap()
            .len(),
        20
    );
    assert_eq!(
        j["class_weights"]["inverse_frequency"][0], 0.0,
        "unlabeled is ignored"
    );
    assert!(j["splits"]["all"]["cells"]["road"].as_u64().unwrap() > 10_000);
    let png = t.path().join("p.png");
    let (code, _, e) = run_text(&[
        "preview",
        s(&out.join("lidar_2d/00_000000.npy")),
        "--out",
        s(&png),
    ]);
    assert_eq!(code, 0, "{e}");
    let img = kitti2pgm::raster::read(&png).unwrap();
    // Some label pixel is road's colour (color_map 40: [255, 0, 255] BGR = RGB 255, 0, 255).
    let road = ClassMap::semantic_kitti().colour(9);
    assert!(
        img.pixels().any(|p| p.0 == road),
        "road drawn in its colour {road:?}"
    );
}
