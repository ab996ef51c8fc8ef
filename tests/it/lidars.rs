//! Other sensors than KITTI's HDL-64E: the PCD and flat readers and the sensor model (beam
//! tables, presets) on the real scans of `fixtures/lidars` and `../shared/lidars`.

use std::path::{Path, PathBuf};

use kitti2pgm::sensor::{self, presets::Sensor, RingOrder, SensorModel};
use kitti2pgm::source::{self, pcd, Scan};

/// `../shared/lidars` where present, else `fixtures/lidars` (a subset).
fn lidars() -> PathBuf {
    let shared = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/lidars");
    if shared.join("hesai").is_dir() {
        shared
    } else {
        super::util::fixture("lidars")
    }
}

/// The scans with their sensors: (scan, calibration file, preset).
fn scans() -> Vec<(PathBuf, PathBuf, Sensor)> {
    let root = lidars();
    let all = [
        (
            "velodyne/vlp16_1673400472138016708.pcd",
            "velodyne/VLP16.yaml",
            Sensor::Vlp16,
        ),
        (
            "velodyne/vlp32_1713492677464078412.pcd",
            "velodyne/VLP32.yaml",
            Sensor::Vlp32c,
        ),
        (
            "hesai/Pandar40P_1673400149711850138.pcd",
            "hesai/Pandar40P.csv",
            Sensor::Pandar40p,
        ),
        (
            "hesai/Pandar64_1673403880898440686.pcd",
            "hesai/Pandar64.csv",
            Sensor::Pandar64,
        ),
        (
            "hesai/PandarQT64_1673401196087570870.pcd",
            "hesai/PandarQT64.csv",
            Sensor::PandarQt64,
        ),
        (
            "hesai/PandarXT16_1732848128093928016.pcd",
            "hesai/PandarXT16.csv",
            Sensor::PandarXt16,
        ),
        (
            "hesai/PandarXT32_1673400678101968885.pcd",
            "hesai/PandarXT32.csv",
            Sensor::PandarXt32,
        ),
        (
            "hesai/PandarXT32M_1660893203292679064.pcd",
            "hesai/PandarXT32M.csv",
            Sensor::PandarXt32m,
        ),
    ];
    all.iter()
        .map(|(s, c, p)| (root.join(s), root.join(c), *p))
        .filter(|(s, _, _)| s.is_file())
        .collect()
}

/// Largest difference between a point's elevation and its row's beam, degrees.
fn worst_fit(cloud: &Scan, model: &SensorModel, rows: &[u8]) -> f64 {
    cloud
        .points
        .iter()
        .zip(rows)
        .map(|(p, &r)| {
            let e = (p.z as f64)
                .atan2((p.x as f64).hypot(p.y as f64))
                .to_degrees();
            (e - model.table.beams()[r as usize].elevation.0).abs()
        })
        .fold(0.0, f64::max)
}

#[test]
fn every_point_of_every_real_scan_is_on_one_beam_of_its_table() {
    let scans = scans();
    assert!(scans.len() >= 3, "fixtures/lidars holds three scans");
    for (scan, calib, preset) in scans {
        let cloud = pcd::read(&scan).unwrap();
        assert!(cloud.len() > 10_000, "{}", scan.display());
        for model in [
            sensor::read_calibration(&calib).unwrap(),
            preset.model_table(),
        ] {
            let rows = model.assign(&cloud.points);
            assert_eq!(rows.off_model, 0, "{} with {}", scan.display(), model.name);
            // Within 1e-3 degrees of the beam (float32 coordinates): no row holds two beams.
            let worst = worst_fit(&cloud, &model, &rows.rows);
            assert!(worst < 1e-3, "{}: {worst} deg off", scan.display());
        }
    }
}

#[test]
fn the_vlp16_rows_are_its_channels() {
    let root = lidars();
    let cloud = pcd::read(&root.join("velodyne/vlp16_1673400472138016708.pcd")).unwrap();
    assert_eq!(cloud.file_len, 14_831);
    let channel = cloud.ring.as_ref().expect("the scan has a channel field");
    let model = Sensor::Vlp16.model_table();
    let by_ring = sensor::ring_rows(channel, 16, RingOrder::BottomUp, Path::new("vlp16")).unwrap();
    let by_elevation = model.assign(&cloud.points);
    assert!(
        by_ring == by_elevation.rows,
        "the channel field and the table disagree"
    );
    // The driver's channel counts from the lowest beam; the YAML's laser 0 is -15 deg too
    // (row 15), its laser 1 +1 deg (row 7): rows run top to bottom.
    assert_eq!(model.table.row_of_id(0), Some(15));
    assert_eq!(model.table.row_of_id(1), Some(7));
    let e = sensor::ring_rows(&[3, 16], 16, RingOrder::BottomUp, Path::new("c.pcd"))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("c.pcd") && e.contains("point 1 has ring 16"),
        "{e}"
    );
}

#[test]
fn the_nuscenes_keyframe_has_its_ring_column_and_32_beams() {
    let dir = lidars().join("nuscenes");
    let path = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| p.to_string_lossy().ends_with(".pcd.bin"))
        .unwrap();
    let cloud = source::read_file(&path, None).unwrap();
    assert_eq!(cloud.file_len, 34_688);
    let ring = cloud.ring.as_ref().unwrap();
    assert_eq!(ring.iter().copied().max(), Some(31));
    // Ring 0 is the lowest beam: its points lie below those of ring 31.
    let median = |r: u16| {
        let mut e: Vec<f64> = cloud
            .points
            .iter()
            .zip(ring)
            .filter(|(_, &q)| q == r)
            .map(|(p, _)| (p.z as f64).atan2((p.x as f64).hypot(p.y as f64)))
            .collect();
        e.sort_by(f64::total_cmp);
        e[e.len() / 2]
    };
    assert!(median(0) < median(15) && median(15) < median(31));
    assert!(cloud.has_intensity);
}

#[test]
fn ouster_metadata_gives_the_beams_the_origin_offset_and_the_sensor_frame() {
    let path = lidars().join("ouster/OS-1-32-G_v2.1.1_1024x10.json");
    let ouster = sensor::ouster::read_model(&path).unwrap();
    let (model, format) = (&ouster.sensor, &ouster.format);
    assert_eq!(model.name, "OS-1-32-G");
    assert_eq!(model.beams(), 32);
    assert_eq!(format.columns_per_frame, 1024);
    assert!((model.beam_origin_offset - 0.015806).abs() < 1e-9);
    // 180 degrees about z, 36.18 mm up.
    let t = model.lidar_to_points;
    assert!((t.translation.vector.z - 0.03618).abs() < 1e-9);
    let x = t.rotation * kitti2pgm::geom::na::Vector3::x();
    assert!((x.x + 1.0).abs() < 1e-12);
    // A point straight along beam 0 (12.75 deg) at 10 m, from its beam origin, written in the
    // sensor frame, is on beam 0.
    let alt = 12.75f64.to_radians();
    let lidar =
        kitti2pgm::geom::na::Point3::new(0.015806 + 10.0 * alt.cos(), 0.0, 10.0 * alt.sin());
    let s = t * lidar;
    let p = kitti2pgm::geom::Point3::new(s.x as f32, s.y as f32, s.z as f32);
    let rows = model.assign(&[p]);
    assert_eq!((rows.rows[0], rows.off_model), (0, 0));
}

/// Ouster's own columns, on points placed as the SDK's `XYZLut` places each pixel (beam `u`,
/// measurement id `m`; checked against the SDK itself, on the real captures, by the Python tests):
/// every pixel comes back at its beam's row and its destaggered column, `(m + shift[u]) mod W`.
#[test]
fn ouster_columns_undo_the_sdk_s_lookup_table() {
    use kitti2pgm::geom::{na, Point3};
    let path =
        super::util::fixture("lidars/ouster/OS-1-128_767798045_1024x10_20230712_120049.json");
    let ouster = sensor::ouster::read_model(&path).unwrap();
    let (model, format) = (&ouster.sensor, &ouster.format);
    let w = format.columns_per_frame;
    let n = model.beam_origin_offset;
    let (mut points, mut expected) = (Vec::new(), Vec::new());
    for (u, beam) in model.table.beams().iter().enumerate() {
        let (alt, az) = (beam.elevation.to_radians(), -beam.azimuth.to_radians());
        for m in (0..w).step_by(3) {
            let e = std::f64::consts::TAU * (1.0 - m as f64 / w as f64);
            let d = na::Vector3::new(
                alt.cos() * (e + az).cos(),
                alt.cos() * (e + az).sin(),
                alt.sin(),
            );
            // Ranges from 0.5 m to 80 m.
            let r = 0.5 + ((u * 7 + m * 13) % 800) as f64 / 10.0;
            let q = na::Point3::from(d * (r - n) + na::Vector3::new(e.cos(), e.sin(), 0.0) * n);
            let p = model.lidar_to_points * q;
            points.push(Point3::new(p.x as f32, p.y as f32, p.z as f32));
            let shift = format.pixel_shift_by_row[beam.id as usize];
            expected.push((u as u8, (m as i64 + shift).rem_euclid(w as i64) as u16));
        }
    }
    let rows = model.assign(&points);
    assert_eq!(rows.off_model, 0);
    let cols = ouster.columns(&points, &rows.rows);
    let got: Vec<(u8, u16)> = rows.rows.into_iter().zip(cols).collect();
    assert_eq!(got, expected);
    assert!(
        format.pixel_shift_by_row.iter().any(|&s| s < 0),
        "negative shifts tested too"
    );
}

/// A PCD of `body` after a header for `fields` (name, size, type) and `n` points.
fn pcd_file(fields: &[(&str, usize, char)], n: usize, data: &str, body: &[u8]) -> Vec<u8> {
    let names: Vec<&str> = fields.iter().map(|f| f.0).collect();
    let sizes: Vec<String> = fields.iter().map(|f| f.1.to_string()).collect();
    let types: Vec<String> = fields.iter().map(|f| f.2.to_string()).collect();
    let mut out = format!(
        "# .PCD v0.7\nVERSION 0.7\nFIELDS {}\nSIZE {}\nTYPE {}\nCOUNT {}\nWIDTH {n}\nHEIGHT 1\n\
         VIEWPOINT 0 0 0 1 0 0 0\nPOINTS {n}\nDATA {data}\n",
        names.join(" "),
        sizes.join(" "),
        types.join(" "),
        vec!["1"; fields.len()].join(" ")
    )
    .into_bytes();
    out.extend_from_slice(body);
    out
}

#[test]
fn pcd_field_order_types_and_nan_points() {
    // z, a padding byte, intensity u8, x as f64, y, ring u16 and a NaN point.
    let fields = [
        ("z", 4, 'F'),
        ("pad", 1, 'U'),
        ("intensity", 1, 'U'),
        ("x", 8, 'F'),
        ("y", 4, 'F'),
        ("ring", 2, 'U'),
    ];
    let mut body = Vec::new();
    for (i, (x, y, z)) in [
        (1.0f64, 2.0f32, 3.0f32),
        (f64::NAN, 0.0, 0.0),
        (4.0, 5.0, 6.0),
    ]
    .into_iter()
    .enumerate()
    {
        body.extend_from_slice(&z.to_le_bytes());
        body.push(0);
        body.push(10 * i as u8);
        body.extend_from_slice(&x.to_le_bytes());
        body.extend_from_slice(&y.to_le_bytes());
        body.extend_from_slice(&(i as u16 + 7).to_le_bytes());
    }
    let bytes = pcd_file(&fields, 3, "binary", &body);
    let c = pcd::decode(&bytes, Path::new("t.pcd")).unwrap();
    assert_eq!(c.points.len(), 2);
    assert_eq!(c.dropped, vec![1]);
    assert_eq!(c.points[1].coords.as_slice(), &[4.0, 5.0, 6.0]);
    assert_eq!(c.intensity, vec![0.0, 20.0]);
    assert_eq!(c.ring, Some(vec![7, 9]));
    // The same points as text.
    let text = "3 0 0 1 2 7\nnan 0 10 nan 0 8\n6 0 20 4 5 9\n";
    let a = pcd::decode(
        &pcd_file(&fields, 3, "ascii", text.as_bytes()),
        Path::new("a.pcd"),
    )
    .unwrap();
    assert_eq!(a, c);
}

#[test]
fn bad_pcd_files_are_named_with_what_is_wrong() {
    let f = [("x", 4, 'F'), ("y", 4, 'F'), ("z", 4, 'F')];
    let p = Path::new("bad.pcd");
    let err = |b: &[u8]| pcd::decode(b, p).unwrap_err().to_string();
    let body = vec![0u8; 24];
    // Truncated: the header says 3 points, the data holds 2.
    let e = err(&pcd_file(&f, 3, "binary", &body));
    assert!(
        e.contains("bad.pcd") && e.contains("24") && e.contains("36"),
        "{e}"
    );
    // A header that lies about its field sizes (SIZE 3 for a float).
    let e = err(&pcd_file(
        &[("x", 3, 'F'), ("y", 4, 'F'), ("z", 4, 'F')],
        2,
        "binary",
        &body,
    ));
    assert!(e.contains("not a PCD type"), "{e}");
    // An unknown type letter.
    let e = err(&pcd_file(
        &[("x", 4, 'Q'), ("y", 4, 'F'), ("z", 4, 'F')],
        2,
        "binary",
        &body,
    ));
    assert!(e.contains("TYPE Q"), "{e}");
    // POINTS against WIDTH x HEIGHT.
    let mut lie = pcd_file(&f, 2, "binary", &body);
    let s = String::from_utf8_lossy(&lie).replace("POINTS 2", "POINTS 5");
    lie = s.into_bytes();
    let e = err(&lie);
    assert!(e.contains("POINTS is 5"), "{e}");
    // No z field.
    let e = err(&pcd_file(
        &[("x", 4, 'F'), ("y", 4, 'F')],
        3,
        "binary",
        &body,
    ));
    assert!(e.contains("no z field"), "{e}");
    // Damaged compressed data: sizes that do not add up, then garbage.
    let mut cmp = 16u32.to_le_bytes().to_vec();
    cmp.extend_from_slice(&24u32.to_le_bytes());
    cmp.extend_from_slice(&[0xff; 16]);
    let e = err(&pcd_file(&f, 2, "binary_compressed", &cmp));
    assert!(
        e.contains("damaged") && e.contains("binary_compressed"),
        "{e}"
    );
    let e = err(&pcd_file(&f, 2, "binary_compressed", &cmp[..12]));
    assert!(e.contains("truncated"), "{e}");
    // Not a PCD at all.
    let e = err(b"\x89PNG\r\n\x1a\n");
    assert!(e.contains("not a PCD file"), "{e}");
    // An ascii line with a missing value.
    let e = err(&pcd_file(&f, 2, "ascii", b"1 2 3\n4 5\n"));
    assert!(e.contains("point 1 has 2 values"), "{e}");
}

#[test]
fn bad_calibration_tables_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let write = |name: &str, text: &str| {
        let p = dir.path().join(name);
        std::fs::write(&p, text).unwrap();
        p
    };
    let e = sensor::read_calibration(&write("none.csv", "Laser id,Elevation,Azimuth\n"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("none.csv") && e.contains("no beam"), "{e}");
    let e = sensor::read_calibration(&write(
        "two.csv",
        "Laser id,Elevation,Azimuth\n1,2.0,0\n2,2.0,0\n",
    ))
    .unwrap_err()
    .to_string();
    assert!(e.contains("one elevation"), "{e}");
    let e = sensor::read_calibration(&write("x.csv", "a,b\n1,2\n"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("Hesai"), "{e}");
    let e = sensor::read_calibration(&write("v.yaml", "lasers: []\nnum_lasers: 16\n"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("num_lasers is 16"), "{e}");
    let e = sensor::read_calibration(&write("o.json", "{\"beam_altitude_angles\": [1, 2]}"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("beam_azimuth_angles"), "{e}");
}

#[test]
fn a_cloud_outside_the_sensor_frame_leaves_its_points_off_the_model() {
    let root = lidars();
    // The Pandar40P scan in a vehicle frame (1.8 m above the sensor): its own table no longer
    // fits.
    let mut lifted = pcd::read(&root.join("hesai/Pandar40P_1673400149711850138.pcd")).unwrap();
    for p in &mut lifted.points {
        p.z += 1.8;
    }
    let shifted = Sensor::Pandar40p.model_table().assign(&lifted.points);
    assert!(shifted.off_model as usize > lifted.len() / 4);
}

/// A sequence folder holding `scans` (file name in `velodyne/`, source file).
fn sequence_of(dir: &Path, scans: &[(&str, &Path)]) -> PathBuf {
    let root = dir.join("own");
    let v = root.join("sequences/00/velodyne");
    std::fs::create_dir_all(&v).unwrap();
    for (name, from) in scans {
        std::fs::copy(from, v.join(name)).unwrap();
    }
    root
}

#[test]
fn convert_makes_one_row_per_beam_from_the_ring_field_or_the_table() {
    use super::util::{convert_json, s, tmp};
    let t = tmp();
    let root = lidars();
    let vlp = root.join("velodyne/vlp16_1673400472138016708.pcd");
    let p40 = root.join("hesai/Pandar40P_1673400149711850138.pcd");
    let seq = sequence_of(t.path(), &[("000000.pcd", &vlp)]);
    // VLP-16 by its ring (channel) field: every point in the 360-degree map, on its channel's row.
    let out = t.path().join("vlp");
    let (code, j, err) = convert_json(
        &seq,
        &out,
        &["--sensor", "vlp16", "--all-frames", "--cols", "2048"],
    );
    assert_eq!(code, 0, "{err}");
    assert_eq!(j["params"]["map"]["spec"]["rows"], 16);
    assert_eq!(j["params"]["map"]["sensor"]["source"]["preset"], "vlp16");
    assert_eq!(j["ring_field_frames"], 1);
    assert_eq!(j["off_model"], 0);
    assert_eq!(j["in_fov"], 14_831);
    let (shape, data) =
        kitti2pgm::format::npy::read_f32(&out.join("lidar_2d/00_000000.npy")).unwrap();
    assert_eq!(shape, vec![16, 2048, 6]);
    // Each filled cell's point has the elevation of its row's beam.
    let model = Sensor::Vlp16.model_table();
    for (cell, v) in data.chunks_exact(6).enumerate() {
        if v[4] > 0.0 {
            let e = (v[2] as f64)
                .atan2((v[0] as f64).hypot(v[1] as f64))
                .to_degrees();
            let beam = model.table.beams()[cell / 2048].elevation.0;
            assert!(
                (e - beam).abs() < 1e-3,
                "cell {cell}: {e} deg on the {beam} deg row"
            );
        }
    }
    // A re-run keeps the frame (the .label holds one label per point of the PCD).
    let (code, j, _) = convert_json(
        &seq,
        &out,
        &["--sensor", "vlp16", "--all-frames", "--cols", "2048"],
    );
    assert_eq!((code, j["resumed_frames"].as_u64()), (0, Some(1)));
    // Pandar40P has no ring field: rows by its calibration table.
    let seq = sequence_of(&t.path().join("p"), &[("000000.pcd", &p40)]);
    let calib = root.join("hesai/Pandar40P.csv");
    let out = t.path().join("p40");
    let (code, j, err) = convert_json(
        &seq,
        &out,
        &["--sensor-calibration", s(&calib), "--all-frames"],
    );
    assert_eq!(code, 0, "{err}");
    assert_eq!(j["params"]["map"]["spec"]["rows"], 40);
    assert_eq!(j["beam_table_frames"], 1);
    assert_eq!(j["beam_table_frame_ids"], serde_json::json!(["00_000000"]));
    assert_eq!(j["off_model"], 0);
    assert!(j["params"]["map"]["sensor"]["source"]["file"]["digest"].is_string());
}

#[test]
fn convert_names_a_bad_scan_of_another_sensor_and_finishes_the_rest() {
    use super::util::{convert_json, tmp};
    let t = tmp();
    let vlp = lidars().join("velodyne/vlp16_1673400472138016708.pcd");
    let seq = sequence_of(t.path(), &[("000000.pcd", &vlp), ("000001.pcd", &vlp)]);
    // Frame 1 truncated.
    let bad = seq.join("sequences/00/velodyne/000001.pcd");
    let bytes = std::fs::read(&bad).unwrap();
    std::fs::write(&bad, &bytes[..bytes.len() - 100]).unwrap();
    let out = t.path().join("out");
    let (code, j, err) = convert_json(&seq, &out, &["--sensor", "vlp16", "--all-frames"]);
    assert_ne!(code, 0, "{err}");
    assert_eq!(j["frames_converted"], 1);
    let failure = j["failures"].to_string();
    assert!(
        failure.contains("000001.pcd") && failure.contains("bytes"),
        "{failure}"
    );
    // A ring field beyond the sensor's beams: the VLP-16's channels read as a 16-beam... of 8.
    let calib = t.path().join("eight.csv");
    let mut csv = "Laser id,Elevation,Azimuth\n".to_string();
    for i in 1..=8 {
        csv += &format!("{i},{},0\n", 15 - 4 * i);
    }
    std::fs::write(&calib, csv).unwrap();
    let out = t.path().join("out8");
    let (code, j, _) = convert_json(
        &seq,
        &out,
        &[
            "--sensor-calibration",
            calib.to_str().unwrap(),
            "--all-frames",
        ],
    );
    assert_ne!(code, 0);
    let failure = j["failures"].to_string();
    assert!(
        failure.contains("000000.pcd") && failure.contains("8 beams"),
        "{failure}"
    );
}

#[test]
fn an_unknown_sensor_or_a_bad_calibration_stops_before_any_work() {
    use super::util::{fails_with, fixture, run_text, s, tmp};
    let t = tmp();
    let seq = fixture("own_lidar");
    let out = t.path().join("out");
    let (code, _, err) = run_text(&["convert", s(&seq), "--out", s(&out), "--sensor", "vlp17"]);
    assert_eq!(code, 2);
    assert!(err.contains("vlp16") && err.contains("pandar40p"), "{err}");
    let bad = t.path().join("bad.csv");
    std::fs::write(&bad, "Laser id,Elevation,Azimuth\n1,2,0\n2,2,0\n").unwrap();
    let e = fails_with(
        &[
            "convert",
            s(&seq),
            "--out",
            s(&out),
            "--sensor-calibration",
            s(&bad),
        ],
        "format",
    );
    assert!(
        e["message"].as_str().unwrap().contains("one elevation"),
        "{e}"
    );
    assert!(!out.join("lidar_2d").exists());
}

#[test]
fn a_pcd_beside_the_bin_of_its_frame_is_named_not_read() {
    use kitti2pgm::source::kitti::Drive;
    let t = super::util::tmp();
    let vlp = lidars().join("velodyne/vlp16_1673400472138016708.pcd");
    let bin = super::util::fixture("semantickitti/sequences/00/velodyne/000000.bin");
    let seq = sequence_of(
        t.path(),
        &[
            ("000000.pcd", &vlp),
            ("000000.bin", &bin),
            ("000001.pcd", &vlp),
        ],
    );
    let drive = Drive::sequence(&seq.join("sequences/00")).unwrap();
    let listing = drive.scan_listing().unwrap();
    assert_eq!(listing.frames, vec![0, 1]);
    let dir = seq.join("sequences/00/velodyne");
    assert_eq!(listing.not_frames, vec![dir.join("000000.pcd")]);
    assert_eq!(drive.scan_path(0), dir.join("000000.bin"));
    assert_eq!(drive.scan_path(1), dir.join("000001.pcd"));
}

/// Issue 47, defect 5 and the smaller ones on PCD: a real VLP-16 scan with a `COUNT 0` padding
/// field added to its header (zero bytes, as three.js's PCDLoader reads it) and bytes after its
/// points reads as the scan itself, the trailing bytes counted; ascii values outside their
/// declared type and an unknown DATA are named plainly.
#[test]
fn zero_wide_fields_trailing_bytes_and_ascii_ranges() {
    let path = lidars().join("velodyne/vlp16_1673400472138016708.pcd");
    let original = std::fs::read(&path).unwrap();
    let expected = pcd::read(&path).unwrap();
    let text = String::from_utf8_lossy(&original[..400]).to_string();
    let head_len = text.find("DATA binary\n").unwrap() + "DATA binary\n".len();
    let head = text[..head_len]
        .replace("time_stamp\n", "time_stamp _\n")
        .replace("SIZE 4 4 4 1 1 2 4 4 4 4\n", "SIZE 4 4 4 1 1 2 4 4 4 4 1\n")
        .replace("TYPE F F F U U U F F F U\n", "TYPE F F F U U U F F F U U\n")
        .replace(
            "COUNT 1 1 1 1 1 1 1 1 1 1\n",
            "COUNT 1 1 1 1 1 1 1 1 1 1 0\n",
        );
    assert_ne!(head, text[..head_len], "the header was rewritten");
    let mut padded = head.into_bytes();
    padded.extend_from_slice(&original[head_len..]);
    padded.extend_from_slice(&[0u8; 13]);
    let got = pcd::decode(&padded, Path::new("export.pcd")).unwrap();
    assert_eq!(got.trailing_bytes, 13);
    assert_eq!(
        Scan {
            trailing_bytes: 0,
            ..got
        },
        expected
    );
    let f = [
        ("x", 4, 'F'),
        ("y", 4, 'F'),
        ("z", 4, 'F'),
        ("intensity", 1, 'U'),
    ];
    let err = |b: &[u8]| pcd::decode(b, Path::new("a.pcd")).unwrap_err().to_string();
    for bad in ["300", "-1", "1.5"] {
        let body = format!("1 2 3 7\n4 5 6 {bad}\n");
        let e = err(&pcd_file(&f, 2, "ascii", body.as_bytes()));
        assert!(
            e.contains("a.pcd") && e.contains(bad) && e.contains("field intensity (U 1)"),
            "{e}"
        );
    }
    assert_eq!(
        pcd::decode(
            &pcd_file(&f, 1, "ascii", b"1 2 nan 255\n"),
            Path::new("a.pcd")
        )
        .unwrap()
        .dropped,
        [0]
    );
    for (data, shown) in [("binary_lz4", "\"binary_lz4\""), ("", "with no value")] {
        let e = err(&pcd_file(&f, 1, data, b""));
        assert!(e.contains(shown) && !e.contains("Some("), "{e}");
    }
}

/// Issue 47's smaller defects: a `--fields` declaration naming a field twice, or ending with a
/// field without a type, is refused; Ouster metadata with an offset of a kilometre is refused.
#[test]
fn implausible_declarations_and_metadata_are_refused() {
    for bad in ["x,y,z:f32,x:f32", "x,y,z:f32,intensity"] {
        let e = source::PointLayout::declared(bad).unwrap_err().to_string();
        assert!(e.contains("--fields"), "{e}");
    }
    assert!(source::PointLayout::declared("x,y,z:f32,_:u8,_:u8,ring:u16").is_ok());
    let meta = lidars().join("ouster/OS-1-32-G_v2.1.1_1024x10.json");
    let text = std::fs::read_to_string(&meta).unwrap();
    let dir = tempfile::tempdir().unwrap();
    for (from, to) in [
        (
            "\"lidar_origin_to_beam_origin_mm\": 15.806",
            "\"lidar_origin_to_beam_origin_mm\": 1e30",
        ),
        ("36.18", "1e30"),
    ] {
        assert!(text.contains(from), "{from}");
        let p = dir.path().join("bad.json");
        std::fs::write(&p, text.replacen(from, to, 1)).unwrap();
        let e = sensor::read_calibration(&p).unwrap_err().to_string();
        assert!(e.contains("bad.json") && e.contains("mm"), "{e}");
    }
}
