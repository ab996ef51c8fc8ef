//! `kitti2pgm label` (issue 46): a sequence of the real VLP-16 scan labelled from
//! SUSTechPOINTS boxes, every point's class and instance compared with the independent
//! reference of `annotations.rs`; re-runs, foreign labels, unknown types, missing scans, and
//! what `convert` makes of the result.

use std::path::{Path, PathBuf};

use super::annotations::{centred_refs, obj, reference, rx_ry_rz, test_boxes, TestBox};
use super::util::{fails_with, fixture, run_text, s, tmp};

/// SUSTechPOINTS' types of the test boxes, and their classes in its shipped map.
const TYPES: [&str; 5] = ["Car", "Pedestrian", "Truck", "Car", "BicycleRider"];
const CLASSES: [u32; 5] = [1, 4, 2, 1, 5];

/// A root of `frames` copies of the real VLP-16 scan (sequences/00/velodyne/<frame6>.pcd) and
/// a SUSTechPOINTS scene beside it: (root, scene).
fn root_and_scene(dir: &Path, frames: u32) -> (PathBuf, PathBuf) {
    let root = dir.join("root");
    let velo = root.join("sequences/00/velodyne");
    std::fs::create_dir_all(&velo).unwrap();
    let scene = dir.join("scene");
    std::fs::create_dir_all(scene.join("label")).unwrap();
    std::fs::create_dir_all(scene.join("lidar")).unwrap();
    let scan = fixture("own_lidar/sequences/00/velodyne/000000.pcd");
    for f in 0..frames {
        std::fs::copy(&scan, velo.join(format!("{f:06}.pcd"))).unwrap();
        write_frame(&scene, f, &test_boxes(), &TYPES);
    }
    (root, scene)
}

/// Writes frame `f`'s boxes as SUSTechPOINTS does (obj_type, obj_id, psr).
fn write_frame(scene: &Path, f: u32, boxes: &[TestBox], types: &[&str]) {
    let objs: Vec<_> = (boxes.iter().enumerate())
        .map(|(i, (p, sz, r))| {
            serde_json::json!({"obj_type": types[i % types.len()], "obj_id": (i + 1).to_string(),
                "psr": {"position": obj(*p), "scale": obj(*sz), "rotation": obj(*r)}})
        })
        .collect();
    let file = scene.join(format!("label/{f:06}.json"));
    std::fs::write(file, serde_json::to_vec(&objs).unwrap()).unwrap();
}

/// Runs `label ROOT --boxes SCENE --json EXTRA`: (exit code, report, stderr).
fn label(root: &Path, scene: &Path, extra: &[&str]) -> (i32, serde_json::Value, String) {
    let mut args = vec![
        "label",
        s(root),
        "--boxes",
        s(scene),
        "--json",
        "--no-progress",
    ];
    args.extend_from_slice(extra);
    let (code, out, err) = run_text(&args);
    (code, serde_json::from_str(&out).unwrap_or_default(), err)
}

fn label_file(root: &Path, f: u32) -> PathBuf {
    root.join(format!("sequences/00/labels/{f:06}.label"))
}

fn entries(path: &Path) -> Vec<u32> {
    let b = std::fs::read(path).unwrap();
    b.chunks_exact(4)
        .map(|c| u32::from_le_bytes(c.try_into().unwrap()))
        .collect()
}

fn points() -> Vec<kitti2pgm::geom::Point3> {
    let path = fixture("own_lidar/sequences/00/velodyne/000000.pcd");
    kitti2pgm::source::read_file(&path, None).unwrap().points
}

/// Asserts a label file holds the reference's class and instance on every point off the faces.
fn assert_reference(path: &Path, boxes: &[TestBox], classes: &[u32], grow: f64) {
    let mut refs = centred_refs(boxes, rx_ry_rz);
    for r in &mut refs {
        r.grow(grow);
    }
    // Boxes of the background class label nothing (a Tram box in KITTI's rule).
    refs.retain(|r| classes[r.instance as usize - 1] != 0);
    let (want, edge) = reference(&points(), &refs);
    let got = entries(path);
    assert_eq!(
        got.len(),
        want.len(),
        "one entry per point (no point dropped here)"
    );
    let mut compared = 0;
    for k in 0..got.len() {
        if edge[k] {
            continue;
        }
        let inst = want[k] as u32;
        let class = if inst == 0 {
            0
        } else {
            classes[inst as usize - 1]
        };
        assert_eq!(got[k], class | inst << 16, "point {k}");
        compared += 1;
    }
    assert!(compared > got.len() * 99 / 100);
    assert!(want.iter().filter(|&&i| i > 0).count() > 100);
}

#[test]
fn label_writes_the_reference_labels_and_convert_takes_its_class_map() {
    let t = tmp();
    let (root, scene) = root_and_scene(t.path(), 1);
    let (code, r, err) = label(&root, &scene, &[]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(
        (r["format"].as_str(), r["class_map"].as_str()),
        (Some("sustechpoints"), Some("sustechpoints"))
    );
    assert_eq!(
        (
            r["frames_written"].as_u64(),
            r["boxes"].as_u64(),
            r["instances"].as_u64()
        ),
        (Some(1), Some(5), Some(5))
    );
    assert_reference(&label_file(&root, 0), &test_boxes(), &CLASSES, 0.0);
    // The record: the class map in full, the box file's digest, the instance table.
    let rec: serde_json::Value =
        serde_json::from_slice(&std::fs::read(root.join("sequences/00/box_labels.json")).unwrap())
            .unwrap();
    assert_eq!(rec["complete"], true);
    assert_eq!(rec["instances"][4]["object_type"], "BicycleRider");
    assert_eq!(rec["instances"][4]["class"], "rider");
    assert_eq!(rec["box_files"].as_object().unwrap().len(), 1);
    // check reads them with the recorded map too (SemanticKITTI's lists none of ids 2-5).
    let (code, out, err) = run_text(&["check", s(&root), "--only", "label-ids", "--no-progress"]);
    assert_eq!(code, 0, "{out} {err}");
    let (code, _, _) = run_text(&[
        "check",
        s(&root),
        "--class-map",
        "semantic-kitti",
        "--no-progress",
    ]);
    assert_eq!(code, 3, "with SemanticKITTI's map the ids are unknown");
    // convert reads the labels with the recorded map, unless told another.
    let out = t.path().join("out");
    let (code, j, err) = super::util::convert_json(
        &root,
        &out,
        &["--sensor", "vlp16", "--all-frames", "--cols", "1024"],
    );
    assert_eq!(code, 0, "{err}");
    let names: Vec<&str> = (j["params"]["map"]["class_map"]["classes"]
        .as_array()
        .unwrap()
        .iter())
    .map(|c| c["name"].as_str().unwrap())
    .collect();
    assert_eq!(names[..3], ["background", "car", "truck"]);
    let (code, j, _) = super::util::convert_json(
        &root,
        &t.path().join("out2"),
        &[
            "--sensor",
            "vlp16",
            "--all-frames",
            "--class-map",
            "semantic-kitti",
        ],
    );
    assert_ne!(
        code, 0,
        "the labels' raw ids are not SemanticKITTI's all: {j}"
    );
}

#[test]
fn a_rerun_rewrites_exactly_the_frames_whose_boxes_changed_and_keeps_instance_ids() {
    let t = tmp();
    let (root, scene) = root_and_scene(t.path(), 3);
    assert_eq!(label(&root, &scene, &[]).0, 0);
    let before: Vec<_> = (0..3)
        .map(|f| {
            std::fs::metadata(label_file(&root, f))
                .unwrap()
                .modified()
                .unwrap()
        })
        .collect();
    std::thread::sleep(std::time::Duration::from_millis(20));
    // Unchanged: nothing written.
    let (code, r, _) = label(&root, &scene, &[]);
    assert_eq!(
        (
            code,
            r["frames_written"].as_u64(),
            r["frames_unchanged"].as_u64()
        ),
        (0, Some(0), Some(3))
    );
    // Frame 1 gains a new object (a tool id that sorts first) and a box moves.
    let mut boxes = test_boxes();
    boxes[2].0[0] += 1.0;
    let mut objs: Vec<serde_json::Value> =
        serde_json::from_slice(&std::fs::read(scene.join("label/000001.json")).unwrap()).unwrap();
    objs[2]["psr"]["position"]["x"] = serde_json::json!(boxes[2].0[0]);
    objs.push(serde_json::json!({"obj_type": "Car", "obj_id": "0",
        "psr": {"position": obj([9.0, 9.0, 0.0]), "scale": obj([1.0; 3]), "rotation": obj([0.0; 3])}}));
    std::fs::write(
        scene.join("label/000001.json"),
        serde_json::to_vec(&objs).unwrap(),
    )
    .unwrap();
    let (code, r, err) = label(&root, &scene, &[]);
    assert_eq!(
        (
            code,
            r["frames_written"].as_u64(),
            r["frames_unchanged"].as_u64()
        ),
        (0, Some(1), Some(2)),
        "{err}"
    );
    for f in [0, 2] {
        assert_eq!(
            std::fs::metadata(label_file(&root, f))
                .unwrap()
                .modified()
                .unwrap(),
            before[f as usize]
        );
    }
    // The five tracks keep ids 1-5; the new one takes 6.
    assert_reference(&label_file(&root, 1), &boxes, &CLASSES, 0.0);
    let rec: serde_json::Value =
        serde_json::from_slice(&std::fs::read(root.join("sequences/00/box_labels.json")).unwrap())
            .unwrap();
    let new = rec["instances"]
        .as_array()
        .unwrap()
        .iter()
        .find(|e| e["track"] == "0")
        .unwrap()
        .clone();
    assert_eq!(new["instance"], 6);
}

#[test]
fn labels_that_label_did_not_write_are_refused_unless_overwrite() {
    let t = tmp();
    let (root, scene) = root_and_scene(t.path(), 2);
    let labels = root.join("sequences/00/labels");
    std::fs::create_dir_all(&labels).unwrap();
    let n = points().len();
    std::fs::write(label_file(&root, 1), vec![0u8; n * 4]).unwrap();
    let e = fails_with(&["label", s(&root), "--boxes", s(&scene)], "input");
    assert!(
        e["message"].as_str().unwrap().contains("000001.label"),
        "{e}"
    );
    assert!(!label_file(&root, 0).exists(), "nothing written");
    assert_eq!(label(&root, &scene, &["--overwrite"]).0, 0);
    // A label file edited by hand since: refused again, then replaced with --overwrite.
    std::fs::write(label_file(&root, 0), vec![1u8; n * 4]).unwrap();
    let e = fails_with(&["label", s(&root), "--boxes", s(&scene)], "input");
    assert!(e["message"].as_str().unwrap().contains("edited"), "{e}");
    assert_eq!(label(&root, &scene, &["--overwrite"]).0, 0);
    assert_reference(&label_file(&root, 0), &test_boxes(), &CLASSES, 0.0);
    // The labels a dataset ships (an unpacked nuScenes scene's) never.
    std::fs::remove_file(root.join("sequences/00/box_labels.json")).unwrap();
    std::fs::write(
        root.join("sequences/00/nuscenes.json"),
        b"{\"complete\": true}",
    )
    .unwrap();
    let e = fails_with(
        &["label", s(&root), "--boxes", s(&scene), "--overwrite"],
        "input",
    );
    assert!(
        e["message"].as_str().unwrap().contains("dataset itself"),
        "{e}"
    );
}

#[test]
fn unknown_types_are_an_error_unless_aliased_or_given_a_class() {
    let t = tmp();
    let (root, scene) = root_and_scene(t.path(), 1);
    write_frame(&scene, 0, &test_boxes(), &["Car", "Rider"]);
    let e = fails_with(&["label", s(&root), "--boxes", s(&scene)], "config");
    let m = e["message"].as_str().unwrap();
    assert!(
        m.contains("\"Rider\" (2 objects") && m.contains("BicycleRider") && m.contains("--alias"),
        "{m}"
    );
    assert!(!label_file(&root, 0).exists());
    let (code, _, err) = label(&root, &scene, &["--alias", "Rider=rider"]);
    assert_eq!(code, 0, "{err}");
    assert_reference(&label_file(&root, 0), &test_boxes(), &[1, 5, 1, 5, 1], 0.0);
    let (code, r, _) = label(&root, &scene, &["--unknown-class", "background"]);
    assert_eq!(
        (code, r["unknown_type_boxes"]["Rider"].as_u64()),
        (0, Some(2))
    );
    assert_reference(&label_file(&root, 0), &test_boxes(), &[1, 0, 1, 0, 1], 0.0);
    fails_with(
        &[
            "label",
            s(&root),
            "--boxes",
            s(&scene),
            "--alias",
            "Rider=nothing",
        ],
        "config",
    );
    fails_with(
        &[
            "label",
            s(&root),
            "--boxes",
            s(&scene),
            "--unknown-class",
            "nothing",
        ],
        "config",
    );
}

#[test]
fn a_frame_naming_a_missing_scan_fails_alone_and_stale_labels_go() {
    let t = tmp();
    let (root, scene) = root_and_scene(t.path(), 3);
    write_frame(&scene, 7, &test_boxes(), &TYPES);
    let (code, r, _) = label(&root, &scene, &[]);
    assert_eq!((code, r["frames_written"].as_u64()), (3, Some(3)));
    assert_eq!(r["failures"][0]["annotation"], "000007");
    assert!(r["failures"][0]["error"]
        .as_str()
        .unwrap()
        .contains("no scan called"));
    // A frame no longer annotated loses the labels `label` wrote for it; its scan is named.
    std::fs::remove_file(scene.join("label/000007.json")).unwrap();
    std::fs::remove_file(scene.join("label/000002.json")).unwrap();
    let (code, r, _) = label(&root, &scene, &[]);
    assert_eq!((code, r["removed"][0].as_str()), (0, Some("000002")));
    assert_eq!(r["scans_without_boxes"][0], "000002");
    assert!(!label_file(&root, 2).exists());
}

#[test]
fn an_interrupted_run_is_refused_by_convert_and_finished_by_the_next() {
    let t = tmp();
    let (root, scene) = root_and_scene(t.path(), 1);
    assert_eq!(label(&root, &scene, &[]).0, 0);
    let rec = root.join("sequences/00/box_labels.json");
    let text = std::fs::read_to_string(&rec).unwrap().replacen(
        "\"complete\": true",
        "\"complete\": false",
        1,
    );
    std::fs::write(&rec, text).unwrap();
    let out = t.path().join("out");
    fails_with(
        &[
            "convert",
            s(&root),
            "--out",
            s(&out),
            "--sensor",
            "vlp16",
            "--all-frames",
        ],
        "unfinished",
    );
    assert_eq!(label(&root, &scene, &[]).0, 0);
    let (code, _, err) =
        super::util::convert_json(&root, &out, &["--sensor", "vlp16", "--all-frames"]);
    assert_eq!(code, 0, "{err}");
    // A run killed after writing a frame's new labels: its unfinished record lists the frame as
    // pending, so the next run takes the file for its own (no --overwrite) and writes it again.
    let mut boxes = test_boxes();
    boxes[0].0[0] += 0.5;
    write_frame(&scene, 0, &boxes, &TYPES);
    let mut j: serde_json::Value = serde_json::from_slice(&std::fs::read(&rec).unwrap()).unwrap();
    j["complete"] = serde_json::json!(false);
    j["pending"] = serde_json::json!(["000000"]);
    std::fs::write(&rec, j.to_string()).unwrap();
    std::fs::write(label_file(&root, 0), vec![3u8; points().len() * 4]).unwrap();
    let (code, r, err) = label(&root, &scene, &[]);
    assert_eq!((code, r["frames_written"].as_u64()), (0, Some(1)), "{err}");
    assert_reference(&label_file(&root, 0), &boxes, &CLASSES, 0.0);
    let j: serde_json::Value = serde_json::from_slice(&std::fs::read(&rec).unwrap()).unwrap();
    assert!(j["complete"] == true && j.get("pending").is_none(), "{j}");
    // Without the pending mark, the same file is taken for a hand edit and refused.
    std::fs::write(label_file(&root, 0), vec![3u8; points().len() * 4]).unwrap();
    fails_with(&["label", s(&root), "--boxes", s(&scene)], "input");
}

/// 500 small boxes on a grid around the sensor, and a margin: the reference's labels.
#[test]
fn a_frame_of_500_boxes_and_a_margin_label_as_the_reference() {
    let t = tmp();
    let (root, scene) = root_and_scene(t.path(), 1);
    let boxes: Vec<TestBox> = (0..500)
        .map(|i| {
            let (gx, gy) = ((i % 25) as f64, (i / 25) as f64);
            (
                [gx * 1.6 - 20.0, gy * 1.6 - 16.0, -0.5],
                [1.2, 0.9, 2.0],
                [0.0, 0.1, 0.05 * gx],
            )
        })
        .collect();
    write_frame(&scene, 0, &boxes, &["Car"]);
    assert_eq!(label(&root, &scene, &[]).0, 0);
    assert_reference(&label_file(&root, 0), &boxes, &[1; 500], 0.0);
    let (code, _, err) = label(&root, &scene, &["--margin", "0.2"]);
    assert_eq!(code, 0, "{err}");
    assert_reference(&label_file(&root, 0), &boxes, &[1; 500], 0.2);
    fails_with(
        &["label", s(&root), "--boxes", s(&scene), "--margin", "-1"],
        "config",
    );
}

#[test]
fn bad_boxes_are_refused_naming_the_file_and_the_object() {
    let t = tmp();
    let (root, scene) = root_and_scene(t.path(), 1);
    let mut boxes = test_boxes();
    boxes[3].1[1] = -2.0;
    write_frame(&scene, 0, &boxes, &TYPES);
    let e = fails_with(&["label", s(&root), "--boxes", s(&scene)], "format");
    let m = e["message"].as_str().unwrap();
    assert!(m.contains("000000.json") && m.contains('4'), "{m}");
    assert!(!label_file(&root, 0).exists());
    // A box file given under another format's name says which it looks like.
    let e = fails_with(
        &[
            "label",
            s(&root),
            "--boxes",
            s(&scene),
            "--box-format",
            "supervisely",
        ],
        "input",
    );
    assert!(
        e["message"]
            .as_str()
            .unwrap()
            .contains("looks like sustechpoints"),
        "{e}"
    );
    // Labels into the box export itself: refused.
    fails_with(
        &[
            "label",
            s(&root),
            "--boxes",
            s(&root.join("sequences/00/labels")),
        ],
        "output_over_input",
    );
}

/// `check` on a labelled root reads its box export again and runs the box checks on it: a box
/// that jumps between frames, a heading that flips, sizes, overlaps, and boxes that hold no
/// point (all of them, when the boxes are in another frame than the scans').
#[test]
fn check_runs_the_box_checks_on_imported_boxes() {
    let t = tmp();
    let (root, scene) = root_and_scene(t.path(), 3);
    let mut boxes = test_boxes();
    boxes[2].0[0] += 6.0; // track 3 jumps 6 m at frame 1 and back at frame 2
    boxes[4].2[2] += 2.5; // track 5 turns 2.5 rad at frame 1
    write_frame(&scene, 1, &boxes, &TYPES);
    assert_eq!(label(&root, &scene, &[]).0, 0);
    let (code, out, err) = run_text(&["check", s(&root), "--json", "--no-progress"]);
    assert_eq!(code, 3, "{err}");
    let j: serde_json::Value = serde_json::from_str(&out).unwrap();
    let findings = j["findings"].as_array().unwrap();
    let of = |check: &str| -> Vec<&serde_json::Value> {
        findings.iter().filter(|f| f["check"] == check).collect()
    };
    let jump = of("pose-jump");
    assert_eq!(jump.len(), 1, "{jump:?}");
    assert_eq!(jump[0]["object"]["kind"], "Truck (3)");
    assert!(jump[0]["file"]
        .as_str()
        .unwrap()
        .ends_with("label/000000.json"));
    assert_eq!(jump[0]["frame"], 1);
    let flip = of("yaw-flip");
    assert_eq!(flip[0]["object"]["kind"], "BicycleRider (5)", "{flip:?}");
    assert!(of("box-size")
        .iter()
        .any(|f| f["object"]["kind"] == "Car (4)"));
    assert!(of("box-overlap").iter().any(|f| f["frame"] == 0));
    assert!(of("empty-box").is_empty(), "the boxes hold points");
    // A track in front of the sensor, annotated in frames 0 and 1 and not 2, on scans that do
    // not change: its box carried on still holds its points.
    let mut front = test_boxes();
    front.push(([1.6, 0.0, 0.0], [1.6, 2.4, 3.0], [0.0, 0.0, 0.0]));
    let types = ["Car", "Pedestrian", "Truck", "Car", "BicycleRider", "Car"];
    for f in 0..2 {
        let mut b = front.clone();
        if f == 1 {
            b[2].0[0] += 6.0;
            b[4].2[2] += 2.5;
        }
        write_frame(&scene, f, &b, &types);
    }
    assert_eq!(label(&root, &scene, &[]).0, 0);
    let (_, out, _) = run_text(&["check", s(&root), "--json", "--no-progress"]);
    let j: serde_json::Value = serde_json::from_str(&out).unwrap();
    let ends: Vec<_> = (j["findings"].as_array().unwrap().iter())
        .filter(|f| f["check"] == "annotation-ends")
        .collect();
    assert_eq!(ends.len(), 1, "{ends:?}");
    assert_eq!(
        (
            ends[0]["frame"].as_u64(),
            ends[0]["object"]["kind"].as_str()
        ),
        (Some(2), Some("Car (6)"))
    );
    assert!(ends[0]["file"]
        .as_str()
        .unwrap()
        .ends_with("label/000002.json"));
    // Boxes 20 m off, where the scan has no point: every box is empty, and one error says why.
    let far: Vec<TestBox> = (test_boxes().into_iter())
        .map(|(c, sz, r)| ([c[0] + 20.0, c[1], c[2]], sz, r))
        .collect();
    for f in 0..3 {
        write_frame(&scene, f, &far, &TYPES);
    }
    assert_eq!(label(&root, &scene, &[]).0, 0);
    let (_, out, _) = run_text(&["check", s(&root), "--json", "--no-progress"]);
    let j: serde_json::Value = serde_json::from_str(&out).unwrap();
    let empty: Vec<_> = (j["findings"].as_array().unwrap().iter())
        .filter(|f| f["check"] == "empty-box")
        .collect();
    assert_eq!(
        empty.len(),
        6,
        "each of the 5 tracks (frames 0-2) and the summary"
    );
    assert!(empty
        .iter()
        .any(|f| f["severity"] == "error"
            && f["message"].as_str().unwrap().contains("another frame")));
}

/// `convert --viz` of a labelled root carries the imported boxes as Foxglove cubes (the boxes
/// of a class, with the instance ids of the label files); a changed export reconverts.
#[test]
fn viz_shards_carry_the_imported_boxes() {
    use foxglove::schemas::SceneUpdate;
    use kitti2pgm::format::shard::Shard;
    use prost::Message as _;
    let t = tmp();
    let (root, scene) = root_and_scene(t.path(), 2);
    assert_eq!(label(&root, &scene, &[]).0, 0);
    let out = t.path().join("out");
    let args = [
        "--sensor",
        "vlp16",
        "--all-frames",
        "--format",
        "mcap",
        "--viz",
    ];
    let (code, _, err) = super::util::convert_json(&root, &out, &args);
    assert_eq!(code, 0, "{err}");
    let cubes = |out: &Path| -> Vec<usize> {
        let mut n = Vec::new();
        for e in std::fs::read_dir(out.join("shards")).unwrap() {
            let shard = Shard::open(&e.unwrap().path()).unwrap();
            for m in mcap::MessageStream::new(shard.bytes()).unwrap() {
                let m = m.unwrap();
                if m.channel.topic == "/kitti2pgm/viz/boxes" {
                    let v = SceneUpdate::decode(&m.data[..]).unwrap();
                    n.push(v.entities.iter().map(|e| e.cubes.len()).sum());
                }
            }
        }
        n
    };
    assert_eq!(cubes(&out), [5, 5]);
    // Frame 1 loses two boxes: label, then convert again: its shard follows.
    write_frame(&scene, 1, &test_boxes()[..3], &TYPES);
    assert_eq!(label(&root, &scene, &[]).0, 0);
    let (code, j, err) = super::util::convert_json(&root, &out, &args);
    assert_eq!(code, 0, "{err}");
    assert!(
        j["reconverted"].as_u64().unwrap_or(0) >= 1 || j["frames_converted"].as_u64().unwrap() >= 1,
        "{j}"
    );
    assert_eq!(cubes(&out), [5, 3]);
}

/// `preview` of a labelled root draws each labelled scan from above in its classes' colours,
/// with its boxes.
#[test]
fn preview_draws_each_labelled_frame_with_its_boxes() {
    let t = tmp();
    let (root, scene) = root_and_scene(t.path(), 2);
    assert_eq!(label(&root, &scene, &[]).0, 0);
    let pics = t.path().join("pics");
    let (code, _, err) = run_text(&["preview", s(&root), "--out", s(&pics), "--no-progress"]);
    assert_eq!(code, 0, "{err}");
    let img = kitti2pgm::raster::read(&pics.join("00_000001.png")).unwrap();
    assert_eq!((img.width(), img.height()), (800, 800));
    // The truck's colour (SUSTechPOINTS' map: [80, 30, 180]) is on its points and outline.
    let truck = (0..800 * 800)
        .filter(|i| img.get_pixel(i % 800, i / 800).0 == [90, 90, 180])
        .count();
    assert!(truck > 50, "{truck} pixels of the truck's outline colour");
    assert!(pics.join("00_000000.png").is_file());
}

/// Segments.ai's point cloud segmentation labels (each point's object id) map straight to the
/// label file: every point's class and instance as the file says, through the class map; a
/// label of another point count fails its frame alone.
#[test]
fn segments_ai_point_annotations_become_the_label_file() {
    let t = tmp();
    let (root, _) = root_and_scene(t.path(), 2);
    let pts = points();
    let ids: Vec<u32> = (pts.iter())
        .map(|p| match (p.x > 0.0 && p.y > 0.0, p.x < -3.0) {
            (true, _) => 7,
            (_, true) => 9,
            _ => 0,
        })
        .collect();
    let sample = |name: &str, ids: &[u32]| {
        serde_json::json!({"name": name, "attributes": {"pcd": {"url": format!("https://x/{name}.pcd"), "type": "pcd"}},
            "labels": {"ground-truth": {"attributes": {"format_version": "0.1",
                "annotations": [{"id": 7, "category_id": 1}, {"id": 9, "category_id": 2}],
                "point_annotations": ids}}}})
    };
    let release = serde_json::json!({"dataset": {"name": "own", "task_type": "pointcloud-segmentation",
        "task_attributes": {"categories": [{"id": 1, "name": "car"}, {"id": 2, "name": "person"}]},
        "samples": [sample("000000", &ids), sample("000001", &ids[1..])]}});
    let file = t.path().join("release.json");
    std::fs::write(&file, release.to_string()).unwrap();
    let map = t.path().join("map.yaml");
    std::fs::write(&map, "name: own\nclasses:\n  - {name: background}\n  - {name: car, types: [car]}\n  - {name: pedestrian, types: [person]}\n").unwrap();
    let (code, r, err) = label(&root, &file, &["--class-map", s(&map)]);
    assert_eq!(code, 3, "{err}");
    assert_eq!(r["failures"][0]["annotation"], "000001");
    assert!(
        r["failures"][0]["error"]
            .as_str()
            .unwrap()
            .contains("point annotations"),
        "{r}"
    );
    let got = entries(&label_file(&root, 0));
    let want: Vec<u32> = (ids.iter())
        .map(|&id| match id {
            7 => 1 | 1 << 16,
            9 => 2 | 2 << 16,
            _ => 0,
        })
        .collect();
    assert_eq!(got, want);
    assert!(ids.iter().filter(|&&i| i == 7).count() > 100 && ids.contains(&9));
}
