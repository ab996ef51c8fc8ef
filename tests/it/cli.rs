//! The binary end to end on the fixtures: outputs, summary, determinism, preview.

use kitti2pgm::format::npy::read_f32;

use crate::util::*;

#[test]
fn converts_the_fixtures() {
    let t = tmp();
    let out = t.path().join("out");
    let (code, stdout, stderr) = run_text(&["convert", s(&fixtures()), "--out", s(&out), "--json"]);
    assert_eq!(code, 0, "{stderr}");
    let j: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(j["frames_converted"], 3);
    assert_eq!(j["frames_failed"], 0);
    assert_eq!(j["ring_fallbacks"], 0);
    assert!(j["labelled_points"]["car"].as_u64().unwrap() > 1000);
    let ids = [
        "2011_09_26_0001_0000000000",
        "2011_09_26_0001_0000000045",
        "2011_09_26_0052_0000000000",
    ];
    for id in ids {
        let (shape, data) = read_f32(&out.join(format!("lidar_2d/{id}.npy"))).unwrap();
        assert_eq!(shape, vec![64, 512, 6]);
        // range is the norm of x, y, z; labels are class ids; empty cells are all zero.
        for cell in data.chunks_exact(6) {
            let r = (cell[0] * cell[0] + cell[1] * cell[1] + cell[2] * cell[2]).sqrt();
            assert!((cell[4] - r).abs() <= 1e-4 * r.max(1.0));
            assert!([0.0, 1.0, 2.0, 3.0].contains(&cell[5]));
            if cell[4] == 0.0 {
                assert!(cell.iter().all(|v| *v == 0.0));
            }
        }
    }
    // One u32 per point of the .bin, class in the low 16 bits.
    let bin = fixture_drive(1).join("velodyne_points/data/0000000000.bin");
    let label = out.join("labels/2011_09_26_drive_0001_sync/0000000000.label");
    let lb = std::fs::read(&label).unwrap();
    assert_eq!(
        lb.len(),
        std::fs::metadata(&bin).unwrap().len() as usize / 4
    );
    let words: Vec<u32> = lb
        .chunks_exact(4)
        .map(|c| u32::from_le_bytes(c.try_into().unwrap()))
        .collect();
    assert!(
        words.iter().any(|w| w & 0xffff == 1 && w >> 16 > 0),
        "car points carry an instance id"
    );
    assert!(words.iter().all(|w| w & 0xffff <= 3));
    // No temporary file is left behind.
    assert!(tree_bytes(&out).iter().all(|(p, _)| !p.contains(".tmp-")));
}

#[test]
fn rgb_output_has_nine_channels_in_unit_range() {
    let t = tmp();
    let out = t.path().join("out");
    let (code, stdout, stderr) = run_text(&[
        "convert",
        s(&fixture_drive(1)),
        "--out",
        s(&out),
        "--rgb",
        "--json",
    ]);
    assert_eq!(code, 0, "{stderr}");
    let j: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    let filled = j["filled_cells"].as_u64().unwrap();
    let rgb = j["rgb_cells"].as_u64().unwrap();
    // The camera sees less than the 90-degree map (narrower and not above the horizon).
    assert!(rgb > filled / 3 && rgb < filled, "{rgb} of {filled}");
    let (shape, data) = read_f32(&out.join("lidar_2d/2011_09_26_0001_0000000000.npy")).unwrap();
    assert_eq!(shape, vec![64, 512, 9]);
    assert!(data
        .chunks_exact(9)
        .all(|c| c[6..].iter().all(|v| (0.0..=1.0).contains(v))));
    // Columns near the edges of the 90-degree map are outside the camera's ~82-degree view.
    let coloured_at = |col: usize| {
        (0..64).any(|r| {
            data[(r * 512 + col) * 9 + 6..(r * 512 + col) * 9 + 9]
                .iter()
                .any(|v| *v > 0.0)
        })
    };
    assert!(coloured_at(256) && !coloured_at(0));
}

#[test]
fn output_is_identical_whatever_the_thread_count() {
    let t = tmp();
    let (a, b) = (t.path().join("a"), t.path().join("b"));
    let root = raw_root();
    assert_eq!(
        run_text(&[
            "--threads",
            "1",
            "convert",
            s(&root),
            "--out",
            s(&a),
            "--rgb"
        ])
        .0,
        0
    );
    assert_eq!(
        run_text(&[
            "--threads",
            "3",
            "convert",
            s(&root),
            "--out",
            s(&b),
            "--rgb"
        ])
        .0,
        0
    );
    let (ta, tb) = (tree_bytes(&a), tree_bytes(&b));
    assert!(!ta.is_empty());
    assert!(ta == tb, "outputs differ between 1 and 3 threads");
}

#[test]
fn all_frames_and_selection() {
    let t = tmp();
    let out = t.path().join("out");
    // Drive 0052's fixture frame 0 has tracklet poses; drop the tracklets: the frame is skipped
    // by default and converted (all background) with --all-frames.
    let root = fixture_copy(t.path());
    std::fs::remove_file(root.join("2011_09_26/2011_09_26_drive_0052_sync/tracklet_labels.xml"))
        .unwrap();
    let (code, stdout, _) = run_text(&["convert", s(&root), "--out", s(&out), "--json"]);
    assert_eq!(code, 0);
    let j: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(j["frames_converted"], 2);
    assert_eq!(j["frames_skipped"]["drive has no tracklet_labels.xml"], 1);
    let (code, stdout, _) = run_text(&[
        "convert",
        s(&root),
        "--out",
        s(&out),
        "--json",
        "--all-frames",
    ]);
    assert_eq!(code, 0);
    let j: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(j["frames_converted"], 3);
}

#[test]
fn summary_table_and_preview() {
    let t = tmp();
    let out = t.path().join("out");
    let (code, stdout, _) =
        run_text(&["convert", s(&fixture_drive(52)), "--out", s(&out), "--rgb"]);
    assert_eq!(code, 0);
    assert!(
        stdout.contains("frames converted") && stdout.contains("car"),
        "{stdout}"
    );
    let npy = out.join("lidar_2d/2011_09_26_0052_0000000000.npy");
    let png = t.path().join("p.png");
    assert_eq!(run_text(&["preview", s(&npy), "--out", s(&png)]).0, 0);
    let img = kitti2pgm::raster::read(&png).unwrap();
    assert_eq!((img.width(), img.height()), (512, 4 * 128 + 3 * 4));
    // The label panel (last) shows car green somewhere.
    let green = kitti2pgm::label::ClassMap::kitti_paper().colour(1);
    assert!((0..512).any(|x| (392..520).any(|y| img.get_pixel(x, y).0 == green)));
    // A folder output for several inputs.
    let dir = t.path().join("pngs");
    assert_eq!(
        run_text(&["preview", s(&npy), s(&npy), "--out", s(&dir)]).0,
        0
    );
    assert!(dir.join("2011_09_26_0052_0000000000.png").is_file());
}

#[test]
fn help_explains_the_commands() {
    let (code, stdout, _) = run_text(&["--help"]);
    assert_eq!(code, 0);
    assert!(stdout.contains("convert") && stdout.contains("preview"));
    let (_, stdout, _) = run_text(&["convert", "--help"]);
    for flag in [
        "--rgb",
        "--camera",
        "--all-frames",
        "--fov-deg",
        "--row-mode",
        "--threads",
        "--json",
    ] {
        assert!(stdout.contains(flag), "convert --help lacks {flag}");
    }
    assert_eq!(run_text(&["convert"]).0, 2, "usage errors exit 2");
}

/// The in-process conversion the other tests use as a shortcut writes what the binary writes,
/// byte for byte (the summary's timing aside).
#[test]
fn in_process_conversion_is_the_binarys() {
    let t = tmp();
    let (cli, lib) = (t.path().join("cli"), t.path().join("lib"));
    let (code, _, e) = run_text(&["convert", s(&fixtures()), "--out", s(&cli), "--no-progress"]);
    assert_eq!(code, 0, "{e}");
    convert_fixtures_in_process(&lib);
    let strip = |tree: Vec<(String, Vec<u8>)>| -> Vec<(String, Vec<u8>)> {
        tree.into_iter()
            .map(|(p, b)| {
                if p.ends_with(".json") {
                    let mut j: serde_json::Value = serde_json::from_slice(&b).unwrap();
                    j.as_object_mut().unwrap().remove("seconds");
                    (p, j.to_string().into_bytes())
                } else {
                    (p, b)
                }
            })
            .collect()
    };
    let (a, b) = (strip(tree_bytes(&cli)), strip(tree_bytes(&lib)));
    assert_eq!(
        a.iter().map(|(p, _)| p).collect::<Vec<_>>(),
        b.iter().map(|(p, _)| p).collect::<Vec<_>>()
    );
    for ((p, x), (_, y)) in a.iter().zip(&b) {
        assert!(x == y, "{p} differs: {}", String::from_utf8_lossy(y));
    }
}
