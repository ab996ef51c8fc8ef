//! nuScenes: `unpack` of a nuScenes root (its devkit's layout: tables, samples/LIDAR_TOP,
//! lidarseg) into sequences, then `convert --sensor hdl32e --class-map nuscenes`. The root is
//! made here around the real LIDAR_TOP keyframe of `fixtures/lidars/nuscenes` (no labelled
//! keyframe is public in a size to carry: its labels are made by region, one uint8 per point).

use std::path::{Path, PathBuf};

use serde_json::json;

use super::util::{convert_json, run_text, s, tmp};

const SCAN: &str = "n015-2018-07-24-11-22-45+0800__LIDAR_TOP__1532402927647951.pcd.bin";

/// The general class of a point by region: driveable surface below the sensor, cars ahead on the
/// left, manmade elsewhere, noise on every 97th point.
fn general_class(i: usize, x: f32, y: f32, z: f32) -> u8 {
    match () {
        _ if i.is_multiple_of(97) => 0,
        _ if z < -1.5 => 24,
        _ if x > 0.0 && y > 0.0 => 17,
        _ => 28,
    }
}

/// A nuScenes root: scene-0061 with two LIDAR_TOP keyframes (listed out of time order, the
/// second without labels), scene-1077 with one; a sweep and a camera keyframe that are not
/// frames. Returns the root and the labels of the real scan.
fn nuscenes_root(dir: &Path) -> (PathBuf, Vec<u8>) {
    let root = dir.join("nuscenes");
    let scan = super::util::fixture(&format!("lidars/nuscenes/{SCAN}"));
    let bytes = std::fs::read(&scan).unwrap();
    std::fs::create_dir_all(root.join("samples/LIDAR_TOP")).unwrap();
    std::fs::create_dir_all(root.join("lidarseg/v1.0-mini")).unwrap();
    std::fs::create_dir_all(root.join("v1.0-mini")).unwrap();
    let names = ["a", "b", "c"].map(|k| format!("scan-{k}__LIDAR_TOP__{k}.pcd.bin"));
    for n in &names {
        std::fs::write(root.join("samples/LIDAR_TOP").join(n), &bytes).unwrap();
    }
    let labels: Vec<u8> = bytes
        .chunks_exact(20)
        .enumerate()
        .map(|(i, p)| {
            let f = |k: usize| f32::from_le_bytes(p[4 * k..4 * k + 4].try_into().unwrap());
            general_class(i, f(0), f(1), f(2))
        })
        .collect();
    for t in ["sd-a", "sd-c"] {
        std::fs::write(
            root.join(format!("lidarseg/v1.0-mini/{t}_lidarseg.bin")),
            &labels,
        )
        .unwrap();
    }
    let table = |name: &str, v: serde_json::Value| {
        std::fs::write(root.join("v1.0-mini").join(name), v.to_string()).unwrap()
    };
    table(
        "scene.json",
        json!([{"token": "s1077", "name": "scene-1077"}, {"token": "s61", "name": "scene-0061"}]),
    );
    table(
        "sample.json",
        json!([{"token": "a", "scene_token": "s61"}, {"token": "b", "scene_token": "s61"},
               {"token": "c", "scene_token": "s1077"}]),
    );
    let sd = |token: &str, sample: &str, file: &str, key: bool, t: i64| {
        json!({"token": token, "sample_token": sample, "filename": file, "is_key_frame": key,
               "timestamp": t, "fileformat": "pcd", "prev": "", "next": ""})
    };
    table(
        "sample_data.json",
        json!([
            sd(
                "sd-b",
                "b",
                &format!("samples/LIDAR_TOP/{}", names[1]),
                true,
                1_532_402_928_147_951
            ),
            sd(
                "sd-a",
                "a",
                &format!("samples/LIDAR_TOP/{}", names[0]),
                true,
                1_532_402_927_647_951
            ),
            sd(
                "sd-sweep",
                "a",
                "sweeps/LIDAR_TOP/x.pcd.bin",
                false,
                1_532_402_927_700_000
            ),
            sd(
                "sd-cam",
                "a",
                "samples/CAM_FRONT/x.jpg",
                true,
                1_532_402_927_647_951
            ),
            sd(
                "sd-c",
                "c",
                &format!("samples/LIDAR_TOP/{}", names[2]),
                true,
                1_533_000_000_000_000
            ),
        ]),
    );
    table(
        "lidarseg.json",
        json!([{"token": "l1", "sample_data_token": "sd-a", "filename": "lidarseg/v1.0-mini/sd-a_lidarseg.bin"},
               {"token": "l2", "sample_data_token": "sd-c", "filename": "lidarseg/v1.0-mini/sd-c_lidarseg.bin"}]),
    );
    let categories: Vec<_> = ["noise", "animal", "human.pedestrian.adult"]
        .iter()
        .enumerate()
        .map(|(i, n)| json!({"token": format!("c{i}"), "name": n, "description": "", "index": i}))
        .collect();
    table("category.json", json!(categories));
    (root, labels)
}

fn unpack(args: &[&str]) -> (i32, serde_json::Value, String) {
    let mut a = vec!["unpack", "--json", "--no-progress"];
    a.extend_from_slice(args);
    let (code, out, err) = run_text(&a);
    (code, serde_json::from_str(&out).unwrap_or_default(), err)
}

#[test]
fn a_nuscenes_root_unpacks_one_sequence_a_scene_and_converts_with_its_16_classes() {
    let t = tmp();
    let (root, labels) = nuscenes_root(t.path());
    let (code, list, err) = unpack(&[s(&root), "--list"]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(
        list,
        json!([
            {"scene": "scene-0061", "sequence": "61", "keyframes": 2, "labelled": 1},
            {"scene": "scene-1077", "sequence": "1077", "keyframes": 1, "labelled": 1},
        ])
    );
    // Given to convert as it is, the root is named with the command that makes it readable.
    let (code, _, err) = run_text(&["convert", s(&root), "--out", s(&t.path().join("x"))]);
    assert_eq!(code, 1);
    assert!(
        err.contains("a nuScenes root") && err.contains("kitti2pgm unpack"),
        "{err}"
    );
    let out = t.path().join("root");
    let (code, j, err) = unpack(&[s(&root), "--out", s(&out)]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(
        (j["frames_written"].as_u64(), j["labelled_frames"].as_u64()),
        (Some(3), Some(2))
    );
    // In time order: frame 0 is sd-a (labelled), frame 1 sd-b.
    let seq = out.join("sequences/61");
    let index: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(seq.join("nuscenes.json")).unwrap()).unwrap();
    assert_eq!(index["tokens"], json!(["sd-a", "sd-b"]));
    assert_eq!(
        std::fs::read_to_string(seq.join("times.txt")).unwrap(),
        "0.000000000\n0.500000000\n"
    );
    let scan = std::fs::read(super::util::fixture(&format!("lidars/nuscenes/{SCAN}"))).unwrap();
    assert_eq!(
        std::fs::read(seq.join("velodyne/000000.pcd.bin")).unwrap(),
        scan
    );
    let raw = std::fs::read(seq.join("labels/000000.label")).unwrap();
    let raw: Vec<u32> = raw
        .chunks_exact(4)
        .map(|b| u32::from_le_bytes(b.try_into().unwrap()))
        .collect();
    assert_eq!(
        raw,
        labels.iter().map(|&c| u32::from(c)).collect::<Vec<_>>()
    );
    assert!(!seq.join("labels/000001.label").exists());
    assert!(out.join("sequences/1077/velodyne/000000.pcd.bin").is_file());
    // convert: rows from the ring index (HDL-32E), the benchmark's classes.
    let conv = t.path().join("conv");
    let (code, j, err) = convert_json(
        &out,
        &conv,
        &[
            "--sensor",
            "hdl32e",
            "--class-map",
            "nuscenes",
            "--all-frames",
            "--cols",
            "1024",
        ],
    );
    assert_eq!(code, 0, "{err}");
    assert_eq!(j["frames_converted"], 3);
    assert_eq!(j["ring_field_frames"], 3);
    assert_eq!(j["params"]["map"]["class_map"]["name"], "nuscenes");
    let expect = |general: u8| labels.iter().filter(|&&c| c == general).count() as u64;
    let point_classes = &j["labelled_points"];
    assert_eq!(
        point_classes["car"].as_u64().or(point_classes[4].as_u64()),
        Some(2 * expect(17)),
        "{j}"
    );
    assert!(conv.join("lidar_2d/1077_000000.npy").is_file());
    // check knows the layout, the sensor and the class map: no error.
    let (code, stdout, err) = run_text(&[
        "check",
        s(&out),
        "--sensor",
        "hdl32e",
        "--class-map",
        "nuscenes",
        "--json",
        "--no-progress",
    ]);
    assert_eq!(code, 0, "{err}");
    let check: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    let findings = check["findings"].as_array().unwrap();
    assert!(findings.iter().all(|f| f["severity"] != "error"), "{check}");
    let (code, stdout, err) = run_text(&["stats", s(&conv), "--json", "--no-progress"]);
    assert_eq!(code, 0, "{err}");
    let stats: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(stats["class_map"]["name"], "nuscenes");
    // A re-run into the same root is refused without --overwrite, and keeps everything.
    let (code, _, err) = unpack(&[s(&root), "--out", s(&out)]);
    assert_eq!(code, 1);
    assert!(err.contains("--overwrite"), "{err}");
    let (code, j, err) = unpack(&[
        s(&root),
        "--out",
        s(&out),
        "--overwrite",
        "--scenes",
        "scene-0061",
    ]);
    assert_eq!((code, j["frames_written"].as_u64()), (0, Some(2)), "{err}");
}

#[test]
fn bad_nuscenes_roots_are_named_and_a_bad_frame_fails_alone() {
    let t = tmp();
    let (root, labels) = nuscenes_root(t.path());
    // A lidarseg file of the wrong length fails its frame; the other frames are written.
    std::fs::write(
        root.join("lidarseg/v1.0-mini/sd-c_lidarseg.bin"),
        &labels[..100],
    )
    .unwrap();
    let out = t.path().join("root");
    let (code, j, _) = unpack(&[s(&root), "--out", s(&out)]);
    assert_eq!((code, j["frames_written"].as_u64()), (3, Some(2)));
    let f = &j["failures"][0];
    assert_eq!(
        (f["scene"].as_str(), f["frame"].as_u64()),
        (Some("scene-1077"), Some(0))
    );
    assert!(
        f["error"].as_str().unwrap().contains("sd-c_lidarseg.bin"),
        "{f}"
    );
    assert!(!out.join("sequences/1077/velodyne/000000.pcd.bin").exists());
    // An unknown scene.
    let (code, _, err) = unpack(&[
        s(&root),
        "--out",
        s(&t.path().join("o2")),
        "--scenes",
        "scene-9999",
    ]);
    assert_eq!(code, 1);
    assert!(err.contains("scene-9999"), "{err}");
    // Two versions and none named.
    std::fs::create_dir_all(root.join("v1.0-test")).unwrap();
    std::fs::write(root.join("v1.0-test/sample_data.json"), "[]").unwrap();
    let (code, _, err) = unpack(&[s(&root), "--list"]);
    assert_eq!(code, 1);
    assert!(
        err.contains("v1.0-mini, v1.0-test") && err.contains("--nuscenes-version"),
        "{err}"
    );
    // A category list that is not nuScenes-lidarseg's general classes.
    let cats = json!([{"token": "c", "name": "vehicle.car", "description": "", "index": 1}]);
    std::fs::write(root.join("v1.0-mini/category.json"), cats.to_string()).unwrap();
    let (code, _, err) = unpack(&[s(&root), "--list", "--nuscenes-version", "v1.0-mini"]);
    assert_eq!(code, 1);
    assert!(
        err.contains("category.json") && err.contains("vehicle.car"),
        "{err}"
    );
    // A broken table.
    std::fs::write(root.join("v1.0-mini/sample.json"), "[{\"token\": ").unwrap();
    let (code, _, err) = unpack(&[s(&root), "--list", "--nuscenes-version", "v1.0-mini"]);
    assert_eq!(code, 1);
    assert!(err.contains("sample.json"), "{err}");
}

/// The files of a sequence folder: name -> (inode, bytes), to compare two unpacks.
fn sequence_files(seq: &Path) -> Vec<(String, Vec<u8>)> {
    super::util::tree_bytes(seq)
        .into_iter()
        .filter(|(n, _)| !n.ends_with("nuscenes.json"))
        .collect()
}

/// Issue 47, defect 6: `--overwrite` onto an earlier unpack leaves exactly what a fresh unpack
/// leaves (no `.link-tmp` names: a rename of a link onto another link of the same file does
/// nothing), also after the keyframes' order changed, and never leaves a scan beside another
/// scan's labels; then defect 9: an output inside the dataset's own `samples/LIDAR_TOP`, reached
/// through the hard links, is refused.
#[test]
fn an_overwrite_leaves_what_a_fresh_unpack_leaves() {
    let t = tmp();
    let (root, _) = nuscenes_root(t.path());
    let out = t.path().join("out");
    let fresh = t.path().join("fresh");
    for _ in 0..3 {
        let (code, j, err) = unpack(&[s(&root), "--out", s(&out), "--overwrite"]);
        assert_eq!(code, 0, "{err} {j}");
        let left: Vec<_> = super::util::tree_bytes(&out)
            .into_iter()
            .filter(|(n, _)| n.contains("link-tmp"))
            .map(|(n, _)| n)
            .collect();
        assert!(left.is_empty(), "{left:?}");
    }
    // The keyframes' order changes: a (labelled) and b (not) swap their times, so frame 0 is
    // now b's scan, which has no labels: a's labels must not stay beside it.
    let table = root.join("v1.0-mini/sample_data.json");
    let text = std::fs::read_to_string(&table).unwrap();
    let swapped = text
        .replace("1532402928147951", "X")
        .replace("1532402927647951", "1532402928147951")
        .replace("X", "1532402927647951");
    std::fs::write(&table, swapped).unwrap();
    let (code, j, err) = unpack(&[s(&root), "--out", s(&out), "--overwrite"]);
    assert_eq!(code, 0, "{err} {j}");
    let (code, _, err) = unpack(&[s(&root), "--out", s(&fresh)]);
    assert_eq!(code, 0, "{err}");
    for seq in ["sequences/61", "sequences/1077"] {
        assert_eq!(
            sequence_files(&out.join(seq)),
            sequence_files(&fresh.join(seq)),
            "{seq}"
        );
    }
    assert!(!out.join("sequences/61/labels/000000.label").exists());
    assert!(out.join("sequences/61/labels/000001.label").exists());
    // An output in the dataset's own folder, known to the converted root only by the links.
    let inside = root.join("samples/LIDAR_TOP/converted");
    let v = super::util::fails_with(
        &[
            "convert",
            s(&out),
            "--out",
            s(&inside),
            "--sensor",
            "hdl32e",
            "--class-map",
            "nuscenes",
        ],
        "output_over_input",
    );
    assert_eq!(v["exit"], 2, "{v}");
    assert!(!inside.exists());
}

/// Issue 47, defect 8: an unpack that did not finish (its `nuscenes.json` still says
/// `complete: false`, as a kill leaves it) is refused by convert, check and split, and a run of
/// unpack again makes it whole.
#[test]
fn an_unfinished_unpack_is_refused_until_it_is_run_again() {
    let t = tmp();
    let (root, _) = nuscenes_root(t.path());
    let out = t.path().join("out");
    let (code, _, err) = unpack(&[s(&root), "--out", s(&out)]);
    assert_eq!(code, 0, "{err}");
    let index = out.join("sequences/61/nuscenes.json");
    let mut j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&index).unwrap()).unwrap();
    assert_eq!(j["complete"], true);
    j["complete"] = json!(false);
    std::fs::write(&index, j.to_string()).unwrap();
    let conv = t.path().join("conv");
    for args in [
        vec!["convert", s(&out), "--out", s(&conv), "--sensor", "hdl32e"],
        vec!["check", s(&out)],
        vec!["split", s(&out), "--out", s(&conv)],
    ] {
        let v = super::util::fails_with(&args, "unfinished");
        let m = v["message"].as_str().unwrap();
        assert!(
            m.contains("nuscenes.json") && m.contains("--overwrite"),
            "{m}"
        );
    }
    assert!(!conv.join("lidar_2d").exists());
    let (code, _, err) = unpack(&[s(&root), "--out", s(&out), "--overwrite"]);
    assert_eq!(code, 0, "{err}");
    let (code, _, err) = convert_json(
        &out,
        &conv,
        &[
            "--sensor",
            "hdl32e",
            "--all-frames",
            "--class-map",
            "nuscenes",
        ],
    );
    assert_eq!(code, 0, "{err}");
}

/// Issue 49: each kind of recording takes its own options; the other kind's are refused by
/// name before anything is written.
#[test]
fn each_recording_refuses_the_other_kind_s_options() {
    let t = tmp();
    let (root, _) = nuscenes_root(t.path());
    let out = t.path().join("out");
    for (flag, value) in [
        ("--topic", "/points"),
        ("--sequence", "3"),
        ("--sensor-frame", "lidar"),
    ] {
        let (code, _, err) = unpack(&[s(&root), "--out", s(&out), flag, value]);
        assert_eq!(code, 1, "{flag}");
        assert!(err.contains(&format!("{flag} is for bags")), "{err}");
    }
    let bag = super::util::fixture("own_lidar_bag");
    for (flag, value) in [
        ("--scenes", "scene-0061"),
        ("--nuscenes-version", "v1.0-mini"),
    ] {
        let (code, _, err) = unpack(&[s(&bag), "--out", s(&out), flag, value]);
        assert_eq!(code, 1, "{flag}");
        assert!(
            err.contains(&format!("{flag} is for a nuScenes root")),
            "{err}"
        );
    }
    assert!(!out.exists());
}
