//! From map predictions back to every point (issue 17): `unproject`, `score --unproject`,
//! `submission`, on the real fixture scans.

use std::path::{Path, PathBuf};

use kitti2pgm::format::label_file;
use kitti2pgm::format::npy::read_f32;
use kitti2pgm::project::{project_with_point_cells, PgmSpec, EMPTY};
use kitti2pgm::source::Scan;

use crate::util::*;

/// A `|u1` (H, W) `.npy` holding `labels`.
pub(crate) fn write_label_map(path: &Path, labels: &[u8], (h, w): (usize, usize)) {
    let header = format!("{{'descr': '|u1', 'fortran_order': False, 'shape': ({h}, {w}), }}");
    let pad = (10 + header.len() + 1).next_multiple_of(64) - (10 + header.len() + 1);
    let h = format!("{header}{}\n", " ".repeat(pad));
    let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
    bytes.extend_from_slice(&(h.len() as u16).to_le_bytes());
    bytes.extend_from_slice(h.as_bytes());
    bytes.extend_from_slice(labels);
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    std::fs::write(path, bytes).unwrap();
}

/// The label channel of every converted map as a prediction folder (perfect map predictions).
pub(crate) fn perfect_predictions(out: &Path, pred: &Path) {
    for e in std::fs::read_dir(out.join("lidar_2d")).unwrap() {
        let p = e.unwrap().path();
        let (shape, data) = read_f32(&p).unwrap();
        let c = shape[2] as usize;
        let labels: Vec<u8> = data.chunks_exact(c).map(|v| v[5] as u8).collect();
        write_label_map(
            &pred.join(p.file_name().unwrap()),
            &labels,
            (shape[0] as usize, shape[1] as usize),
        );
    }
}

/// `kitti2pgm unproject --gt GT --pred PRED --raw RAW --out OUT EXTRA...`: exit status,
/// stdout, stderr.
fn unproject(
    gt: &Path,
    pred: &Path,
    raw: &Path,
    out: &Path,
    extra: &[&str],
) -> (i32, String, String) {
    let mut args = vec![
        "unproject",
        "--gt",
        s(gt),
        "--pred",
        s(pred),
        "--raw",
        s(raw),
        "--out",
        s(out),
    ];
    args.extend_from_slice(extra);
    run_text(&args)
}

#[test]
fn cell_unprojection_of_the_truth_is_the_converters_labels_where_points_won() {
    let t = tmp();
    let out = t.path().join("out");
    convert_fixtures(&out, &[]);
    let pred = t.path().join("pred");
    perfect_predictions(&out, &pred);
    let back = t.path().join("back");
    let (code, stdout, e) = unproject(
        &out,
        &pred,
        &fixtures(),
        &back,
        &["--method", "cell", "--json"],
    );
    assert_eq!(code, 0, "{e}");
    let j: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(j["frames"], 3);
    assert!(
        j["not_predicted"].as_u64().unwrap() > 100_000,
        "the 90-degree map's back: {j}"
    );
    for (drive, frame) in [
        ("0001", "0000000000"),
        ("0001", "0000000045"),
        ("0052", "0000000000"),
    ] {
        let dname = format!("2011_09_26_drive_{drive}_sync");
        let scan = Scan::read(&fixtures().join(format!(
            "2011_09_26/{dname}/velodyne_points/data/{frame}.bin"
        )))
        .unwrap();
        let proj = project_with_point_cells(&scan.points, &PgmSpec::default());
        let ours =
            label_file::read_raw(&back.join(format!("labels/{dname}/{frame}.label"))).unwrap();
        let theirs =
            label_file::read_raw(&out.join(format!("labels/{dname}/{frame}.label"))).unwrap();
        assert_eq!(ours.len(), scan.file_len);
        let mut won = 0;
        for (i, &c) in proj.point_cell.iter().enumerate() {
            if c == EMPTY {
                assert_eq!(ours[i], 0xFFFF, "outside the map: not predicted");
            } else if proj.cell_point[c as usize] as usize == i {
                assert_eq!(ours[i], theirs[i] & 0xFFFF, "point {i} won its cell");
                won += 1;
            }
        }
        assert!(won > 20_000);
    }
}

#[test]
fn semantickitti_predictions_score_the_same_through_every_path() {
    let t = tmp();
    let out = t.path().join("sk");
    let (code, _, e) = convert_json(&fixture("semantickitti"), &out, &[]);
    assert_eq!(code, 0, "{e}");
    let pred = t.path().join("pred");
    perfect_predictions(&out, &pred);
    let back = t.path().join("back");
    let sk = fixture("semantickitti");
    let (code, _, e) = unproject(&out, &pred, &sk, &back, &[]);
    assert_eq!(code, 0, "{e}");
    assert!(back.join("sequences/00/predictions/000000.label").is_file());
    // The written raw ids score against the dataset itself as score --unproject knn does.
    let (code, a, e) = run_text(&["score", "--gt", s(&sk), "--pred", s(&back), "--json"]);
    assert_eq!(code, 0, "{e}");
    let a: serde_json::Value = serde_json::from_str(&a).unwrap();
    let (code, b, e) = run_text(&[
        "score",
        "--gt",
        s(&out),
        "--pred",
        s(&pred),
        "--raw",
        s(&sk),
        "--unproject",
        "knn",
        "--json",
    ]);
    assert_eq!(code, 0, "{e}");
    let b: serde_json::Value = serde_json::from_str(&b).unwrap();
    assert_eq!(a["miou"], b["points"]["miou"]);
    assert_eq!(a["confusion"], b["points"]["confusion"]);
    // Perfect per cell: the 12 classes present score 1, the 7 absent count 0.
    assert!(
        (b["cells"]["miou"].as_f64().unwrap() - 12.0 / 19.0).abs() < 1e-12,
        "{b}"
    );
    assert!(b["points"]["accuracy"].as_f64().unwrap() > 0.99);
    // The benchmark's checks pass, and the archive is packed.
    let zip = t.path().join("sub.zip");
    let (code, stdout, e) = run_text(&["submission", s(&back), "--gt", s(&sk), "--zip", s(&zip)]);
    assert_eq!(code, 0, "{e}");
    assert!(
        stdout.contains("1 of 1 predictions valid, 0 problems"),
        "{stdout}"
    );
    assert!(std::fs::metadata(&zip).unwrap().len() > 1000);
}

#[test]
fn the_submission_check_catches_each_injected_problem() {
    let t = tmp();
    let sk = fixture("semantickitti");
    let good = t.path().join("good/sequences/00/predictions");
    std::fs::create_dir_all(&good).unwrap();
    let truth = std::fs::read(sk.join("sequences/00/labels/000000.label")).unwrap();
    let check = |name: &str, edit: &dyn Fn(&Path), want: &str| {
        let dir = t.path().join(name);
        copy_tree(&t.path().join("good"), &dir);
        edit(&dir.join("sequences/00/predictions"));
        let (code, stdout, e) = run_text(&["submission", s(&dir), "--gt", s(&sk)]);
        assert_eq!(code, 1, "{name}: {e}");
        assert!(stdout.contains(want), "{name}: {stdout}");
    };
    std::fs::write(good.join("000000.label"), &truth).unwrap();
    check(
        "short",
        &|d| std::fs::write(d.join("000000.label"), &truth[..truth.len() - 4]).unwrap(),
        "124667 labels for the 124668 points",
    );
    check(
        "unknown",
        &|d| {
            let mut b = truth.clone();
            b[8..12].copy_from_slice(&77u32.to_le_bytes());
            std::fs::write(d.join("000000.label"), b).unwrap();
        },
        "1 labels are not raw ids of the dataset's learning_map (first: point 2, id 77)",
    );
    check(
        "missing",
        &|d| std::fs::remove_file(d.join("000000.label")).unwrap(),
        "missing",
    );
    check(
        "extra",
        &|d| std::fs::write(d.join("000001.label"), &truth).unwrap(),
        "extra: not the prediction of a scan",
    );
    let (code, _, e) = run_text(&["submission", s(&t.path().join("good")), "--gt", s(&sk)]);
    assert_eq!(code, 0, "{e}");
}

#[test]
fn bad_unprojection_inputs_are_named_and_leave_nothing_half_written() {
    let t = tmp();
    let out = t.path().join("out");
    convert_fixtures(&out, &[]);
    let pred = t.path().join("pred");
    perfect_predictions(&out, &pred);
    // A map of the wrong shape, a class beyond the map, a scan that changed since.
    write_label_map(
        &pred.join("2011_09_26_0001_0000000000.npy"),
        &vec![1u8; 64 * 256],
        (64, 256),
    );
    write_label_map(
        &pred.join("2011_09_26_0001_0000000045.npy"),
        &vec![9u8; 64 * 512],
        (64, 512),
    );
    let raw = fixture_copy(t.path());
    let bin = raw.join("2011_09_26/2011_09_26_drive_0052_sync/velodyne_points/data/0000000000.bin");
    let bytes = std::fs::read(&bin).unwrap();
    std::fs::write(&bin, &bytes[..bytes.len() - 16 * 10]).unwrap();
    let back = t.path().join("back");
    let (code, _, e) = unproject(&out, &pred, &raw, &back, &[]);
    assert_eq!(code, 1, "every frame failed: {e}");
    assert!(
        e.contains("2011_09_26_0001_0000000000.npy") && e.contains("is 64x256, expected 64x512"),
        "{e}"
    );
    assert!(
        e.contains("2011_09_26_0001_0000000045.npy") && e.contains("has label 9"),
        "{e}"
    );
    assert!(
        e.contains("0000000000.bin") && e.contains("the data changed since"),
        "{e}"
    );
    let leftovers: Vec<_> = walk(&back);
    assert!(
        leftovers
            .iter()
            .all(|p| !p.to_string_lossy().contains(".tmp-")),
        "{leftovers:?}"
    );
    assert!(
        leftovers.iter().all(|p| !p.is_file()),
        "nothing written: {leftovers:?}"
    );
    // Predictions for frames the ground truth does not hold.
    let (code, _, e) = unproject(&out, &t.path().join("nowhere"), &raw, &back, &[]);
    assert_eq!(code, 1);
    assert!(e.contains("nowhere"), "{e}");
}

fn walk(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    if let Ok(rd) = std::fs::read_dir(dir) {
        for e in rd {
            let p = e.unwrap().path();
            out.push(p.clone());
            if p.is_dir() {
                out.extend(walk(&p));
            }
        }
    }
    out
}

#[test]
fn per_point_predictions_are_drawn_and_go_to_foxglove() {
    let t = tmp();
    let out = t.path().join("sk");
    let sk = fixture("semantickitti");
    let (code, _, e) = convert_json(&sk, &out, &[]);
    assert_eq!(code, 0, "{e}");
    let pred = t.path().join("pred");
    perfect_predictions(&out, &pred);
    let back = t.path().join("back");
    let viz = t.path().join("viz.mcap");
    let (code, stdout, e) = unproject(&out, &pred, &sk, &back, &["--viz", s(&viz)]);
    assert_eq!(code, 0, "{e}");
    assert!(stdout.contains("viz"), "{stdout}");
    // One point cloud: every point in the map, wrong ones in red (class 20).
    let bytes = std::fs::read(&viz).unwrap();
    let mut clouds = 0;
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        if m.channel.topic == "/kitti2pgm/viz/points" {
            use prost::Message as _;
            let c = foxglove::schemas::PointCloud::decode(&m.data[..]).unwrap();
            assert_eq!(c.point_stride, 21);
            assert_eq!(c.data.len() % 21, 0);
            assert!(c.data.len() / 21 > 100_000);
            clouds += 1;
        }
    }
    assert_eq!(clouds, 1);
    let pics = t.path().join("pics");
    let (code, _, e) = run_text(&["preview", s(&back), "--raw", s(&sk), "--out", s(&pics)]);
    assert_eq!(code, 0, "{e}");
    let img = kitti2pgm::raster::read(&pics.join("00_000000.png")).unwrap();
    assert!(img.width() >= 1024 && img.height() > 700);
    // Mostly right: more green than red in the error panels.
    let green = img.pixels().filter(|p| p.0 == [60, 170, 70]).count();
    let red = img.pixels().filter(|p| p.0 == [230, 40, 40]).count();
    assert!(green > 20 * red.max(1), "{green} right, {red} wrong");
    // Map predictions are not per-point ones.
    let (code, _, e) = run_text(&["preview", s(&pred), "--raw", s(&sk), "--out", s(&pics)]);
    assert_eq!(code, 1);
    assert!(e.contains("per-point predictions"), "{e}");
}

#[test]
fn semantickitti_map_predictions_score_per_point_by_default_with_every_point() {
    let t = tmp();
    let sk = fixture("semantickitti");
    // A 90-degree map: most points are outside it, and the benchmark counts them.
    let out = t.path().join("sk90");
    let (code, _, e) = convert_json(&sk, &out, &["--preset", "squeezeseg"]);
    assert_eq!(code, 0, "{e}");
    let pred = t.path().join("pred");
    perfect_predictions(&out, &pred);
    let (code, stdout, e) = run_text(&[
        "score",
        "--gt",
        s(&out),
        "--pred",
        s(&pred),
        "--raw",
        s(&sk),
        "--json",
    ]);
    assert_eq!(code, 0, "{e}");
    let by_default: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(
        by_default["unproject"], "knn",
        "per point by default: {stdout}"
    );
    let back = t.path().join("back");
    let (code, j, e) = {
        let (c, o, e) = unproject(&out, &pred, &sk, &back, &["--json"]);
        (
            c,
            serde_json::from_str::<serde_json::Value>(&o).unwrap_or_default(),
            e,
        )
    };
    assert_eq!(code, 0, "{e}");
    assert!(j["not_predicted"].as_u64().unwrap() > 80_000, "{j}");
    let (code, bench, e) = run_text(&["score", "--gt", s(&sk), "--pred", s(&back), "--json"]);
    assert_eq!(code, 0, "{e}");
    let bench: serde_json::Value = serde_json::from_str(&bench).unwrap();
    assert_eq!(
        by_default["points"]["confusion"], bench["confusion"],
        "exactly the benchmark's count"
    );
    assert_eq!(by_default["points"]["elements"], bench["elements"]);
    // A prediction for a frame the ground truth does not hold is named.
    let extra = pred.join("00_000007.npy");
    std::fs::copy(pred.join("00_000000.npy"), &extra).unwrap();
    let (code, _, e) = unproject(&out, &pred, &sk, &t.path().join("b2"), &[]);
    assert_eq!(code, 3, "{e}");
    assert!(
        e.contains("00_000007.npy") && e.contains("not in the ground truth"),
        "{e}"
    );
}
