//! Re-runs and interruptions: a folder holds one conversion; leftovers of a killed run are
//! removed, finished frames kept only when proved, a run with other parameters replaces the
//! outputs; readers refuse an unfinished conversion unless asked.

use std::path::Path;

use crate::util::*;

const D1: &str = "2011_09_26/2011_09_26_drive_0001_sync";

#[test]
fn leftovers_are_removed_and_finished_frames_kept() {
    let t = tmp();
    let out = t.path().join("out");
    let clean = t.path().join("clean");
    convert_fixtures(&clean, &[]);
    convert_fixtures(&out, &[]);
    let gone = out.join("lidar_2d/2011_09_26_0001_0000000045.npy");
    std::fs::remove_file(&gone).unwrap();
    std::fs::write(out.join("lidar_2d/.tmp-XYZ123"), [0u8; 1000]).unwrap();
    std::fs::write(out.join("labels/2011_09_26_drive_0001_sync/.tmp-abc"), b"x").unwrap();
    let run = |extra: &[&str]| {
        let raw = fixtures();
        let mut args = vec!["convert", s(&raw), "--out", s(&out), "--json"];
        args.extend_from_slice(extra);
        let (code, stdout, stderr) = run_text(&args);
        assert_eq!(code, 0, "{stderr}");
        serde_json::from_str::<serde_json::Value>(&stdout).unwrap()
    };
    let j = run(&[]);
    assert_eq!(j["leftovers_removed"], 2);
    assert!(!out.join("lidar_2d/.tmp-XYZ123").exists());
    let done = (j["resumed_frames"].as_u64(), j["frames_converted"].as_u64());
    assert_eq!(done, (Some(2), Some(1)), "the finished frames are kept");
    let j = run(&[]);
    assert_eq!(j["resumed_frames"], 3, "same parameters: every frame kept");
    assert_eq!(j["frames_converted"], 0);
    assert_eq!(j["complete"], true);
    let j = run(&["--no-point-labels"]);
    assert_eq!(
        j["frames_converted"], 3,
        "other parameters: every frame again"
    );
    let j = run(&[]);
    assert_eq!(j["frames_converted"], 3);
    let j = run(&["--overwrite"]);
    assert_eq!(j["frames_converted"], 3, "--overwrite converts every frame");
    let files = |d: &Path| {
        tree_bytes(d)
            .into_iter()
            .filter(|(p, _)| p.starts_with("lidar_2d") || p.starts_with("labels"))
            .collect::<Vec<_>>()
    };
    assert_eq!(files(&out), files(&clean));
}
#[cfg(unix)]
#[test]
fn kill_9_then_rerun_gives_the_clean_output() {
    // 120 frames: drive 0001's two scans under 60 drive names (symlinks).
    let t = tmp();
    let root = t.path().join("raw");
    let date = root.join("2011_09_26");
    std::fs::create_dir_all(&date).unwrap();
    for f in [
        "calib_cam_to_cam.txt",
        "calib_velo_to_cam.txt",
        "calib_imu_to_velo.txt",
    ] {
        std::fs::copy(fixtures().join("2011_09_26").join(f), date.join(f)).unwrap();
    }
    for n in 0..60 {
        std::os::unix::fs::symlink(
            fixtures().join(D1),
            date.join(format!("2011_09_26_drive_{:04}_sync", 1000 + n)),
        )
        .unwrap();
    }
    let clean = t.path().join("clean");
    let (code, _, stderr) = run_text(&[
        "convert",
        s(&root),
        "--out",
        s(&clean),
        "--no-progress",
        "--rgb",
    ]);
    assert_eq!(code, 0, "{stderr}");
    let out = t.path().join("out");
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_kitti2pgm"))
        .args([
            "convert",
            s(&root),
            "--out",
            s(&out),
            "--no-progress",
            "--rgb",
        ])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    // Kill it once it has written some frames, before it has written them all.
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(60);
    loop {
        let written = std::fs::read_dir(out.join("lidar_2d")).map_or(0, |d| d.count());
        if written >= 10 || std::time::Instant::now() > deadline {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    child.kill().unwrap(); // SIGKILL
    child.wait().unwrap();
    let (code, stdout, stderr) = run_text(&[
        "convert",
        s(&root),
        "--out",
        s(&out),
        "--no-progress",
        "--rgb",
        "--json",
    ]);
    assert_eq!(code, 0, "{stderr}");
    let j: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert!(
        j["resumed_frames"].as_u64().unwrap() > 0,
        "the finished frames are kept: {j}"
    );
    let files = |d: &Path| {
        tree_bytes(d)
            .into_iter()
            .filter(|(p, _)| {
                !p.ends_with("convert_summary.json") && !p.ends_with(".kitti2pgm.lock")
            })
            .collect::<Vec<_>>()
    };
    let (a, b) = (files(&out), files(&clean));
    assert!(
        a.iter().all(|(p, _)| !p.contains(".tmp-")),
        "no temporary file left"
    );
    assert_eq!(a.len(), b.len());
    assert!(
        a == b,
        "the resumed output is byte-identical to a clean run's"
    );
}
#[test]
fn every_frame_failing_exits_1_and_writes_no_shard() {
    let t = tmp();
    let out = t.path().join("out");
    let (code, j, stderr) = convert_json(
        &fixtures(),
        &out,
        &["--format", "mcap", "--rgb", "--camera", "3"],
    );
    assert_eq!(code, 1, "{stderr}");
    assert!(stderr.contains("nothing converted"), "{stderr}");
    assert_eq!(j["frames_converted"], 0);
    assert_eq!(j["shards_written"], 0);
    let shards: Vec<_> = std::fs::read_dir(out.join("shards")).unwrap().collect();
    assert!(shards.is_empty(), "no empty shard: {shards:?}");
}
/// The `.npy` files of a convert folder as (name, bytes).
fn maps(out: &Path) -> Vec<(String, Vec<u8>)> {
    tree_bytes(&out.join("lidar_2d"))
}
#[test]
fn resume_never_mixes_parameters() {
    let t = tmp();
    let out = t.path().join("out");
    let fresh = t.path().join("fresh");
    convert_fixtures(&fresh, &["--fov-deg", "360"]);
    // 90 degrees everywhere, then 360 on one drive only, then 360 on all: every map must be a
    // 360-degree one. (The drive folder is another dataset root: nothing is resumed across
    // roots.)
    convert_fixtures(&out, &[]);
    let (code, j, e) = convert_json(&fixture_drive(1), &out, &["--fov-deg", "360"]);
    assert_eq!(code, 0, "{e}");
    assert!(j["stale_removed"].as_u64().unwrap() > 0, "{j}");
    assert_eq!(j["restarted"], "parameters changed", "{j}");
    let (code, j, e) = convert_json(&fixtures(), &out, &["--fov-deg", "360"]);
    assert_eq!(code, 0, "{e}");
    assert_eq!(j["resumed_frames"], 0, "{j}");
    assert_eq!(j["restarted"], "dataset root changed", "{j}");
    assert_eq!(maps(&out), maps(&fresh), "every map is a 360-degree map");
    // An interrupted run (the summary says so) that changed parameters: the same.
    convert_fixtures(&out, &[]);
    mark_unfinished(&out);
    let (code, j, e) = convert_json(&fixtures(), &out, &["--fov-deg", "360"]);
    assert_eq!(code, 0, "{e}");
    assert_eq!(j["resumed_frames"], 0, "{j}");
    assert_eq!(maps(&out), maps(&fresh));
    // Same parameters: every frame kept.
    let (_, j, _) = convert_json(&fixtures(), &out, &["--fov-deg", "360"]);
    assert_eq!(j["resumed_frames"], 3, "{j}");
    assert_eq!(maps(&out), maps(&fresh));
}
#[test]
fn resume_refuses_a_folder_of_unknown_maps() {
    let t = tmp();
    let out = t.path().join("out");
    std::fs::create_dir_all(out.join("lidar_2d")).unwrap();
    let stray = out.join("lidar_2d/2011_09_26_0001_0000000000.npy");
    std::fs::write(&stray, b"somebody's map").unwrap();
    let (code, _, e) = convert_json(&fixtures(), &out, &[]);
    assert_eq!(code, 1, "{e}");
    assert!(e.contains("no record of how they were made"), "{e}");
    assert_eq!(std::fs::read(&stray).unwrap(), b"somebody's map");
    let (code, _, e) = convert_json(&fixtures(), &out, &["--overwrite"]);
    assert_eq!(code, 0, "{e}");
}
#[test]
fn stale_shards_are_removed() {
    let t = tmp();
    let out = t.path().join("out");
    for format in ["mcap", "points"] {
        convert_fixtures(&out, &["--format", format, "--shard-frames", "1"]);
        let dir = out.join(if format == "mcap" { "shards" } else { "points" });
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 3);
        convert_fixtures(&out, &["--format", format, "--shard-frames", "3"]);
        let names: Vec<String> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        assert_eq!(names, ["train-00000.mcap"], "{format}");
    }
    convert_fixtures(&out, &["--format", "mcap", "--shard-frames", "3"]);
    let gt = kitti2pgm::report::truth::GroundTruth::open(&out).unwrap();
    let st = kitti2pgm::report::stats::stats(&gt, &[], None, &|_| {}).unwrap();
    assert_eq!(st.splits["all"].frames, 3);
    // A shard of another conversion copied in: refused, both shards named.
    let other = t.path().join("other");
    convert_fixtures(&other, &["--format", "mcap", "--shard-frames", "1"]);
    let copied = out.join("shards/train-00007.mcap");
    std::fs::copy(other.join("shards/train-00001.mcap"), &copied).unwrap();
    let (code, _, e) = run_text(&["stats", s(&out)]);
    assert_ne!(code, 0);
    assert!(
        e.contains("is in two shards") && e.contains("train-00007.mcap"),
        "{e}"
    );
    let (code, _, e) = run_text(&["score", "--gt", s(&out), "--pred", s(&out)]);
    assert_ne!(code, 0, "{e}");
}
#[test]
fn incomplete_conversions_are_refused_unless_partial() {
    let t = tmp();
    let out = t.path().join("out");
    convert_fixtures(&out, &["--format", "npy,mcap"]);
    let finished = mark_unfinished(&out);
    for gt in [out.clone(), out.join("lidar_2d"), out.join("shards")] {
        let (code, _, e) = run_text(&["stats", s(&gt)]);
        assert_eq!(code, 1, "{e}");
        assert!(
            e.contains("did not finish") && e.contains("--partial"),
            "{e}"
        );
        let pred = out.join("lidar_2d");
        let (code, _, e) = run_text(&["score", "--gt", s(&gt), "--pred", s(&pred)]);
        assert_eq!(code, 1, "{e}");
        assert!(e.contains("did not finish"), "{e}");
    }
    let png = t.path().join("p");
    let (code, _, e) = run_text(&["preview", s(&out), "--out", s(&png)]);
    assert_ne!(code, 0, "{e}");
    assert!(e.contains("did not finish"), "{e}");
    let (code, stdout, e) = run_text(&["stats", s(&out), "--partial", "--json"]);
    assert_eq!(code, 0, "{e}");
    assert!(e.contains("PARTIAL"), "{e}");
    assert!(stdout.contains("PARTIAL"), "the JSON says so too");
    let (code, _, e) = run_text(&["preview", s(&out), "--out", s(&png), "--partial"]);
    assert_eq!(code, 0, "{e}");
    // A map the journal does not list (copied in): refused.
    std::fs::write(out.join("convert_summary.json"), finished).unwrap();
    let from = out.join("lidar_2d/2011_09_26_0001_0000000000.npy");
    let to = out.join("lidar_2d/2011_09_26_0001_0000000099.npy");
    std::fs::copy(from, to).unwrap();
    let (code, _, e) = run_text(&["stats", s(&out)]);
    assert_eq!(code, 1, "{e}");
    assert!(e.contains("were not made by the conversion"), "{e}");
}
#[test]
fn tmp_leftovers_in_points_are_removed_and_never_shards() {
    let t = tmp();
    let out = t.path().join("out");
    convert_fixtures(&out, &["--format", "points"]);
    let leftover = out.join("points/.tmp-abc123.mcap");
    std::fs::write(&leftover, b"half a shard").unwrap();
    let listed = kitti2pgm::format::layout::list_shards(&out.join("points")).unwrap();
    assert!(!listed.contains(&leftover), "{listed:?}");
    let (code, j, e) = convert_json(&fixtures(), &out, &["--format", "points"]);
    assert_eq!(code, 0, "{e}");
    assert!(!leftover.exists());
    assert_eq!(j["leftovers_removed"], 1, "{j}");
}

/// Makes the convert folder `out` look like a run that did not finish (its summary says so);
/// returns the summary as it was.
fn mark_unfinished(out: &Path) -> String {
    let summary = out.join("convert_summary.json");
    let text = std::fs::read_to_string(&summary).unwrap();
    assert!(text.contains("\"complete\": true"), "{text}");
    std::fs::write(
        &summary,
        text.replace("\"complete\": true", "\"complete\": false"),
    )
    .unwrap();
    text
}
