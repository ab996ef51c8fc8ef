//! Provenance of the inputs (issue 26): a re-run keeps a frame only when every file it was made
//! from is as it was; each test is named after the defect it guards against, on real data.

use std::path::Path;

use crate::util::*;

const D1: &str = "2011_09_26/2011_09_26_drive_0001_sync";
const D52: &str = "2011_09_26/2011_09_26_drive_0052_sync";

/// The per-frame outputs of a convert folder (`lidar_2d`, `labels`).
fn outputs(out: &Path) -> Vec<(String, Vec<u8>)> {
    let mut v = tree_bytes(&out.join("lidar_2d"));
    v.extend(tree_bytes(&out.join("labels")));
    v
}

/// Converts `root` into `out`; the summary JSON (exit 0 asserted).
fn convert_ok(root: &Path, out: &Path, extra: &[&str]) -> serde_json::Value {
    let (code, j, e) = convert_json(root, out, extra);
    assert_eq!(code, 0, "{e}");
    j
}

/// A re-run of `root` into `out` converts again exactly what a fresh conversion of the changed
/// data writes: `changed` frames for an input change, the rest kept.
fn rerun_matches_fresh(root: &Path, out: &Path, extra: &[&str], changed: u64) -> serde_json::Value {
    let j = convert_ok(root, out, extra);
    assert_eq!(j["reconverted"]["input changed"], changed, "{j}");
    assert_eq!(j["frames_converted"], changed, "{j}");
    let fresh = out.with_file_name("fresh");
    let _ = std::fs::remove_dir_all(&fresh);
    convert_ok(root, &fresh, extra);
    assert_eq!(
        outputs(out),
        outputs(&fresh),
        "re-run equals a fresh conversion"
    );
    j
}

#[test]
fn a_fixed_tracklet_file_reconverts_its_drives_frames() {
    let t = tmp();
    let root = fixture_copy(t.path());
    let out = t.path().join("out");
    convert_ok(&root, &out, &[]);
    let xml = root.join(D1).join("tracklet_labels.xml");
    let text = std::fs::read_to_string(&xml).unwrap();
    std::fs::write(
        &xml,
        text.replace("<objectType>Car<", "<objectType>Pedestrian<"),
    )
    .unwrap();
    let j = rerun_matches_fresh(&root, &out, &[], 2);
    assert_eq!(j["resumed_frames"], 1, "drive 0052's frame kept: {j}");
    let changed = j["changed_inputs"].as_array().unwrap();
    assert_eq!(changed.len(), 1, "{j}");
    let c = changed[0].as_str().unwrap();
    assert!(c.starts_with(&format!("{D1}/tracklet_labels.xml: ")), "{c}");
}

#[test]
fn a_scan_replaced_by_one_of_the_same_size_is_reconverted() {
    let t = tmp();
    let root = fixture_copy(t.path());
    let out = t.path().join("out");
    convert_ok(&root, &out, &[]);
    // The scan mirrored (y negated): same size, other content; its mtime set back.
    let bin = root.join(D52).join("velodyne_points/data/0000000000.bin");
    let before = std::fs::metadata(&bin).unwrap().modified().unwrap();
    let mut bytes = std::fs::read(&bin).unwrap();
    for p in bytes.chunks_exact_mut(16) {
        p[7] ^= 0x80;
    }
    std::fs::write(&bin, &bytes).unwrap();
    std::fs::File::options()
        .write(true)
        .open(&bin)
        .unwrap()
        .set_modified(before)
        .unwrap();
    let j = rerun_matches_fresh(&root, &out, &[], 1);
    assert_eq!(
        j["changed_inputs"][0],
        format!("{D52}/velodyne_points/data/0000000000.bin: content changed")
    );
}

#[test]
fn an_edited_calibration_reconverts_the_frames_that_use_it() {
    let t = tmp();
    let root = fixture_copy(t.path());
    let (rgb, plain) = (t.path().join("rgb"), t.path().join("plain"));
    convert_ok(&root, &rgb, &["--rgb"]);
    convert_ok(&root, &plain, &[]);
    let calib = root.join("2011_09_26/calib_velo_to_cam.txt");
    let text = std::fs::read_to_string(&calib).unwrap();
    let edited: String = text
        .lines()
        .map(|l| match l.strip_prefix("T: ") {
            Some(_) => "T: -4.069766e-03 -1.763162e-01 -2.717806e-01".to_string(),
            None => l.to_string(),
        })
        .collect::<Vec<_>>()
        .join("\n");
    assert_ne!(edited.trim(), text.trim());
    std::fs::write(&calib, edited + "\n").unwrap();
    // Colour samples the camera through it: every frame again.
    rerun_matches_fresh(&root, &rgb, &["--rgb"], 3);
    // Without colour the calibration is not an input: nothing again.
    let j = convert_ok(&root, &plain, &[]);
    assert_eq!(j["resumed_frames"], 3, "{j}");
    assert_eq!(j["frames_converted"], 0, "{j}");
}

#[test]
fn a_touched_but_unchanged_input_keeps_its_frame() {
    let t = tmp();
    let root = fixture_copy(t.path());
    let out = t.path().join("out");
    convert_ok(&root, &out, &[]);
    let bin = root.join(D52).join("velodyne_points/data/0000000000.bin");
    let bytes = std::fs::read(&bin).unwrap();
    std::fs::write(&bin, bytes).unwrap();
    let j = convert_ok(&root, &out, &[]);
    assert_eq!(j["resumed_frames"], 3, "{j}");
    assert_eq!(j["reconverted"], serde_json::json!({}), "{j}");
}

#[test]
fn another_root_with_the_same_drive_names_is_never_resumed() {
    let t = tmp();
    let a = fixture_copy(&t.path().join("a"));
    let b = fixture_copy(&t.path().join("b"));
    let out = t.path().join("out");
    convert_ok(&a, &out, &[]);
    let j = convert_ok(&b, &out, &[]);
    assert_eq!(j["resumed_frames"], 0, "{j}");
    assert_eq!(j["restarted"], "dataset root changed", "{j}");
    assert_eq!(j["stale_removed"], 6, "3 maps and 3 label files: {j}");
    // The journal records the root.
    let journal = std::fs::read_to_string(out.join(".kitti2pgm-frames")).unwrap();
    let root_line = journal.lines().nth(1).unwrap();
    let recorded: String = serde_json::from_str(root_line.strip_prefix("root ").unwrap()).unwrap();
    assert_eq!(Path::new(&recorded), b.canonicalize().unwrap());
}

#[test]
fn a_label_file_that_appears_is_an_input_change() {
    let t = tmp();
    let root = copy_of("kitti_object", t.path());
    let out = t.path().join("out");
    let label = root.join("training/label_2/000001.txt");
    let kept = t.path().join("000001.txt");
    std::fs::rename(&label, &kept).unwrap();
    let j = convert_ok(&root, &out, &[]);
    assert_eq!(j["frames_without_labels"], 1, "{j}");
    std::fs::rename(&kept, &label).unwrap();
    let j = rerun_matches_fresh(&root, &out, &[], 1);
    assert_eq!(
        j["changed_inputs"][0],
        "training/label_2/000001.txt: appeared"
    );
}

#[test]
fn a_frame_whose_scan_went_loses_its_outputs() {
    let t = tmp();
    let root = fixture_copy(t.path());
    let out = t.path().join("out");
    convert_ok(&root, &out, &[]);
    std::fs::remove_file(root.join(D52).join("velodyne_points/data/0000000000.bin")).unwrap();
    let j = convert_ok(&root, &out, &[]);
    assert_eq!(j["stale_removed"], 2, "its map and label file: {j}");
    assert!(!out.join("lidar_2d/2011_09_26_0052_0000000000.npy").exists());
    let journal = std::fs::read_to_string(out.join(".kitti2pgm-frames")).unwrap();
    assert!(!journal.contains("2011_09_26_0052_0000000000"), "{journal}");
}

#[test]
fn shards_are_rewritten_when_an_input_of_theirs_changes() {
    let t = tmp();
    let root = fixture_copy(t.path());
    let out = t.path().join("out");
    let args = ["--format", "mcap,points", "--val-drives", "0052"];
    convert_ok(&root, &out, &args);
    let j = convert_ok(&root, &out, &args);
    assert_eq!(j["shards_written"], 0, "all kept: {j}");
    let bin = root.join(D52).join("velodyne_points/data/0000000000.bin");
    let mut bytes = std::fs::read(&bin).unwrap();
    bytes[3] ^= 0x01;
    std::fs::write(&bin, &bytes).unwrap();
    let j = convert_ok(&root, &out, &args);
    assert_eq!(j["reconverted"]["input changed"], 1, "{j}");
    // The val shards (maps and points) are written again, the train shards kept.
    assert_eq!(j["shards_written"], 2, "{j}");
    assert_eq!(j["shards_skipped"], 2, "{j}");
    let fresh = t.path().join("fresh");
    convert_ok(&root, &fresh, &args);
    for kind in ["shards", "points"] {
        assert_eq!(
            tree_bytes(&out.join(kind)),
            tree_bytes(&fresh.join(kind)),
            "{kind}"
        );
    }
}

#[test]
fn a_journal_of_an_earlier_version_restarts_the_folder() {
    let t = tmp();
    let out = t.path().join("out");
    convert_fixtures(&out, &["--fov-deg", "360"]);
    // Version 1: the parameters, then bare frame ids (no root, no inputs).
    let path = out.join(".kitti2pgm-frames");
    let text = std::fs::read_to_string(&path).unwrap();
    let params = text.lines().next().unwrap().split_once(' ').unwrap().1;
    let mut v1 = format!("kitti2pgm-frames/1 {params}\n");
    for l in text.lines().skip(2) {
        v1.push_str(l.split_once(' ').unwrap().0);
        v1.push('\n');
    }
    std::fs::write(&path, v1).unwrap();
    let j = convert_ok(&fixtures(), &out, &["--fov-deg", "360"]);
    assert_eq!(
        j["restarted"], "journal without inputs (older version)",
        "{j}"
    );
    assert_eq!(j["resumed_frames"], 0, "{j}");
    assert_eq!(j["frames_converted"], 3, "{j}");
}
