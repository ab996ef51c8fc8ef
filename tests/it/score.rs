//! `kitti2pgm score`: hand-computed IoUs, perfect and empty predictions, both protocols, every
//! prediction format, bad input.

use std::path::{Path, PathBuf};

use kitti2pgm::format::npy::{encode_f32, read_f32};
use kitti2pgm::report::score::{Confusion, Protocol};
use npyz::WriterBuilder;

use crate::util::*;

fn write_f32(path: &Path, shape: &[u64], data: &[f32]) {
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    std::fs::write(path, encode_f32(shape, data)).unwrap();
}

fn write_i64(path: &Path, shape: &[u64], data: &[i64]) {
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    let mut out = Vec::new();
    let mut w = npyz::WriteOptions::new()
        .default_dtype()
        .shape(shape)
        .writer(&mut out)
        .begin_nd()
        .unwrap();
    w.extend(data.iter().copied()).unwrap();
    w.finish().unwrap();
    std::fs::write(path, out).unwrap();
}

fn score_json(args: &[&str]) -> serde_json::Value {
    let mut a = vec!["score", "--json"];
    a.extend_from_slice(args);
    let (code, stdout, stderr) = run_text(&a);
    assert_eq!(code, 0, "{stderr}");
    serde_json::from_str(&stdout).unwrap()
}

fn iou(j: &serde_json::Value, class: &str) -> f64 {
    j["classes"][class]["iou"].as_f64().unwrap_or(f64::NAN)
}

/// A 2 x 4 ground truth and prediction, IoUs worked out by hand.
#[test]
fn hand_computed_ious_on_a_small_map() {
    let t = tmp();
    let gt = t.path().join("gt");
    // Cells (row-major): truth labels, the last cell empty (range 0, not scored).
    let truth = [1, 1, 1, 0, 2, 2, 3, 0];
    let mut data = vec![0f32; 8 * 6];
    for (i, &l) in truth.iter().enumerate() {
        if i != 7 {
            data[i * 6..i * 6 + 6].copy_from_slice(&[1.0, 0.0, 0.0, 0.5, 1.0, l as f32]);
        }
    }
    write_f32(
        &gt.join("lidar_2d/2011_09_26_0001_0000000000.npy"),
        &[2, 4, 6],
        &data,
    );
    let pred = t.path().join("pred/2011_09_26_0001_0000000000.npy");
    write_i64(&pred, &[2, 4], &[1, 1, 0, 1, 2, 0, 0, 3]);
    // Through the library: the figures as typed values.
    use kitti2pgm::report::score::{report, score, Predictions, ScoreOptions};
    let truth = kitti2pgm::report::truth::GroundTruth::open(&gt).unwrap();
    let preds = Predictions::index(pred.parent().unwrap()).unwrap();
    let opts = ScoreOptions {
        protocol: Protocol::Cells,
        missing_as_background: false,
        raw: None,
        unproject: kitti2pgm::project::unproject::Method::Cell,
    };
    let (scores, _) = score(&truth, None, &preds, &opts, &Default::default(), &|_| {}).unwrap();
    let r = report(Protocol::Cells, &scores, &truth.params.class_map);
    let iou = |class: &str| r.classes[class].iou;
    // car: TP 2 (cells 0, 1), FP 1 (cell 3), FN 1 (cell 2) -> 2/4.
    assert_eq!(iou("car"), Some(0.5));
    // pedestrian: TP 1 (cell 4), FN 1 (cell 5) -> 1/2.
    assert_eq!(iou("pedestrian"), Some(0.5));
    // cyclist: TP 0, FN 1 (cell 6); cell 7 is empty, so its prediction does not count -> 0.
    assert_eq!(iou("cyclist"), Some(0.0));
    // background: TP 0, FP 3 (cells 2, 5, 6), FN 1 (cell 3) -> 0.
    assert_eq!(iou("background"), Some(0.0));
    assert_eq!(r.elements, 7);
    assert_eq!(r.miou, (0.5 + 0.5 + 0.0) / 3.0);
    assert_eq!(r.classes["car"].precision, Some(2.0 / 3.0));
    assert_eq!(r.classes["car"].recall, Some(2.0 / 3.0));
    assert_eq!(r.confusion.m[1], [1, 2, 0, 0]);
    // The binary reports the same figures.
    let j = score_json(&["--gt", s(&gt), "--pred", s(pred.parent().unwrap())]);
    assert_eq!(j["classes"], serde_json::to_value(&r.classes).unwrap());
    assert_eq!(j["confusion"], serde_json::to_value(&r.confusion).unwrap());
}

#[test]
fn confusion_algebra() {
    let mut c = Confusion::new(4);
    c.m[1][1] = 8;
    c.m[1][0] = 2;
    c.m[0][1] = 2;
    c.m[0][0] = 100;
    assert_eq!(c.iou(1), Some(8.0 / 12.0));
    assert_eq!(c.iou(2), None);
    assert_eq!(
        c.miou(&[1, 2, 3]),
        8.0 / 12.0,
        "absent classes are left out of the mean"
    );
    let _ = Protocol::Cells;
}

/// Converts the fixtures; returns (gt folder, its lidar_2d).
fn gt(t: &Path) -> (PathBuf, PathBuf) {
    let gt = t.join("gt");
    assert_eq!(run_text(&["convert", s(&fixtures()), "--out", s(&gt)]).0, 0);
    let l = gt.join("lidar_2d");
    (gt, l)
}

#[test]
fn perfect_and_all_background_predictions() {
    let t = tmp();
    let (gt, l2d) = gt(t.path());
    // The ground truth itself, in SqueezeSeg layout: perfect.
    let j = score_json(&["--gt", s(&gt), "--pred", s(&l2d)]);
    for c in ["background", "car", "cyclist"] {
        assert_eq!(iou(&j, c), 1.0, "{c}");
    }
    assert!(
        j["classes"]["pedestrian"]["iou"].is_null(),
        "no pedestrian in the fixtures"
    );
    assert_eq!(j["miou"], 1.0);
    // All background: 0 for every object class, and missing frames may be scored as background.
    let empty = t.path().join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    write_i64(
        &empty.join("2011_09_26_0052_0000000000.npy"),
        &[64, 512],
        &vec![0; 64 * 512],
    );
    let j = score_json(&[
        "--gt",
        s(&gt),
        "--pred",
        s(&empty),
        "--missing-as-background",
    ]);
    assert_eq!(j["missing_frames"], 2);
    assert_eq!(iou(&j, "car"), 0.0);
    assert_eq!(iou(&j, "cyclist"), 0.0);
    assert_eq!(j["miou"], 0.0);
    assert!(iou(&j, "background") > 0.5);
}

#[test]
fn every_prediction_format_gives_the_same_score() {
    let t = tmp();
    let (gt, l2d) = gt(t.path());
    let reference = score_json(&["--gt", s(&gt), "--pred", s(&l2d)]);
    let (maps, scores) = (t.path().join("maps"), t.path().join("scores"));
    for e in std::fs::read_dir(&l2d).unwrap() {
        let p = e.unwrap().path();
        let (_, data) = read_f32(&p).unwrap();
        let labels: Vec<f32> = data.chunks_exact(6).map(|c| c[5]).collect();
        // A float label map, and one-hot-ish scores whose argmax is the label.
        write_f32(&maps.join(p.file_name().unwrap()), &[64, 512], &labels);
        let sc: Vec<f32> = labels
            .iter()
            .flat_map(|&l| (0..4).map(move |k| if k as f32 == l { 0.7 } else { 0.1 }))
            .collect();
        write_f32(&scores.join(p.file_name().unwrap()), &[64, 512, 4], &sc);
    }
    for pred in [&maps, &scores] {
        let j = score_json(&["--gt", s(&gt), "--pred", s(pred)]);
        assert_eq!(j["confusion"], reference["confusion"], "{}", pred.display());
    }
    // Per-point .label files (the converter's own) under the cell protocol: the prediction of a
    // cell is that of the point that won it, so this is perfect too.
    let j = score_json(&[
        "--gt",
        s(&gt),
        "--pred",
        s(&gt.join("labels")),
        "--raw",
        s(&fixtures()),
    ]);
    assert_eq!(j["confusion"], reference["confusion"]);
}

/// Rewrites a scan keeping, in the front field of view, only the point that wins each cell, so
/// that no cell holds two points.
fn deduplicated_raw(t: &Path) -> PathBuf {
    use kitti2pgm::project::{project, PgmSpec, EMPTY};
    use kitti2pgm::source::Scan;
    let root = fixture_copy(t);
    let bin =
        root.join("2011_09_26/2011_09_26_drive_0052_sync/velodyne_points/data/0000000000.bin");
    let scan = Scan::read(&bin).unwrap();
    let spec = PgmSpec::default();
    let proj = project(&scan.points, &spec);
    let winners: std::collections::BTreeSet<u32> = proj
        .cell_point
        .iter()
        .copied()
        .filter(|&p| p != EMPTY)
        .collect();
    let mut bytes = Vec::new();
    for (i, p) in scan.points.iter().enumerate() {
        if spec.column(p).is_some() && !winners.contains(&(i as u32)) {
            continue;
        }
        for v in [p.x, p.y, p.z, scan.intensity[i]] {
            bytes.extend_from_slice(&v.to_le_bytes());
        }
    }
    std::fs::write(&bin, bytes).unwrap();
    root
}

#[test]
fn cell_and_point_protocols_agree_where_no_cell_holds_two_points() {
    let t = tmp();
    let raw = deduplicated_raw(t.path());
    let gt = t.path().join("gt");
    let (code, stdout, _) = run_text(&[
        "convert",
        s(&raw.join("2011_09_26/2011_09_26_drive_0052_sync")),
        "--out",
        s(&gt),
        "--json",
    ]);
    assert_eq!(code, 0);
    let summary: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(
        summary["collisions"], 0,
        "the rewritten scan has no collisions"
    );
    assert_eq!(summary["ring_fallbacks"], 0);
    // A prediction that is wrong in places: every tenth cell called car.
    let (_, data) = read_f32(&gt.join("lidar_2d/2011_09_26_0052_0000000000.npy")).unwrap();
    let pred: Vec<i64> = data
        .chunks_exact(6)
        .enumerate()
        .map(|(i, c)| if i % 10 == 0 { 1 } else { c[5] as i64 })
        .collect();
    let pdir = t.path().join("pred");
    write_i64(
        &pdir.join("2011_09_26_0052_0000000000.npy"),
        &[64, 512],
        &pred,
    );
    let cells = score_json(&["--gt", s(&gt), "--pred", s(&pdir)]);
    let points = score_json(&[
        "--gt",
        s(&gt),
        "--pred",
        s(&pdir),
        "--points",
        "--raw",
        s(&raw),
    ]);
    assert_eq!(points["protocol"], "points");
    assert_eq!(cells["confusion"], points["confusion"]);
    assert!(iou(&cells, "car") < 1.0);
}

#[test]
fn points_protocol_on_real_scans_with_collisions() {
    let t = tmp();
    let (gt, _) = gt(t.path());
    let j = score_json(&[
        "--gt",
        s(&gt),
        "--pred",
        s(&gt.join("labels")),
        "--points",
        "--raw",
        s(&fixtures()),
    ]);
    assert_eq!(iou(&j, "car"), 1.0);
    let cells = score_json(&[
        "--gt",
        s(&gt),
        "--pred",
        s(&gt.join("labels")),
        "--raw",
        s(&fixtures()),
    ]);
    assert!(
        j["elements"].as_u64().unwrap() > cells["elements"].as_u64().unwrap(),
        "points outnumber filled cells"
    );
}

#[test]
fn json_schema_is_stable() {
    let t = tmp();
    let (gt, l2d) = gt(t.path());
    let j = score_json(&["--gt", s(&gt), "--pred", s(&l2d), "--per-frame"]);
    let keys: Vec<&str> = j.as_object().unwrap().keys().map(String::as_str).collect();
    assert_eq!(
        keys,
        [
            "accuracy",
            "class_names",
            "classes",
            "confusion",
            "elements",
            "frames",
            "miou",
            "miou_absent",
            "miou_classes",
            "missing_frames",
            "per_frame",
            "predictions_without_truth",
            "protocol",
            "version"
        ]
    );
    assert_eq!(j["version"], 3, "3 added accuracy and miou_absent");
    assert_eq!(
        j["class_names"],
        serde_json::json!(["background", "car", "pedestrian", "cyclist"])
    );
    assert_eq!(
        j["miou_classes"],
        serde_json::json!(["car", "pedestrian", "cyclist"])
    );
    let class_keys: Vec<&str> = j["classes"]["car"]
        .as_object()
        .unwrap()
        .keys()
        .map(String::as_str)
        .collect();
    assert_eq!(class_keys, ["iou", "precision", "recall", "support"]);
    let pf = &j["per_frame"][0];
    let pf_keys: Vec<&str> = pf.as_object().unwrap().keys().map(String::as_str).collect();
    assert_eq!(pf_keys, ["elements", "id", "iou", "miou_present"]);
    assert_eq!(j["per_frame"].as_array().unwrap().len(), 3);
}

#[test]
fn pictures_and_imageset() {
    let t = tmp();
    let (gt, l2d) = gt(t.path());
    let list = t.path().join("val.txt");
    std::fs::write(&list, "2011_09_26_0052_0000000000\n").unwrap();
    let (conf, worst) = (t.path().join("c.png"), t.path().join("worst"));
    let (code, stdout, _) = run_text(&[
        "score",
        "--gt",
        s(&gt),
        "--pred",
        s(&l2d),
        "--imageset",
        s(&list),
        "--confusion",
        s(&conf),
        "--worst",
        "5",
        "--worst-dir",
        s(&worst),
        "--per-frame",
    ]);
    assert_eq!(code, 0);
    assert!(
        stdout.contains("1 frames")
            && stdout.contains("mIoU")
            && stdout.contains("2011_09_26_0052_0000000000"),
        "{stdout}"
    );
    assert!(kitti2pgm::raster::read(&conf).unwrap().width() > 400);
    let pngs: Vec<_> = std::fs::read_dir(&worst).unwrap().collect();
    assert_eq!(pngs.len(), 1, "only one frame in the list");
}

#[test]
fn bad_predictions_name_the_frame() {
    let t = tmp();
    let (gt, l2d) = gt(t.path());
    let bad = t.path().join("bad");
    let one = |name: &str| bad.join(format!("{name}.npy"));
    let id = "2011_09_26_0052_0000000000";
    let run_bad = |extra: &[&str]| {
        let mut a = vec!["score", "--gt", s(&gt), "--pred", s(&bad)];
        a.extend_from_slice(extra);
        run_text(&a)
    };
    // A ground-truth frame without prediction.
    write_i64(&one(id), &[64, 512], &vec![0; 64 * 512]);
    let (code, _, stderr) = run_bad(&[]);
    assert_eq!(code, 1);
    assert!(
        stderr.contains("no prediction for ground-truth frame 2011_09_26_0001_0000000000")
            && stderr.contains("--missing-as-background"),
        "{stderr}"
    );
    // Shape mismatch.
    write_i64(&one(id), &[32, 512], &vec![0; 32 * 512]);
    let (code, _, stderr) = run_bad(&["--missing-as-background"]);
    assert_eq!(code, 1);
    assert!(
        stderr.contains(&format!("{id}.npy")) && stderr.contains("is 32x512, expected 64x512"),
        "{stderr}"
    );
    // Labels out of range.
    let mut v = vec![0i64; 64 * 512];
    v[700] = 7;
    write_i64(&one(id), &[64, 512], &v);
    let (code, _, stderr) = run_bad(&["--missing-as-background"]);
    assert_eq!(code, 1);
    assert!(
        stderr.contains(&format!("{id}.npy"))
            && stderr.contains("cell (1, 188) has label 7, not a class id"),
        "{stderr}"
    );
    // NaN scores.
    let mut sc = vec![0.25f32; 64 * 512 * 4];
    sc[4 * 1000 + 2] = f32::NAN;
    write_f32(&one(id), &[64, 512, 4], &sc);
    let (code, _, stderr) = run_bad(&["--missing-as-background"]);
    assert_eq!(code, 1);
    assert!(
        stderr.contains(&format!("{id}.npy")) && stderr.contains("NaN"),
        "{stderr}"
    );
    // Mixed formats.
    std::fs::create_dir_all(bad.join("2011_09_26_drive_0052_sync")).unwrap();
    std::fs::copy(
        gt.join("labels/2011_09_26_drive_0052_sync/0000000000.label"),
        bad.join("2011_09_26_drive_0052_sync/0000000001.label"),
    )
    .unwrap();
    let (code, _, stderr) = run_bad(&["--missing-as-background"]);
    assert_eq!(code, 1);
    assert!(stderr.contains("mixed formats"), "{stderr}");
    // The point protocol without the raw scans is a usage error.
    assert_eq!(
        run_text(&["score", "--gt", s(&gt), "--pred", s(&l2d), "--points"]).0,
        2
    );
}

#[test]
fn ground_truth_shards_score_like_the_npy_folder() {
    let t = tmp();
    let gt = t.path().join("gt");
    assert_eq!(
        run_text(&[
            "convert",
            s(&fixtures()),
            "--out",
            s(&gt),
            "--format",
            "npy,mcap",
            "--shard-frames",
            "2"
        ])
        .0,
        0
    );
    let (_, data) = read_f32(&gt.join("lidar_2d/2011_09_26_0001_0000000045.npy")).unwrap();
    let pdir = t.path().join("pred");
    for e in std::fs::read_dir(gt.join("lidar_2d")).unwrap() {
        let p = e.unwrap().path();
        let (_, d) = read_f32(&p).unwrap();
        let pred: Vec<i64> = d
            .chunks_exact(6)
            .enumerate()
            .map(|(i, c)| if i % 7 == 0 { 2 } else { c[5] as i64 })
            .collect();
        write_i64(&pdir.join(p.file_name().unwrap()), &[64, 512], &pred);
    }
    assert!(!data.is_empty());
    let from_npy = score_json(&["--gt", s(&gt), "--pred", s(&pdir)]);
    let from_shards = score_json(&["--gt", s(&gt.join("shards")), "--pred", s(&pdir)]);
    assert_eq!(from_npy["confusion"], from_shards["confusion"]);
    assert_eq!(from_shards["frames"], 3);
    let one = score_json(&[
        "--gt",
        s(&gt.join("shards/train-00001.mcap")),
        "--pred",
        s(&pdir),
    ]);
    assert_eq!(one["frames"], 1);
    // An ImageSet restricts the frames; one naming a frame absent from the shards is an error.
    let list = t.path().join("val.txt");
    std::fs::write(&list, "2011_09_26_0052_0000000000\n").unwrap();
    let j = score_json(&[
        "--gt",
        s(&gt.join("shards")),
        "--pred",
        s(&pdir),
        "--imageset",
        s(&list),
        "--worst",
        "1",
        "--worst-dir",
        s(&t.path().join("w")),
    ]);
    assert_eq!(j["frames"], 1);
    assert!(t
        .path()
        .join("w/001_2011_09_26_0052_0000000000.png")
        .is_file());
    std::fs::write(&list, "2011_09_26_0052_0000000001\n").unwrap();
    let (code, _, stderr) = run_text(&[
        "score",
        "--gt",
        s(&gt.join("shards")),
        "--pred",
        s(&pdir),
        "--imageset",
        s(&list),
    ]);
    assert_eq!(code, 1);
    assert!(
        stderr.contains("2011_09_26_0052_0000000001") && stderr.contains("not in the ground truth"),
        "{stderr}"
    );
    // Shards as predictions: their label maps, matched by frame id (perfect against themselves).
    let j = score_json(&["--gt", s(&gt), "--pred", s(&gt.join("shards"))]);
    assert_eq!(iou(&j, "car"), 1.0);
    assert_eq!(j["frames"], 3);
    let (code, _, stderr) = run_text(&[
        "score",
        "--gt",
        s(&gt.join("shards")),
        "--pred",
        s(&pdir),
        "--points",
        "--raw",
        s(&fixtures()),
    ]);
    assert_eq!(code, 2);
    assert!(
        stderr.contains("point protocol needs a convert output folder"),
        "{stderr}"
    );
}

/// `np.save(path, np.asfortranarray(a))` for a float32 array.
fn fortran_npy(shape: &[u64], c_data: &[f32]) -> Vec<u8> {
    let dims: Vec<usize> = shape.iter().map(|&d| d as usize).collect();
    let (h, w, c) = (dims[0], dims[1], dims[2]);
    let mut f = Vec::with_capacity(c_data.len());
    for k in 0..c {
        for j in 0..w {
            for i in 0..h {
                f.push(c_data[(i * w + j) * c + k]);
            }
        }
    }
    let mut bytes = kitti2pgm::format::npy::encode_f32(shape, &f);
    let header = String::from_utf8_lossy(&bytes[10..80]).into_owned();
    assert!(header.contains("'fortran_order': False"));
    // Same length: "True, " + padding is one byte shorter than "False,"; NumPy pads with spaces.
    let patched = header.replacen("'fortran_order': False", "'fortran_order': True ", 1);
    bytes[10..80].copy_from_slice(patched.as_bytes());
    bytes
}

#[test]
fn fortran_ordered_predictions_are_read_right() {
    let t = tmp();
    let out = t.path().join("out");
    convert_fixtures(&out, &[]);
    let pred = t.path().join("pred");
    std::fs::create_dir_all(&pred).unwrap();
    for e in std::fs::read_dir(out.join("lidar_2d")).unwrap() {
        let p = e.unwrap().path();
        let (shape, data) = kitti2pgm::format::npy::read_f32(&p).unwrap();
        std::fs::write(
            pred.join(p.file_name().unwrap()),
            fortran_npy(&shape, &data),
        )
        .unwrap();
    }
    let (code, stdout, stderr) =
        run_text(&["score", "--gt", s(&out), "--pred", s(&pred), "--json"]);
    assert_eq!(code, 0, "{stderr}");
    let j: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(j["miou"], 1.0, "perfect predictions saved in Fortran order");
}

#[test]
fn predictions_without_ground_truth_are_named() {
    let t = tmp();
    let out = t.path().join("out");
    convert_fixtures(&out, &[]);
    let pred = t.path().join("pred");
    copy_tree(&out.join("lidar_2d"), &pred);
    std::fs::copy(
        pred.join("2011_09_26_0052_0000000000.npy"),
        pred.join("2011_09_26_0052_0000000099.npy"),
    )
    .unwrap();
    let (code, stdout, stderr) =
        run_text(&["score", "--gt", s(&out), "--pred", s(&pred), "--json"]);
    assert_eq!(code, 0);
    let j: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(
        j["predictions_without_truth"],
        serde_json::json!(["2011_09_26_0052_0000000099"])
    );
    assert!(
        stderr.contains("not in the ground truth, not scored"),
        "{stderr}"
    );
}

#[test]
fn semantickitti_scores_say_points_and_blame_a_truncated_truth() {
    let t = tmp();
    let sk = copy_of("semantickitti", t.path());
    let truth = sk.join("sequences/00/labels/000000.label");
    let pred_dir = t.path().join("pred/sequences/00/predictions");
    std::fs::create_dir_all(&pred_dir).unwrap();
    std::fs::copy(&truth, pred_dir.join("000000.label")).unwrap();
    let pred = t.path().join("pred");
    let (code, stdout, e) = run_text(&["score", "--gt", s(&sk), "--pred", s(&pred), "--json"]);
    assert_eq!(code, 0, "{e}");
    let j: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(j["protocol"], "points", "{stdout}");
    let bytes = std::fs::read(&truth).unwrap();
    std::fs::write(&truth, &bytes[..bytes.len() - 40]).unwrap();
    let (code, _, e) = run_text(&["score", "--gt", s(&sk), "--pred", s(&pred)]);
    assert_eq!(code, 1, "{e}");
    assert!(
        e.contains("labels/000000.label") && e.contains("truncated ground truth"),
        "{e}"
    );
}
