//! Inputs that exist but cannot be read (issue 26): links that lead nowhere or loop, folders,
//! FIFOs and devices in place of input files are errors naming the file, in `convert` and
//! `check` alike, never a hang, an endless read or "this drive has no tracklets".

use std::path::Path;
use std::time::Duration;

use crate::util::*;

const D1: &str = "2011_09_26/2011_09_26_drive_0001_sync";
const D52: &str = "2011_09_26/2011_09_26_drive_0052_sync";

#[cfg(unix)]
fn mkfifo(path: &Path) {
    let status = std::process::Command::new("mkfifo")
        .arg(path)
        .status()
        .unwrap();
    assert!(status.success());
}

/// Runs with a time limit: (exit code, stderr); a hang fails the test.
fn run_bounded(args: &[&str]) -> (i32, String) {
    run_limited(args, Duration::from_secs(60)).unwrap_or_else(|| panic!("{args:?} hung"))
}

#[cfg(unix)]
#[test]
fn a_dangling_tracklet_link_fails_its_drive_everywhere() {
    let t = tmp();
    let root = fixture_copy(t.path());
    let xml = root.join(D1).join("tracklet_labels.xml");
    std::fs::remove_file(&xml).unwrap();
    std::os::unix::fs::symlink(t.path().join("nowhere.xml"), &xml).unwrap();
    let (code, j, e) = convert_json(&root, &t.path().join("out"), &[]);
    assert_eq!(code, 3, "{e}");
    let failure = &j["failures"][0];
    assert_eq!(failure["what"], "2011_09_26_drive_0001_sync", "{j}");
    let msg = failure["error"].as_str().unwrap();
    assert!(
        msg.contains("tracklet_labels.xml: a link that leads nowhere"),
        "{msg}"
    );
    let (code, _, e) = run_text(&["check", s(&root), "--no-progress", "--no-scans", "--json"]);
    assert_eq!(code, 3, "an error, not a warning: {e}");
    let e = fails_with(
        &["split", s(&root), "--out", s(&t.path().join("split"))],
        "not_a_file",
    );
    assert_eq!(e["exit"], 1);
    // A link loop.
    std::fs::remove_file(&xml).unwrap();
    std::os::unix::fs::symlink(&xml, &xml).unwrap();
    let (code, j, _) = convert_json(&root, &t.path().join("out2"), &[]);
    assert_eq!(code, 3);
    let msg = j["failures"][0]["error"].as_str().unwrap();
    assert!(msg.contains("a link that cannot be followed"), "{msg}");
}

#[test]
fn a_folder_named_like_the_tracklet_file_is_an_error_in_check_too() {
    let t = tmp();
    let root = fixture_copy(t.path());
    let xml = root.join(D1).join("tracklet_labels.xml");
    std::fs::remove_file(&xml).unwrap();
    std::fs::create_dir(&xml).unwrap();
    let (code, stdout, e) = run_text(&["check", s(&root), "--no-progress", "--no-scans", "--json"]);
    assert_eq!(code, 3, "{e}");
    let report: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    let findings = report["findings"].as_array().unwrap();
    assert!(
        findings.iter().any(|f| f["severity"] == "error"
            && f["message"]
                .as_str()
                .unwrap()
                .contains("a folder, not a regular file")),
        "{report}"
    );
    let (code, j, _) = convert_json(&root, &t.path().join("out"), &[]);
    assert_eq!(code, 3);
    assert!(j["failures"][0]["error"]
        .as_str()
        .unwrap()
        .contains("a folder"));
}

#[cfg(unix)]
#[test]
fn fifos_in_place_of_inputs_never_hang() {
    let t = tmp();
    let root = fixture_copy(t.path());
    let day = root.join("2011_09_26");
    for p in [
        root.join(D1).join("tracklet_labels.xml"),
        day.join("calib_velo_to_cam.txt"),
        root.join(D52).join("velodyne_points/timestamps.txt"),
        root.join(D52).join("velodyne_points/data/0000000000.bin"),
        root.join(D52).join("image_02/data/0000000000.png"),
    ] {
        let _ = std::fs::remove_file(&p);
        mkfifo(&p);
    }
    let out = t.path().join("out");
    let (code, e) = run_bounded(&[
        "convert",
        s(&root),
        "--out",
        s(&out),
        "--rgb",
        "--no-progress",
    ]);
    assert_eq!(code, 1, "nothing could be converted: {e}");
    assert!(e.contains("a named pipe (FIFO), not a regular file"), "{e}");
    let (code, e) = run_bounded(&["check", s(&root), "--no-progress"]);
    assert_eq!(code, 3, "{e}");
    let (code, e) = run_bounded(&["split", s(&root), "--out", s(&t.path().join("s"))]);
    assert_ne!(code, 0, "{e}");
}

#[cfg(unix)]
#[test]
fn an_input_linked_to_dev_zero_is_refused_not_read_forever() {
    let t = tmp();
    let root = fixture_copy(t.path());
    let bin = root.join(D52).join("velodyne_points/data/0000000000.bin");
    std::fs::remove_file(&bin).unwrap();
    std::os::unix::fs::symlink("/dev/zero", &bin).unwrap();
    let xml = root.join(D1).join("tracklet_labels.xml");
    std::fs::remove_file(&xml).unwrap();
    std::os::unix::fs::symlink("/dev/zero", &xml).unwrap();
    let (code, e) = run_bounded(&[
        "convert",
        s(&root),
        "--out",
        s(&t.path().join("o")),
        "--no-progress",
    ]);
    assert_eq!(code, 1, "{e}");
    assert!(
        e.contains("0000000000.bin: a device, not a regular file"),
        "{e}"
    );
    assert!(e.contains("tracklet_labels.xml: a device"), "{e}");
    let (code, e) = run_bounded(&["check", s(&root), "--no-progress"]);
    assert_eq!(code, 3, "{e}");
}

#[test]
fn a_tracklet_box_of_1e38_metres_fails_its_drive_with_file_and_line() {
    let t = tmp();
    let root = fixture_copy(t.path());
    let xml = root.join(D1).join("tracklet_labels.xml");
    let text = std::fs::read_to_string(&xml).unwrap();
    let at = text.find("<l>").unwrap();
    let end = at + text[at..].find("</l>").unwrap();
    let edited = format!("{}<l>1e38{}", &text[..at], &text[end..]);
    std::fs::write(&xml, edited).unwrap();
    let (code, j, e) = convert_json(&root, &t.path().join("out"), &[]);
    assert_eq!(code, 3, "{e}");
    let msg = j["failures"][0]["error"].as_str().unwrap();
    assert!(
        msg.contains("tracklet_labels.xml:") && msg.contains("box size l=1e38 m is implausible"),
        "{msg}"
    );
    // Infinite in single precision, too.
    let edited = format!("{}<l>1e39{}", &text[..at], &text[end..]);
    std::fs::write(&xml, edited).unwrap();
    let (_, j, _) = convert_json(&root, &t.path().join("out2"), &[]);
    let msg = j["failures"][0]["error"].as_str().unwrap();
    assert!(msg.contains("not finite in single precision"), "{msg}");
}
