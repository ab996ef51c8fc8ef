//! Nothing lost silently: one test per defect of the hostile audit (issue "Nothing lost
//! silently"), on the real fixtures.

use std::path::{Path, PathBuf};

use crate::util::*;

/// The library's seeded generator (splitmix64), so that every run mutates the same bytes.
pub struct Rng(pub u64);

impl Rng {
    pub fn next(&mut self) -> u64 {
        kitti2pgm::rng::splitmix64(&mut self.0)
    }

    pub fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
}

fn shard_of(out: &Path) -> PathBuf {
    out.join("shards/train-00000.mcap")
}

#[test]
fn every_bit_flip_in_a_shard_is_caught() {
    let t = tmp();
    let out = t.path().join("out");
    convert_fixtures(&out, &["--format", "mcap", "--viz"]);
    let shard = shard_of(&out);
    let good = std::fs::read(&shard).unwrap();
    assert_eq!(run_text(&["inspect", s(&shard)]).0, 0);
    let mut rng = Rng(7);
    for k in 0..40 {
        let mut bad = good.clone();
        let at = rng.below(bad.len());
        bad[at] ^= 1 << rng.below(8);
        let copy = t.path().join(format!("flip{k}.mcap"));
        std::fs::write(&copy, &bad).unwrap();
        // In process: what inspect and score read the shard with.
        let e = kitti2pgm::report::inspect::inspect(&copy)
            .expect_err(&format!(
                "flip at byte {at} of {} went unnoticed",
                bad.len()
            ))
            .to_string();
        assert!(e.contains(&format!("flip{k}.mcap")), "{e}");
        let truth = kitti2pgm::report::truth::GroundTruth::open(&copy);
        let scored = truth.and_then(|gt| {
            let preds = kitti2pgm::report::score::Predictions::index(&shard)?;
            let opts = kitti2pgm::report::score::ScoreOptions {
                protocol: kitti2pgm::report::score::Protocol::Cells,
                missing_as_background: false,
                raw: None,
                unproject: kitti2pgm::project::unproject::Method::Cell,
            };
            let none = Default::default();
            kitti2pgm::report::score::score(&gt, None, &preds, &opts, &none, &|_| {})
        });
        assert!(scored.is_err(), "score read a shard flipped at byte {at}");
        // The command says so too (exit status, the shard named): once is enough.
        if k == 0 {
            let (code, _, stderr) = run_text(&["inspect", s(&copy)]);
            assert_ne!(code, 0);
            assert!(stderr.contains("flip0.mcap"), "{stderr}");
        }
    }
    // A re-run rewrites a corrupted shard instead of keeping it as complete and intact.
    let mut bad = good.clone();
    bad[good.len() / 2] ^= 0x10;
    std::fs::write(&shard, &bad).unwrap();
    convert_fixtures(&out, &["--format", "mcap", "--viz"]);
    assert_eq!(std::fs::read(&shard).unwrap(), good);
}

#[test]
fn inspect_names_a_folder() {
    let t = tmp();
    let (code, _, stderr) = run_text(&["inspect", s(t.path())]);
    assert_ne!(code, 0);
    assert!(stderr.contains("a folder, not a regular file"), "{stderr}");
}

const D1: &str = "2011_09_26/2011_09_26_drive_0001_sync";
const D52: &str = "2011_09_26/2011_09_26_drive_0052_sync";

#[test]
fn stray_files_are_named_and_the_drive_converts() {
    let t = tmp();
    let root = fixture_copy(t.path());
    let data = root.join(D1).join("velodyne_points/data");
    std::fs::write(data.join("abc.bin"), b"x").unwrap();
    std::fs::write(data.join("00000000000000000000000001.bin"), [0u8; 16]).unwrap();
    let (code, j, stderr) = convert_json(&root, &t.path().join("out"), &[]);
    assert_eq!(code, 0, "{stderr}");
    assert_eq!(j["frames_converted"], 3, "the drive's real frames convert");
    let named = j["not_frames"].to_string();
    assert!(
        named.contains("abc.bin") && named.contains("00000000000000000000000001.bin"),
        "{named}"
    );
    assert!(
        stderr.contains("abc.bin: not a <frame10>.bin scan, skipped"),
        "{stderr}"
    );
}

#[test]
fn an_unlistable_drive_is_a_failure() {
    let t = tmp();
    let root = fixture_copy(t.path());
    let data = root.join(D52).join("velodyne_points/data");
    std::fs::remove_dir_all(&data).unwrap();
    std::fs::write(&data, b"not a folder").unwrap();
    let (code, j, _) = convert_json(&root, &t.path().join("out"), &[]);
    assert_eq!(code, 3, "a drive that cannot be listed is a failure");
    assert_eq!(j["frames_converted"], 2);
    assert!(
        failures_of(&j).contains("2011_09_26_drive_0052_sync"),
        "{j}"
    );
}

#[cfg(unix)]
#[test]
fn a_drive_folder_name_that_is_not_utf8_is_named() {
    use std::os::unix::ffi::OsStrExt;
    let t = tmp();
    let root = fixture_copy(t.path());
    let odd = root.join("2011_09_26").join(std::ffi::OsStr::from_bytes(
        b"2011_09_26_drive_\xff\xfe_sync",
    ));
    copy_tree(&root.join(D52), &odd);
    let (code, j, _) = convert_json(&root, &t.path().join("out"), &[]);
    assert_eq!(code, 3);
    assert_eq!(j["frames_converted"], 3);
    assert!(failures_of(&j).contains("not valid UTF-8"), "{j}");
}

fn failures_of(j: &serde_json::Value) -> String {
    j["failures"].to_string()
}

/// `np.save(path, np.asfortranarray(a))` for a float32 array.
fn fortran_npy(shape: &[u64], c_data: &[f32]) -> Vec<u8> {
    let dims: Vec<usize> = shape.iter().map(|&d| d as usize).collect();
    let (h, w, c) = (dims[0], dims[1], dims[2]);
    let mut f = Vec::with_capacity(c_data.len());
    for k in 0..c {
        for j in 0..w {
            for i in 0..h {
                f.push(c_data[(i * w + j) * c + k]);
            }
        }
    }
    let mut bytes = kitti2pgm::format::npy::encode_f32(shape, &f);
    let header = String::from_utf8_lossy(&bytes[10..80]).into_owned();
    assert!(header.contains("'fortran_order': False"));
    // Same length: "True, " + padding is one byte shorter than "False,"; NumPy pads with spaces.
    let patched = header.replacen("'fortran_order': False", "'fortran_order': True ", 1);
    bytes[10..80].copy_from_slice(patched.as_bytes());
    bytes
}

#[test]
fn fortran_ordered_predictions_are_read_right() {
    let t = tmp();
    let out = t.path().join("out");
    convert_fixtures(&out, &[]);
    let pred = t.path().join("pred");
    std::fs::create_dir_all(&pred).unwrap();
    for e in std::fs::read_dir(out.join("lidar_2d")).unwrap() {
        let p = e.unwrap().path();
        let (shape, data) = kitti2pgm::format::npy::read_f32(&p).unwrap();
        std::fs::write(
            pred.join(p.file_name().unwrap()),
            fortran_npy(&shape, &data),
        )
        .unwrap();
    }
    let (code, stdout, stderr) =
        run_text(&["score", "--gt", s(&out), "--pred", s(&pred), "--json"]);
    assert_eq!(code, 0, "{stderr}");
    let j: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(j["miou"], 1.0, "perfect predictions saved in Fortran order");
}

#[test]
fn a_point_at_1e30_is_dropped_and_counted() {
    let t = tmp();
    let root = fixture_copy(t.path());
    let bin = root.join(D52).join("velodyne_points/data/0000000000.bin");
    let mut bytes = std::fs::read(&bin).unwrap();
    bytes[16 * 100..16 * 100 + 4].copy_from_slice(&1e30f32.to_le_bytes());
    std::fs::write(&bin, &bytes).unwrap();
    let out = t.path().join("out");
    let (code, j, _) = convert_json(&root, &out, &[]);
    assert_eq!(code, 0);
    assert_eq!(j["dropped_out_of_range"], 1);
    let (_, data) =
        kitti2pgm::format::npy::read_f32(&out.join("lidar_2d/2011_09_26_0052_0000000000.npy"))
            .unwrap();
    assert!(data.iter().all(|v| v.is_finite()));
    use kitti2pgm::report::{stats::stats, truth::GroundTruth};
    let stats_of = |out: &Path| stats(&GroundTruth::open(out).unwrap(), &[], None, &|_| {});
    let st = stats_of(&out).unwrap();
    let norm = &st.normalisation;
    assert!(
        norm.mean.iter().chain(&norm.std).all(|v| v.is_finite()),
        "{norm:?}"
    );
    // A map with an infinite range (written by another tool) is refused by name.
    let npy = out.join("lidar_2d/2011_09_26_0001_0000000000.npy");
    let (shape, mut data) = kitti2pgm::format::npy::read_f32(&npy).unwrap();
    let cell = data.chunks(6).position(|c| c[4] > 0.0).unwrap();
    data[cell * 6 + 4] = f32::INFINITY;
    std::fs::write(&npy, kitti2pgm::format::npy::encode_f32(&shape, &data)).unwrap();
    match stats_of(&out) {
        Err(kitti2pgm::Error::NotFinite { path, what, value }) => {
            assert_eq!(path, npy);
            assert!(what.ends_with("channel range"), "{what}");
            assert_eq!(value, f64::INFINITY);
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn an_image_of_the_wrong_size_fails_its_frame() {
    let t = tmp();
    let root = fixture_copy(t.path());
    let png = root.join(D52).join("image_02/data/0000000000.png");
    image::RgbImage::new(100, 50).save(&png).unwrap();
    let (code, j, _) = convert_json(&root, &t.path().join("out"), &["--rgb"]);
    assert_eq!(code, 3);
    assert_eq!(j["frames_converted"], 2);
    let f = failures_of(&j);
    assert!(
        f.contains("0000000000.png") && f.contains("100x50") && f.contains("1242x375"),
        "{f}"
    );
}

#[test]
fn an_unknown_object_type_is_named_and_counted() {
    let t = tmp();
    let root = fixture_copy(t.path());
    let xml = root.join(D1).join("tracklet_labels.xml");
    let text = std::fs::read_to_string(&xml).unwrap();
    std::fs::write(
        &xml,
        text.replacen(
            "<objectType>Car</objectType>",
            "<objectType>Hovercraft</objectType>",
            1,
        ),
    )
    .unwrap();
    let (code, j, stderr) = convert_json(&root, &t.path().join("out"), &[]);
    assert_eq!(code, 0);
    assert_eq!(j["unknown_object_types"]["Hovercraft"], 1);
    assert!(
        stderr.contains("unknown object type \"Hovercraft\", labelled background"),
        "{stderr}"
    );
}

#[test]
fn a_duplicate_calibration_key_is_refused() {
    let t = tmp();
    let root = fixture_copy(t.path());
    let v2c = root.join("2011_09_26/calib_velo_to_cam.txt");
    let mut text = std::fs::read_to_string(&v2c).unwrap();
    let t_line = text
        .lines()
        .find(|l| l.starts_with("T:"))
        .unwrap()
        .to_string();
    text.push_str(&format!("{t_line}\n"));
    std::fs::write(&v2c, &text).unwrap();
    // The calibration matters for colour only (the boxes are in the velodyne frame).
    let (code, _, e) = convert_json(&root, &t.path().join("plain"), &[]);
    assert_eq!(code, 0, "{e}");
    let (code, j, _) = convert_json(&root, &t.path().join("out"), &["--rgb"]);
    assert_eq!(code, 1, "every frame fails");
    let f = failures_of(&j);
    assert!(
        f.contains("calib_velo_to_cam.txt") && f.contains("key `T` appears twice"),
        "{f}"
    );
}

#[test]
fn predictions_without_ground_truth_are_named() {
    let t = tmp();
    let out = t.path().join("out");
    convert_fixtures(&out, &[]);
    let pred = t.path().join("pred");
    copy_tree(&out.join("lidar_2d"), &pred);
    std::fs::copy(
        pred.join("2011_09_26_0052_0000000000.npy"),
        pred.join("2011_09_26_0052_0000000099.npy"),
    )
    .unwrap();
    let (code, stdout, stderr) =
        run_text(&["score", "--gt", s(&out), "--pred", s(&pred), "--json"]);
    assert_eq!(code, 0);
    let j: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(
        j["predictions_without_truth"],
        serde_json::json!(["2011_09_26_0052_0000000099"])
    );
    assert!(
        stderr.contains("not in the ground truth, not scored"),
        "{stderr}"
    );
}

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
