//! Bad input: each gets an error naming the file; the rest of the batch is converted; the exit
//! status is 3 when a frame failed.

use std::path::{Path, PathBuf};

use crate::util::*;

const D1: &str = "2011_09_26/2011_09_26_drive_0001_sync";
const D52: &str = "2011_09_26/2011_09_26_drive_0052_sync";

fn failures(j: &serde_json::Value) -> String {
    j["failures"].to_string()
}

fn scan(root: &Path, drive: &str, frame: u32) -> PathBuf {
    root.join(drive)
        .join(format!("velodyne_points/data/{frame:010}.bin"))
}

#[test]
fn truncated_empty_and_nan_scans() {
    let t = tmp();
    let root = fixture_copy(t.path());
    let truncated = scan(&root, D1, 0);
    let len = std::fs::metadata(&truncated).unwrap().len();
    let f = std::fs::OpenOptions::new()
        .write(true)
        .open(&truncated)
        .unwrap();
    f.set_len(len - 5).unwrap();
    std::fs::write(scan(&root, D1, 45), b"").unwrap();
    // NaN points are dropped and counted, the frame still converts.
    let nan_path = scan(&root, D52, 0);
    let mut bytes = std::fs::read(&nan_path).unwrap();
    bytes[0..4].copy_from_slice(&f32::NAN.to_le_bytes());
    bytes[20..24].copy_from_slice(&f32::INFINITY.to_le_bytes());
    std::fs::write(&nan_path, &bytes).unwrap();

    let out = t.path().join("out");
    let (code, j, stderr) = convert_json(&root, &out, &[]);
    assert_eq!(code, 3);
    assert_eq!(j["frames_converted"], 1);
    assert_eq!(j["frames_failed"], 2);
    assert_eq!(j["dropped_nonfinite"], 2);
    let f = failures(&j);
    assert!(
        f.contains("0000000000.bin") && f.contains("not a multiple of 16"),
        "{f}"
    );
    assert!(f.contains("0000000045.bin") && f.contains("empty"), "{f}");
    assert!(
        stderr.contains("not a multiple of 16"),
        "failures are reported as they happen: {stderr}"
    );
    // The good frame is written, with one .label entry per point of the .bin, NaNs included.
    let label = out.join("labels/2011_09_26_drive_0052_sync/0000000000.label");
    assert_eq!(
        std::fs::metadata(label).unwrap().len() as usize,
        bytes.len() / 4
    );
    assert!(!out.join("lidar_2d/2011_09_26_0001_0000000000.npy").exists());
}

#[test]
fn missing_and_malformed_calibration_keys() {
    let t = tmp();
    let root = fixture_copy(t.path());
    let c2c = root.join("2011_09_26/calib_cam_to_cam.txt");
    let text = std::fs::read_to_string(&c2c).unwrap();
    let without: String = text
        .lines()
        .filter(|l| !l.starts_with("P_rect_02"))
        .map(|l| format!("{l}\n"))
        .collect();
    std::fs::write(&c2c, without).unwrap();
    // Without colour the camera calibration is not needed.
    let (code, _, e) = convert_json(&root, &t.path().join("plain"), &[]);
    assert_eq!(code, 0, "{e}");
    let (code, j, _) = convert_json(&root, &t.path().join("out"), &["--rgb"]);
    // Every frame failed: exit 1, the summary still printed and written.
    assert_eq!(code, 1);
    assert_eq!(j["frames_failed"], 3);
    let f = failures(&j);
    assert!(
        f.contains("calib_cam_to_cam.txt") && f.contains("missing key `P_rect_02`"),
        "{f}"
    );

    let v2c = root.join("2011_09_26/calib_velo_to_cam.txt");
    std::fs::write(&c2c, &text).unwrap();
    let vt = std::fs::read_to_string(&v2c)
        .unwrap()
        .replace("T: ", "T: 1.0 oops ");
    std::fs::write(&v2c, vt).unwrap();
    let (code, j, _) = convert_json(&root, &t.path().join("out"), &["--rgb"]);
    assert_eq!(code, 1);
    let f = failures(&j);
    assert!(
        f.contains("calib_velo_to_cam.txt") && f.contains("`T`"),
        "{f}"
    );
}

#[test]
fn malformed_tracklets_fail_their_drive_only() {
    let t = tmp();
    let root = fixture_copy(t.path());
    let xml = root.join(D52).join("tracklet_labels.xml");
    let text = std::fs::read_to_string(&xml).unwrap();
    std::fs::write(&xml, &text[..text.len() / 2]).unwrap();
    let (code, j, _) = convert_json(&root, &t.path().join("out"), &[]);
    assert_eq!(code, 3);
    assert_eq!(j["frames_converted"], 2, "drive 0001 still converts");
    assert_eq!(j["frames_failed"], 1);
    let f = failures(&j);
    assert!(
        f.contains("2011_09_26_drive_0052_sync/tracklet_labels.xml")
            && f.contains("not well-formed XML"),
        "{f}"
    );

    // A count that disagrees with the items, and an unknown state code.
    std::fs::write(&xml, text.replacen("<count>", "<count>9", 1)).unwrap();
    let (_, j, _) = convert_json(&root, &t.path().join("out"), &[]);
    assert!(failures(&j).contains("items but"), "{}", failures(&j));
    std::fs::write(
        &xml,
        text.replacen("<state>2</state>", "<state>7</state>", 1),
    )
    .unwrap();
    let (_, j, _) = convert_json(&root, &t.path().join("out"), &[]);
    assert!(failures(&j).contains("unknown code 7"), "{}", failures(&j));
}

#[test]
fn tracklet_past_the_last_frame() {
    let t = tmp();
    let root = fixture_copy(t.path());
    // Drive 0001 has 108 frames (its timestamps); make them 50.
    let ts = root.join(D1).join("velodyne_points/timestamps.txt");
    let lines: String = std::fs::read_to_string(&ts)
        .unwrap()
        .lines()
        .take(50)
        .map(|l| format!("{l}\n"))
        .collect();
    std::fs::write(&ts, lines).unwrap();
    let (code, j, _) = convert_json(&root, &t.path().join("out"), &[]);
    assert_eq!(code, 3);
    let f = failures(&j);
    assert!(
        f.contains("tracklet_labels.xml") && f.contains("past the drive's last frame 49"),
        "{f}"
    );
    assert_eq!(j["frames_converted"], 1);
}

#[test]
fn missing_image_with_rgb() {
    let t = tmp();
    let root = fixture_copy(t.path());
    std::fs::remove_file(root.join(D1).join("image_02/data/0000000045.png")).unwrap();
    let (code, j, _) = convert_json(&root, &t.path().join("out"), &["--rgb"]);
    assert_eq!(code, 3);
    assert_eq!(j["frames_converted"], 2);
    let f = failures(&j);
    assert!(f.contains("image_02/data/0000000045.png"), "{f}");
    // Without --rgb the image is not needed.
    let (code, _, _) = convert_json(&root, &t.path().join("out2"), &[]);
    assert_eq!(code, 0);
    // Camera 3 is not in the fixtures: every frame names its missing image.
    let (code, j, _) = convert_json(&root, &t.path().join("out3"), &["--rgb", "--camera", "3"]);
    assert_eq!(code, 1, "every frame failed");
    assert!(failures(&j).contains("image_03/data"));
}

#[test]
fn corrupt_image() {
    let t = tmp();
    let root = fixture_copy(t.path());
    std::fs::write(
        root.join(D52).join("image_02/data/0000000000.png"),
        b"\x89PNG\r\n\x1a\nnot really",
    )
    .unwrap();
    let (code, j, _) = convert_json(&root, &t.path().join("out"), &["--rgb"]);
    assert_eq!(code, 3);
    assert!(
        failures(&j).contains("cannot decode image"),
        "{}",
        failures(&j)
    );
}

#[test]
fn unusable_output_folder_and_inputs() {
    let t = tmp();
    let file = t.path().join("a-file");
    std::fs::write(&file, b"x").unwrap();
    let (code, _, stderr) = run_text(&["convert", s(&fixtures()), "--out", s(&file.join("sub"))]);
    assert_eq!(code, 1);
    assert!(
        stderr.contains("a-file/sub") && stderr.contains("cannot write"),
        "{stderr}"
    );
    let (code, _, stderr) = run_text(&[
        "convert",
        s(&t.path().join("nowhere")),
        "--out",
        s(&t.path().join("o")),
    ]);
    assert_eq!(code, 1);
    assert!(stderr.contains("nowhere: no such folder"), "{stderr}");
    assert_eq!(
        stderr.matches("nowhere").count(),
        1,
        "the path once: {stderr}"
    );
    let (code, _, stderr) = run_text(&["convert", s(t.path()), "--out", s(&t.path().join("o"))]);
    assert_eq!(code, 1);
    assert!(stderr.contains("no KITTI drive found"), "{stderr}");
    let (code, _, stderr) = run_text(&[
        "convert",
        s(&fixtures()),
        "--out",
        s(&t.path().join("o")),
        "--fov-deg",
        "400",
    ]);
    assert_eq!(code, 2, "an option out of range is a usage error");
    assert!(stderr.contains("FOV"), "{stderr}");
}

#[cfg(unix)]
#[test]
fn an_output_that_cannot_be_written_fails_its_frame_only() {
    // A folder where a frame's map goes: the rename onto it fails for root too (permissions
    // do not bind root, so a read-only folder would test nothing there).
    let t = tmp();
    let out = t.path().join("out");
    std::fs::create_dir_all(out.join("lidar_2d/2011_09_26_0001_0000000000.npy/x")).unwrap();
    let (code, j, _) = convert_json(&fixtures(), &out, &[]);
    assert_eq!(code, 3);
    assert!(failures(&j).contains("lidar_2d"), "{}", failures(&j));
    assert_eq!(j["frames_converted"], 2, "{j}");
}
