//! No output over an input, and parameters checked before any work (issue 26): each test is
//! named after the defect it guards against.

use std::path::Path;

use crate::unproject::{perfect_predictions, write_label_map};
use crate::util::*;

/// A usage error (exit 2) of kind `output_over_input`; its message.
fn refused(args: &[&str]) -> String {
    let e = fails_with(args, "output_over_input");
    assert_eq!(e["exit"], 2, "{args:?}");
    e["message"].as_str().unwrap().to_string()
}

#[test]
fn unproject_into_its_ground_truth_is_refused_and_the_truth_kept() {
    let t = tmp();
    let gt = t.path().join("gt");
    convert_fixtures(&gt, &[]);
    let before = tree_bytes(&gt);
    // An all-car model.
    let pred = t.path().join("pred");
    for id in ["2011_09_26_0001_0000000000", "2011_09_26_0001_0000000045"] {
        write_label_map(&pred.join(format!("{id}.npy")), &[1u8; 64 * 512], (64, 512));
    }
    let raw = fixtures();
    let base = [
        "unproject",
        "--gt",
        s(&gt),
        "--pred",
        s(&pred),
        "--raw",
        s(&raw),
    ];
    let e = refused(&[&base[..], &["--out", s(&gt)]].concat());
    assert!(e.contains("is the ground truth"), "{e}");
    refused(&[&base[..], &["--out", s(&gt.join("labels"))]].concat());
    refused(&[&base[..], &["--out", s(&pred)]].concat());
    refused(&[&base[..], &["--out", s(t.path())]].concat());
    // Another conversion's folder: its journal lists the files unproject would replace.
    let other = t.path().join("other");
    convert_fixtures(&other, &["--fov-deg", "120"]);
    let e = refused(&[&base[..], &["--out", s(&other)]].concat());
    assert!(e.contains(".kitti2pgm-frames"), "{e}");
    let viz = gt.join("viz.mcap");
    refused(
        &[
            &base[..],
            &["--out", s(&t.path().join("b")), "--viz", s(&viz)],
        ]
        .concat(),
    );
    assert_eq!(tree_bytes(&gt), before, "the ground truth is untouched");
    assert!(!t.path().join("b").exists(), "refused before any work");
}

#[test]
fn a_submission_archive_never_lands_on_or_inside_the_predictions() {
    let t = tmp();
    let sk = fixture("semantickitti");
    let pred = t.path().join("pred");
    let dir = pred.join("sequences/00/predictions");
    std::fs::create_dir_all(&dir).unwrap();
    let label = dir.join("000000.label");
    std::fs::copy(sk.join("sequences/00/labels/000000.label"), &label).unwrap();
    let before = std::fs::read(&label).unwrap();
    let e = refused(&["submission", s(&pred), "--gt", s(&sk), "--zip", s(&label)]);
    assert!(
        e.contains("is the predictions") || e.contains("is inside the predictions"),
        "{e}"
    );
    refused(&[
        "submission",
        s(&pred),
        "--gt",
        s(&sk),
        "--zip",
        s(&pred.join("sub.zip")),
    ]);
    assert_eq!(std::fs::read(&label).unwrap(), before);
    let zip = t.path().join("sub.zip");
    let (code, _, e) = run_text(&["submission", s(&pred), "--gt", s(&sk), "--zip", s(&zip)]);
    assert_eq!(code, 0, "{e}");
}

#[test]
fn an_archive_packs_exactly_the_files_checked() {
    use kitti2pgm::report::submission::{check_submission, write_zip};
    let t = tmp();
    let sk = fixture("semantickitti");
    let pred = t.path().join("pred");
    let dir = pred.join("sequences/00/predictions");
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::copy(
        sk.join("sequences/00/labels/000000.label"),
        dir.join("000000.label"),
    )
    .unwrap();
    let map = kitti2pgm::label::ClassMap::named_or_file(Path::new("semantic-kitti")).unwrap();
    let c = check_submission(&pred, &sk, None, &map).unwrap();
    assert!(c.is_valid(), "{:?}", c.problems);
    // Written after the check (a temporary file, a stray copy): not packed.
    std::fs::write(dir.join(".tmp-half-written"), b"junk").unwrap();
    std::fs::write(dir.join("000001.label"), b"junk").unwrap();
    let zip = t.path().join("sub.zip");
    write_zip(&pred, &c, &zip, "test").unwrap();
    let mut names: Vec<String> = zip::ZipArchive::new(std::fs::File::open(&zip).unwrap())
        .unwrap()
        .file_names()
        .map(|n| n.unwrap().into_owned())
        .collect();
    names.sort();
    assert_eq!(
        names,
        ["description.txt", "sequences/00/predictions/000000.label"]
    );
    // A file that changed between the check and the packing is not packed.
    std::fs::write(dir.join("000000.label"), b"0000").unwrap();
    assert!(matches!(
        write_zip(&pred, &c, &t.path().join("again.zip"), "test"),
        Err(kitti2pgm::Error::Length { .. })
    ));
}

#[test]
fn convert_split_and_pictures_refuse_outputs_inside_their_inputs() {
    let t = tmp();
    let root = fixture_copy(t.path());
    let r = s(&root);
    let inside = root.join("out");
    refused(&["convert", r, "--out", s(&inside), "--no-progress"]);
    refused(&["convert", r, "--out", r, "--no-progress"]);
    refused(&["split", r, "--out", s(&inside)]);
    refused(&["check", r, "--pictures", s(&inside), "--no-progress"]);
    assert!(!inside.exists(), "nothing written");
    let out = t.path().join("conv");
    convert_fixtures(&out, &[]);
    refused(&["stats", s(&out), "--chart", s(&out.join("balance.png"))]);
    let (code, _, e) = run_text(&["preview", s(&out), "--out", s(&out.join("pics"))]);
    assert_eq!(code, 2, "preview has no --json: {e}");
    let pred = t.path().join("pred");
    perfect_predictions(&out, &pred);
    refused(&[
        "score",
        "--gt",
        s(&out),
        "--pred",
        s(&pred),
        "--confusion",
        s(&pred.join("c.png")),
    ]);
}

#[test]
fn unproject_with_impossible_knn_parameters_is_a_usage_error_before_any_work() {
    let t = tmp();
    let gt = t.path().join("gt");
    convert_fixtures(&gt, &[]);
    let pred = t.path().join("pred");
    perfect_predictions(&gt, &pred);
    let out = t.path().join("back");
    let raw = fixtures();
    for bad in [
        ["--knn-k", "0"],
        ["--knn-window", "4"],
        ["--knn-sigma", "0"],
        ["--knn-sigma", "NaN"],
    ] {
        let mut args = vec!["unproject", "--gt", s(&gt), "--pred", s(&pred)];
        args.extend(["--raw", s(&raw), "--out", s(&out)]);
        args.extend(bad);
        let e = fails_with(&args, "config");
        assert_eq!(e["exit"], 2, "{bad:?}");
        assert!(!out.exists(), "{bad:?}: refused before any work");
        let mut score = vec!["score", "--gt", s(&gt), "--pred", s(&pred)];
        score.extend(bad);
        fails_with(&score, "config");
    }
}

#[test]
fn a_frame_missing_from_a_predicted_drive_is_named() {
    let t = tmp();
    let gt = t.path().join("gt");
    convert_fixtures(&gt, &[]);
    let pred = t.path().join("pred");
    perfect_predictions(&gt, &pred);
    std::fs::remove_file(pred.join("2011_09_26_0001_0000000045.npy")).unwrap();
    // Drive 0052 has no prediction at all: not carried, and said so.
    std::fs::remove_file(pred.join("2011_09_26_0052_0000000000.npy")).unwrap();
    let out = t.path().join("back");
    let raw = fixtures();
    let args = [
        "unproject",
        "--gt",
        s(&gt),
        "--pred",
        s(&pred),
        "--raw",
        s(&raw),
        "--out",
        s(&out),
        "--json",
    ];
    let (code, stdout, e) = run_text(&args);
    assert_eq!(code, 3, "{e}");
    assert!(
        e.contains("2011_09_26_0001_0000000045") && e.contains("no prediction"),
        "{e}"
    );
    let j: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(j["frames"], 1, "{j}");
    assert_eq!(j["not_carried"], 1, "{j}");
}

#[test]
fn a_sequence_asked_for_twice_is_a_usage_error() {
    let t = tmp();
    let sk = fixture("semantickitti");
    let pred = t.path().join("pred");
    std::fs::create_dir_all(pred.join("sequences/00/predictions")).unwrap();
    let e = fails_with(
        &["submission", s(&pred), "--gt", s(&sk), "--sequences", "0,0"],
        "config",
    );
    assert_eq!(e["exit"], 2);
}

#[test]
fn check_thresholds_outside_their_domain_are_usage_errors() {
    for bad in [
        "camera-alignment.frames=2.5",
        "camera-alignment.frames=1e12",
        "split-balance.factor=0",
        "annotation-ends.fov-deg=720",
    ] {
        let e = fails_with(
            &["check", s(&fixtures()), "--set", bad, "--no-progress"],
            "config",
        );
        assert_eq!(e["exit"], 2, "{bad}");
    }
}
