//! Nothing lost silently, round two: one regression test per defect of the second hostile
//! audit (issue 18), each named after its defect, on the real fixtures.

use std::path::Path;
use std::time::Duration;

use crate::util::*;

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
    let summary = out.join("convert_summary.json");
    let text = std::fs::read_to_string(&summary).unwrap();
    std::fs::write(
        &summary,
        text.replace("\"complete\": true", "\"complete\": false"),
    )
    .unwrap();
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
    let summary = out.join("convert_summary.json");
    let text = std::fs::read_to_string(&summary).unwrap();
    std::fs::write(
        &summary,
        text.replace("\"complete\": true", "\"complete\": false"),
    )
    .unwrap();
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
    std::fs::write(&summary, text).unwrap();
    let from = out.join("lidar_2d/2011_09_26_0001_0000000000.npy");
    let to = out.join("lidar_2d/2011_09_26_0001_0000000099.npy");
    std::fs::copy(from, to).unwrap();
    let (code, _, e) = run_text(&["stats", s(&out)]);
    assert_eq!(code, 1, "{e}");
    assert!(e.contains("were not made by the conversion"), "{e}");
}

#[test]
fn a_wild_object_calibration_is_an_error_not_a_hang() {
    let t = tmp();
    let ko = copy_of("kitti_object", t.path());
    let calib = ko.join("training/calib/000000.txt");
    let text = std::fs::read_to_string(&calib).unwrap();
    let wild: String = text
        .lines()
        .map(|l| match l.split_once(':') {
            Some(("Tr_velo_to_cam", v)) => {
                let n = v.split_whitespace().count();
                format!("Tr_velo_to_cam:{}", " 1e155".repeat(n))
            }
            _ => l.to_string(),
        })
        .collect::<Vec<_>>()
        .join("\n");
    std::fs::write(&calib, wild).unwrap();
    let out = t.path().join("out");
    let (code, e) = run_limited(
        &["convert", s(&ko), "--out", s(&out), "--no-progress"],
        Duration::from_secs(120),
    )
    .expect("convert must not hang on a wild calibration");
    assert_eq!(code, 3, "{e}");
    assert!(
        e.contains("000000.txt") && e.contains("`Tr_velo_to_cam` is not a rotation"),
        "{e}"
    );
}

#[test]
fn object_calibration_without_r0_rect_is_an_error() {
    let t = tmp();
    let ko = copy_of("kitti_object", t.path());
    let calib = ko.join("training/calib/000001.txt");
    let text = std::fs::read_to_string(&calib).unwrap();
    let without: String = text
        .lines()
        .filter(|l| !l.starts_with("R0_rect"))
        .map(|l| format!("{l}\n"))
        .collect();
    std::fs::write(&calib, without).unwrap();
    let (code, _, e) = convert_json(&ko, &t.path().join("out"), &[]);
    assert_eq!(code, 3, "{e}");
    assert!(
        e.contains("000001.txt") && e.contains("missing key `R0_rect`"),
        "{e}"
    );
}

/// Points labelled per class in a conversion's summary.
fn labelled(j: &serde_json::Value, class: &str) -> u64 {
    j["labelled_points"][class].as_u64().unwrap_or(0)
}

#[test]
fn unknown_object_types_are_named_and_a_bom_loses_nothing() {
    let t = tmp();
    // Frame 000001: Truck, Car, Cyclist, DontCare; frame 000000: Pedestrian, DontCare.
    let rename = |dir: &str, bom: bool| {
        let ko = copy_of("kitti_object", &t.path().join(dir));
        let labels = ko.join("training/label_2");
        let edit = |name: &str, f: &dyn Fn(String) -> String| {
            let p = labels.join(name);
            std::fs::write(&p, f(std::fs::read_to_string(&p).unwrap())).unwrap();
        };
        edit("000001.txt", &|l| {
            let l = l.replacen("Car ", "Spaceship ", 1);
            if bom {
                format!("\u{feff}{l}")
            } else {
                l
            }
        });
        edit("000000.txt", &|l| l.replacen("Pedestrian ", "car ", 1));
        let (code, j, e) = convert_json(&ko, &t.path().join(dir).join("out"), &[]);
        assert_eq!(code, 0, "{e}");
        (j, e)
    };
    let (plain, e) = rename("plain", false);
    let unknown = &plain["unknown_object_types"];
    assert_eq!(unknown["Spaceship"], 1, "{plain}");
    assert_eq!(unknown["car"], 1, "{plain}");
    assert!(
        e.contains("Spaceship") && e.contains("car"),
        "named on stderr: {e}"
    );
    assert_eq!(labelled(&plain, "pedestrian"), 0, "\"car\" is not Car");
    // A byte order mark before "Truck" loses nothing: the truck still labels its points.
    let (bom, _) = rename("bom", true);
    assert!(labelled(&bom, "car") > 0, "{bom}");
    assert_eq!(bom["labelled_points"], plain["labelled_points"]);
    assert_eq!(bom["unknown_object_types"], plain["unknown_object_types"]);
}

#[test]
fn object_boxes_with_negative_sizes_are_refused() {
    let t = tmp();
    let ko = copy_of("kitti_object", t.path());
    let labels = ko.join("training/label_2/000000.txt");
    let text = std::fs::read_to_string(&labels).unwrap();
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    let i = lines
        .iter()
        .position(|l| !l.starts_with("DontCare"))
        .unwrap();
    let mut f: Vec<String> = lines[i].split(' ').map(str::to_string).collect();
    f[9] = format!("-{}", f[9]);
    lines[i] = f.join(" ");
    std::fs::write(&labels, lines.join("\n") + "\n").unwrap();
    let (code, _, e) = convert_json(&ko, &t.path().join("out"), &[]);
    assert_eq!(code, 3, "{e}");
    assert!(
        e.contains(&format!("000000.txt:{}: box size must be positive", i + 1)),
        "{e}"
    );
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

#[test]
fn reflectance_out_of_range_never_reaches_the_maps() {
    let t = tmp();
    let raw = fixture_copy(t.path());
    let scan =
        raw.join("2011_09_26/2011_09_26_drive_0001_sync/velodyne_points/data/0000000000.bin");
    let mut bytes = std::fs::read(&scan).unwrap();
    bytes[12..16].copy_from_slice(&1e30f32.to_le_bytes());
    bytes[28..32].copy_from_slice(&(-3.0f32).to_le_bytes());
    std::fs::write(&scan, bytes).unwrap();
    let out = t.path().join("out");
    let (code, j, e) = convert_json(&raw, &out, &[]);
    assert_eq!(code, 0, "{e}");
    assert_eq!(j["dropped_out_of_range"], 2, "{j}");
    let gt = kitti2pgm::report::truth::GroundTruth::open(&out).unwrap();
    let st = kitti2pgm::report::stats::stats(&gt, &[], None, &|_| {}).unwrap();
    let norm = &st.normalisation;
    assert_eq!(norm.channels[3], "intensity");
    let mean = norm.mean[3];
    assert!((0.0..=1.0).contains(&mean), "intensity mean {mean}");
    // The two points are dropped: their .label entries are 0 and the rest line up.
    let labels =
        std::fs::read(out.join("labels/2011_09_26_drive_0001_sync/0000000000.label")).unwrap();
    assert_eq!(&labels[..8], &[0; 8]);
}

#[test]
fn a_class_map_that_cannot_label_the_source_is_refused() {
    let t = tmp();
    let yaml = Path::new(env!("CARGO_MANIFEST_DIR")).join("src/label/semantic-kitti.yaml");
    let (code, _, e) = convert_json(
        &fixtures(),
        &t.path().join("out"),
        &["--class-map", s(&yaml)],
    );
    assert_eq!(code, 2, "{e}");
    assert!(e.contains("has no rule for the annotations"), "{e}");
    assert!(!t.path().join("out/lidar_2d").exists() || maps(&t.path().join("out")).is_empty());
}

#[test]
fn absurd_map_options_are_refused() {
    let t = tmp();
    for (flag, value) in [
        ("--fov-up-deg", "inf"),
        ("--fov-down-deg", "-inf"),
        ("--fov-up-deg", "NaN"),
        ("--fov-up-deg", "1e300"),
        ("--fov-deg", "inf"),
    ] {
        let arg = format!("{flag}={value}");
        let (code, _, e) = convert_json(&fixtures(), &t.path().join("out"), &[&arg]);
        assert_eq!(code, 2, "{flag} {value}: {e}");
        assert!(e.to_lowercase().contains("fov"), "{flag} {value}: {e}");
    }
}

#[test]
fn a_scan_named_beyond_u32_is_not_a_frame_and_no_panic() {
    let t = tmp();
    let raw = fixture_copy(t.path());
    let data = raw.join("2011_09_26/2011_09_26_drive_0001_sync/velodyne_points/data");
    std::fs::copy(data.join("0000000000.bin"), data.join("9999999999.bin")).unwrap();
    let (code, j, e) = convert_json(&raw, &t.path().join("out"), &[]);
    assert_eq!(code, 0, "{e}");
    assert!(
        j["not_frames"].to_string().contains("9999999999.bin"),
        "{j}"
    );
    let (code, _, e) = run_text(&["split", s(&raw), "--out", s(&t.path().join("split"))]);
    assert_eq!(code, 0, "{e}");
}

#[test]
fn a_tracklet_far_beyond_any_drive_is_an_error_not_an_abort() {
    let t = tmp();
    let raw = fixture_copy(t.path());
    let xml = raw.join("2011_09_26/2011_09_26_drive_0001_sync/tracklet_labels.xml");
    let text = std::fs::read_to_string(&xml).unwrap();
    let start = text.find("<first_frame>").unwrap();
    let end = text[start..].find("</first_frame>").unwrap() + start;
    let wild = format!("{}<first_frame>400000000{}", &text[..start], &text[end..]);
    std::fs::write(&xml, wild).unwrap();
    let (code, _, e) = convert_json(&raw, &t.path().join("out"), &[]);
    assert_eq!(code, 3, "{e}");
    assert!(
        e.contains("tracklet_labels.xml") && e.contains("beyond any drive"),
        "{e}"
    );
}

#[test]
fn stats_chart_takes_the_twenty_classes() {
    let t = tmp();
    let out = t.path().join("out");
    let (code, _, e) = convert_json(
        &fixture("semantickitti"),
        &out,
        &["--fov-deg", "360", "--cols", "2048"],
    );
    assert_eq!(code, 0, "{e}");
    let png = t.path().join("balance.png");
    let (code, _, e) = run_text(&["stats", s(&out), "--chart", s(&png)]);
    assert_eq!(code, 0, "{e}");
    let img = image::open(&png).unwrap().to_rgb8();
    // Every labelled class's colour is in the legend.
    let map = kitti2pgm::label::ClassMap::semantic_kitti();
    for c in map.labelled() {
        let colour = map.colour(c);
        assert!(
            img.pixels().any(|p| p.0 == colour),
            "{} missing",
            map.name(c)
        );
    }
}

#[test]
fn point_shards_with_viz_are_readable_and_kept() {
    let t = tmp();
    let out = t.path().join("out");
    convert_fixtures(&out, &["--format", "points", "--viz"]);
    let shard = out.join("points/train-00000.mcap");
    let (code, stdout, e) = run_text(&["inspect", s(&shard)]);
    assert_eq!(code, 0, "{e}");
    assert!(stdout.contains("/kitti2pgm/viz/points"), "{stdout}");
    let before = std::fs::read(&shard).unwrap();
    let (code, j, e) = convert_json(&fixtures(), &out, &["--format", "points", "--viz"]);
    assert_eq!(code, 0, "{e}");
    assert_eq!(j["shards_skipped"], 1, "the intact shard is kept: {j}");
    assert_eq!(std::fs::read(&shard).unwrap(), before);
    let frames: Vec<_> = kitti2pgm::format::shard::Shard::open_verified(&shard)
        .unwrap()
        .points()
        .unwrap();
    assert_eq!(frames.len(), 3);
}

// The smaller points ("also fix") of the same audit.

#[cfg(unix)]
#[test]
fn a_dangling_label_link_is_an_error_not_unlabelled() {
    let t = tmp();
    let sk = copy_of("semantickitti", t.path());
    let label = sk.join("sequences/00/labels/000000.label");
    std::fs::remove_file(&label).unwrap();
    std::os::unix::fs::symlink(t.path().join("nowhere.label"), &label).unwrap();
    let (code, j, e) = convert_json(&sk, &t.path().join("out"), &[]);
    assert_eq!(code, 1, "the only frame failed: {e}");
    assert!(e.contains("000000.label"), "{e}");
    assert_ne!(j["frames_without_labels"], 1, "{j}");
}

#[test]
fn extra_label_files_are_named() {
    let t = tmp();
    let sk = copy_of("semantickitti", t.path());
    let labels = sk.join("sequences/00/labels");
    std::fs::copy(labels.join("000000.label"), labels.join("000007.label")).unwrap();
    let (code, j, e) = convert_json(&sk, &t.path().join("out"), &[]);
    assert_eq!(code, 0, "{e}");
    assert!(
        j["labels_without_scan"]
            .to_string()
            .contains("000007.label"),
        "{j}"
    );
    assert!(
        e.contains("000007.label") && e.contains("labels of no scan"),
        "{e}"
    );
}

#[test]
fn unmatched_split_options_are_refused() {
    let t = tmp();
    let out = t.path().join("out");
    for args in [vec!["--val-drives", "9999"], vec!["--val-sequences", "8"]] {
        let root = fixtures();
        let mut split = vec!["split", s(&root), "--out", s(&out)];
        split.extend(&args);
        let (code, _, e) = run_text(&split);
        assert_eq!(code, 2, "{args:?}: {e}");
        assert!(e.contains("not among the 3 frames found"), "{e}");
        let mut convert = vec!["--format", "mcap"];
        convert.extend(&args);
        let (code, _, e) = convert_json(&fixtures(), &out, &convert);
        assert_eq!(code, 2, "{args:?}: {e}");
    }
    let (code, _, e) = run_text(&[
        "split",
        s(&fixtures()),
        "--out",
        s(&out),
        "--val-drives",
        "0052",
    ]);
    assert_eq!(code, 0, "{e}");
}

#[test]
fn absurd_thread_counts_are_refused() {
    let (code, _, e) = run_text(&["--threads", "100000", "split", s(&fixtures()), "--out", "x"]);
    assert_eq!(code, 2, "{e}");
    assert!(e.contains("0..=1024"), "{e}");
}

#[test]
fn grey_and_16_bit_camera_images_are_refused() {
    let t = tmp();
    let raw = fixture_copy(t.path());
    let png = raw.join("2011_09_26/2011_09_26_drive_0001_sync/image_02/data/0000000000.png");
    let img = image::open(&png).unwrap();
    img.to_luma8().save(&png).unwrap();
    let png16 = raw.join("2011_09_26/2011_09_26_drive_0001_sync/image_02/data/0000000045.png");
    image::DynamicImage::ImageRgb16(image::open(&png16).unwrap().to_rgb16())
        .save(&png16)
        .unwrap();
    let (code, j, e) = convert_json(&raw, &t.path().join("out"), &["--rgb"]);
    assert_eq!(code, 3, "{e}");
    assert!(
        e.contains("0000000000.png") && e.contains("8-bit RGB"),
        "{e}"
    );
    assert!(e.contains("0000000045.png") && e.contains("Rgb16"), "{e}");
    assert_eq!(j["frames_failed"], 2, "{j}");
}

#[test]
fn preview_counts_what_it_wrote_before_a_bad_frame() {
    let t = tmp();
    let out = t.path().join("out");
    convert_fixtures(&out, &[]);
    let bad = out.join("lidar_2d/2011_09_26_0052_0000000000.npy");
    let bytes = std::fs::read(&bad).unwrap();
    std::fs::write(&bad, &bytes[..bytes.len() / 2]).unwrap();
    let pics = t.path().join("pics");
    let (code, _, e) = run_text(&["preview", s(&out), "--out", s(&pics), "--threads", "1"]);
    assert_eq!(code, 3, "{e}");
    assert!(!e.contains("no preview written"), "{e}");
    assert!(e.contains("previews written"), "{e}");
    assert!(std::fs::read_dir(&pics).unwrap().count() >= 1);
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
    assert_eq!(j["protocol"], "Points", "{stdout}");
    let bytes = std::fs::read(&truth).unwrap();
    std::fs::write(&truth, &bytes[..bytes.len() - 40]).unwrap();
    let (code, _, e) = run_text(&["score", "--gt", s(&sk), "--pred", s(&pred)]);
    assert_eq!(code, 1, "{e}");
    assert!(
        e.contains("labels/000000.label") && e.contains("truncated ground truth"),
        "{e}"
    );
}

#[test]
fn a_damaged_chunk_names_its_own_frame_whatever_the_compression() {
    let t = tmp();
    for compression in ["none", "lz4", "zstd"] {
        let out = t.path().join(compression);
        convert_fixtures(
            &out,
            &[
                "--format",
                "mcap",
                "--shard-frames",
                "3",
                "--compression",
                compression,
            ],
        );
        let shard = out.join("shards/train-00000.mcap");
        let opened = kitti2pgm::format::shard::Shard::open(&shard).unwrap();
        let summary = opened.summary().unwrap();
        let md = opened.metadata().unwrap();
        let good = std::fs::read(&shard).unwrap();
        // Chunks in file order: frame k's chunk is the k-th (one frame a chunk).
        let mut chunks: Vec<_> = summary.chunk_indexes.iter().collect();
        chunks.sort_by_key(|c| c.chunk_start_offset);
        for (k, c) in chunks.iter().enumerate() {
            let mut bad = good.clone();
            let at = (c.chunk_start_offset + c.chunk_length * 2 / 3) as usize;
            bad[at] ^= 0x08;
            let path = t.path().join(format!("{compression}{k}.mcap"));
            std::fs::write(&path, &bad).unwrap();
            let (code, _, e) = run_text(&["inspect", s(&path)]);
            assert_ne!(code, 0);
            let want = format!("frame #{k} ({})", md.frames[k]);
            assert!(e.contains(&want), "{compression}: {want} in {e}");
        }
    }
}
