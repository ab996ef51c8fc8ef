//! Defaults and names, as a first run meets them: presets, built-in class map names, messages
//! that name the expected layouts, outputs that are where the README says.

use crate::util::*;

#[test]
fn semantickitti_defaults_to_the_full_360_map_and_presets_apply() {
    let t = tmp();
    let sk = fixture("semantickitti");
    let (code, j, e) = convert_json(&sk, &t.path().join("a"), &[]);
    assert_eq!(code, 0, "{e}");
    let spec = &j["params"]["map"]["spec"];
    assert_eq!(
        (spec["cols"].as_u64(), spec["fov"].as_f64()),
        (Some(2048), Some(360.0))
    );
    assert_eq!(spec["row_mode"], "rings");
    assert_eq!(
        j["map_origin"],
        "preset full (the default for SemanticKITTI)"
    );
    let (_, stdout, _) = run_text(&[
        "convert",
        s(&sk),
        "--out",
        s(&t.path().join("b")),
        "--preset",
        "rangenet",
        "--cols",
        "1024",
    ]);
    assert!(
        stdout.contains("64 x 1024 x 6") && stdout.contains("rows by elevation"),
        "{stdout}"
    );
    assert!(
        stdout.contains("preset rangenet (asked for), with cols given"),
        "{stdout}"
    );
    assert!(
        stdout.contains("sequences "),
        "a SemanticKITTI summary counts sequences: {stdout}"
    );
    let (_, j, _) = convert_json(&fixtures(), &t.path().join("c"), &[]);
    assert_eq!(j["params"]["map"]["spec"]["cols"], 512);
    assert_eq!(
        j["map_origin"],
        "preset squeezeseg (the default for KITTI raw)"
    );
    let (code, _, e) = convert_json(&fixtures(), &t.path().join("d"), &["--preset", "bonnetal"]);
    assert_eq!(code, 2);
    assert!(e.contains("squeezeseg, rangenet, full"), "{e}");
    let (_, help, _) = run_text(&["convert", "--help"]);
    assert!(
        help.contains("--preset") && help.contains("RangeNet++"),
        "{help}"
    );
}

#[test]
fn class_maps_by_the_names_outputs_record() {
    let t = tmp();
    let (code, j, e) = convert_json(
        &fixtures(),
        &t.path().join("a"),
        &["--class-map", "kitti-paper-4"],
    );
    assert_eq!(code, 0, "{e}");
    assert_eq!(j["params"]["map"]["class_map"]["name"], "kitti-paper-4");
    let (code, j, e) = convert_json(
        &fixture("semantickitti"),
        &t.path().join("b"),
        &["--class-map", "semantic-kitti"],
    );
    assert_eq!(code, 0, "{e}");
    assert_eq!(j["params"]["map"]["class_map"]["name"], "semantic-kitti");
    let (code, _, e) = convert_json(
        &fixtures(),
        &t.path().join("c"),
        &["--class-map", "nonesuch"],
    );
    // A name that is neither a built-in map nor a file: a usage error listing the built-in maps.
    assert_eq!(code, 2);
    assert!(e.contains("nonesuch") && e.contains("sustechpoints"), "{e}");
}

#[test]
fn shards_alone_write_no_label_files_unless_asked() {
    let t = tmp();
    let (code, _, e) = convert_json(&fixtures(), &t.path().join("a"), &["--format", "mcap"]);
    assert_eq!(code, 0, "{e}");
    assert!(!t.path().join("a/labels").exists());
    let (code, _, e) = convert_json(
        &fixtures(),
        &t.path().join("b"),
        &["--format", "mcap,labels"],
    );
    assert_eq!(code, 0, "{e}");
    assert!(t
        .path()
        .join("b/labels/2011_09_26_drive_0052_sync/0000000000.label")
        .is_file());
    assert!(!t.path().join("b/lidar_2d").exists());
}

#[test]
fn score_takes_an_imageset_folder_and_names_a_missing_list() {
    let t = tmp();
    let out = t.path().join("out");
    convert_fixtures(&out, &[]);
    let (code, _, e) = run_text(&[
        "split",
        s(&fixtures()),
        "--out",
        s(&out),
        "--val-drives",
        "0052",
    ]);
    assert_eq!(code, 0, "{e}");
    let pred = out.join("lidar_2d");
    let (code, stdout, e) = run_text(&[
        "score",
        "--gt",
        s(&out),
        "--pred",
        s(&pred),
        "--imageset",
        s(&out.join("ImageSet")),
        "--json",
    ]);
    assert_eq!(code, 0, "{e}");
    let j: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(j["frames"], 1, "val.txt of the folder: drive 0052's frame");
    assert_eq!(j["accuracy"], 1.0);
    let (code, _, e) = run_text(&[
        "score",
        "--gt",
        s(&out),
        "--pred",
        s(&pred),
        "--imageset",
        s(&out.join("nope.txt")),
    ]);
    assert_eq!(code, 1);
    assert!(e.contains("nope.txt: no such frame list"), "{e}");
}

#[test]
fn semantickitti_scoring_speaks_the_benchmarks_language() {
    let t = tmp();
    let sk = fixture("semantickitti");
    let truth = sk.join("sequences/00/labels/000000.label");
    // The benchmark's layout: scored per point, accuracy beside mIoU, absent classes count 0,
    // no 20 x 20 matrix in the terminal.
    let good = t.path().join("good/sequences/00/predictions");
    std::fs::create_dir_all(&good).unwrap();
    std::fs::copy(&truth, good.join("000000.label")).unwrap();
    let (code, stdout, e) =
        run_text(&["score", "--gt", s(&sk), "--pred", s(&t.path().join("good"))]);
    assert_eq!(code, 0, "{e}");
    assert!(stdout.contains("points scored"), "{stdout}");
    assert!(stdout.contains("accuracy 1.0000"), "{stdout}");
    assert!(stdout.contains("counts 0, as the benchmark's"), "{stdout}");
    assert!(stdout.contains("all but unlabeled"), "{stdout}");
    assert!(!stdout.contains("confusion (rows"), "{stdout}");
    assert!(stdout.contains("--confusion PNG"), "{stdout}");
    // A flat folder of .label files: the message names the expected layouts.
    let flat = t.path().join("flat");
    std::fs::create_dir_all(&flat).unwrap();
    std::fs::copy(&truth, flat.join("000000.label")).unwrap();
    let (code, _, e) = run_text(&["score", "--gt", s(&sk), "--pred", s(&flat)]);
    assert_eq!(code, 1);
    assert!(
        e.contains("000000.label is not named as one")
            && e.contains("sequences/<NN>/predictions/<frame6>.label"),
        "{e}"
    );
    // Raw ids without the predictions/ folder: the hint says where they belong.
    let seq = t.path().join("seq/sequences/00");
    std::fs::create_dir_all(&seq).unwrap();
    std::fs::copy(&truth, seq.join("000000.label")).unwrap();
    let (code, _, e) = run_text(&["score", "--gt", s(&sk), "--pred", s(&t.path().join("seq"))]);
    assert_eq!(code, 1);
    assert!(
        e.contains("are read from sequences/<NN>/predictions/<frame6>.label"),
        "{e}"
    );
}

#[test]
fn previews_of_predictions_and_one_png_name_for_one_frame() {
    let t = tmp();
    let out = t.path().join("out");
    convert_fixtures(&out, &[]);
    let a = out.join("lidar_2d/2011_09_26_0001_0000000000.npy");
    let b = out.join("lidar_2d/2011_09_26_0052_0000000000.npy");
    let (code, _, e) = run_text(&[
        "preview",
        s(&a),
        s(&b),
        "--out",
        s(&t.path().join("two.png")),
    ]);
    assert_eq!(code, 1);
    assert!(e.contains("give a folder for --out"), "{e}");
    assert!(!t.path().join("two.png").exists());
    // A prediction: an H x W uint8 label map, as the trainer writes it.
    let (shape, data) = kitti2pgm::format::npy::read_f32(&a).unwrap();
    let labels: Vec<u8> = data
        .chunks_exact(shape[2] as usize)
        .map(|c| c[5] as u8)
        .collect();
    let pred = t.path().join("2011_09_26_0001_0000000000.npy");
    let header = "{'descr': '|u1', 'fortran_order': False, 'shape': (64, 512), }";
    let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
    let pad = (10 + header.len() + 1).next_multiple_of(64) - (10 + header.len() + 1);
    let h = format!("{header}{}\n", " ".repeat(pad));
    bytes.extend_from_slice(&(h.len() as u16).to_le_bytes());
    bytes.extend_from_slice(h.as_bytes());
    bytes.extend_from_slice(&labels);
    std::fs::write(&pred, bytes).unwrap();
    let png = t.path().join("pred.png");
    let (code, _, e) = run_text(&["preview", s(&pred), "--out", s(&png)]);
    assert_eq!(code, 0, "{e}");
    let img = kitti2pgm::raster::read(&png).unwrap();
    assert_eq!(img.dimensions(), (512, 128));
    let car = kitti2pgm::label::ClassMap::kitti_paper().colour(1);
    assert!(img.pixels().any(|p| p.0 == car), "cars drawn");
}

#[test]
fn object_splits_print_no_empty_drive_list() {
    let t = tmp();
    let (code, stdout, e) = run_text(&[
        "split",
        s(&fixture("kitti_object")),
        "--out",
        s(&t.path().join("o")),
    ]);
    assert_eq!(code, 0, "{e}");
    assert!(!stdout.contains("drives"), "{stdout}");
    let (code, stdout, e) = run_text(&[
        "split",
        s(&fixture("semantickitti")),
        "--out",
        s(&t.path().join("s")),
        "--val-sequences",
        "0",
    ]);
    assert_eq!(code, 0, "{e}");
    assert!(stdout.contains("(1 sequences: 00)"), "{stdout}");
}
