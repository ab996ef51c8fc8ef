//! Bad input: each gets an error naming the file; the rest of the batch is converted; the exit
//! status is 3 when a frame failed.

use std::path::{Path, PathBuf};
use std::time::Duration;

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
    let e = fails_with(
        &[
            "convert",
            s(&fixtures()),
            "--out",
            s(&t.path().join("o")),
            "--fov-deg",
            "400",
        ],
        "config",
    );
    assert_eq!(e["exit"], 2, "an option out of range is a usage error");
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
    assert!(failures(&j).contains("2011_09_26_drive_0052_sync"), "{j}");
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
    assert!(failures(&j).contains("not valid UTF-8"), "{j}");
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
    kitti2pgm::format::png::write(&png, &kitti2pgm::raster::RgbImage::new(100, 50)).unwrap();
    let (code, j, _) = convert_json(&root, &t.path().join("out"), &["--rgb"]);
    assert_eq!(code, 3);
    assert_eq!(j["frames_converted"], 2);
    let f = failures(&j);
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
    let f = failures(&j);
    assert!(
        f.contains("calib_velo_to_cam.txt") && f.contains("key `T` appears twice"),
        "{f}"
    );
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
    let out = t.path().join("out");
    let root = fixtures();
    let args = [
        "convert",
        s(&root),
        "--out",
        s(&out),
        "--class-map",
        s(&yaml),
    ];
    assert_eq!(fails_with(&args, "config")["exit"], 2);
    assert!(
        !t.path().join("out/lidar_2d").exists()
            || tree_bytes(&t.path().join("out/lidar_2d")).is_empty()
    );
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
        let (root, out) = (fixtures(), t.path().join("out"));
        let e = fails_with(&["convert", s(&root), "--out", s(&out), &arg], "config");
        assert_eq!(e["exit"], 2, "{flag} {value}");
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
        assert_eq!(fails_with(&split, "config")["exit"], 2, "{args:?}");
        let mut convert = vec!["convert", s(&root), "--out", s(&out), "--format", "mcap"];
        convert.extend(&args);
        assert_eq!(fails_with(&convert, "config")["exit"], 2, "{args:?}");
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
    // The real images rewritten as 8-bit grey and as 16-bit RGB, by the png crate.
    let write = |path: &std::path::Path,
                 color: png::ColorType,
                 depth: png::BitDepth,
                 data: &[u8],
                 (w, h)| {
        let mut enc = png::Encoder::new(std::fs::File::create(path).unwrap(), w, h);
        enc.set_color(color);
        enc.set_depth(depth);
        enc.write_header().unwrap().write_image_data(data).unwrap();
    };
    let img = kitti2pgm::raster::read(&png).unwrap();
    let grey: Vec<u8> = img
        .pixels()
        .map(|p| ((p[0] as u16 + p[1] as u16 + p[2] as u16) / 3) as u8)
        .collect();
    write(
        &png,
        png::ColorType::Grayscale,
        png::BitDepth::Eight,
        &grey,
        img.dimensions(),
    );
    let png16 = raw.join("2011_09_26/2011_09_26_drive_0001_sync/image_02/data/0000000045.png");
    let img = kitti2pgm::raster::read(&png16).unwrap();
    let wide: Vec<u8> = img
        .as_raw()
        .iter()
        .flat_map(|&v| (v as u16 * 257).to_be_bytes())
        .collect();
    write(
        &png16,
        png::ColorType::Rgb,
        png::BitDepth::Sixteen,
        &wide,
        img.dimensions(),
    );
    let (code, j, e) = convert_json(&raw, &t.path().join("out"), &["--rgb"]);
    assert_eq!(code, 3, "{e}");
    assert!(
        e.contains("0000000000.png") && e.contains("8-bit RGB"),
        "{e}"
    );
    assert!(e.contains("0000000045.png") && e.contains("Rgb16"), "{e}");
    assert_eq!(j["frames_failed"], 2, "{j}");
}
