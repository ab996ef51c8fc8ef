//! REPORTS: `split` against SqueezeSeg's official lists, `stats` against independent counts.

use std::collections::BTreeSet;
use std::path::Path;

use kitti2pgm::format::npy::read_f32;
use kitti2pgm::source::kitti::tracklets::Tracklets;

use crate::util::*;

/// A skeleton KITTI tree from the 36 real tracklet files and the real per-drive frame counts:
/// empty placeholder scans, drive 0009's missing frames left out.
fn skeleton(shared: &Path, root: &Path) -> BTreeSet<u32> {
    let tsv = std::fs::read_to_string(shared.join("drive_frames.tsv")).unwrap();
    let mut drives = BTreeSet::new();
    for line in tsv.lines().skip(1) {
        let cols: Vec<&str> = line.split('\t').collect();
        let (drive, n, missing) = (cols[0], cols[1].parse::<u32>().unwrap(), cols[2]);
        let xml = shared
            .join("tracklets")
            .join(drive)
            .join("tracklet_labels.xml");
        if !xml.exists() {
            continue;
        }
        let gap = (missing != "-")
            .then_some(missing)
            .and_then(|m| m.split_once('-'))
            .map(|(a, b)| a.parse::<u32>().unwrap()..=b.parse::<u32>().unwrap());
        let dir = root.join("2011_09_26").join(drive);
        std::fs::create_dir_all(dir.join("velodyne_points/data")).unwrap();
        std::fs::copy(&xml, dir.join("tracklet_labels.xml")).unwrap();
        for f in 0..n {
            if gap.as_ref().is_some_and(|g| g.contains(&f)) {
                continue;
            }
            std::fs::write(dir.join(format!("velodyne_points/data/{f:010}.bin")), b"").unwrap();
        }
        drives.insert(drive[17..21].parse().unwrap());
    }
    drives
}

#[test]
#[ignore = "needs ../shared"]
fn split_reproduces_the_official_squeezeseg_lists() {
    let shared = needs_shared("kitti");
    let t = tmp();
    let root = t.path().join("raw");
    let drives = skeleton(&shared, &root);
    assert_eq!(drives.len(), 36);
    let out = t.path().join("out");
    let (code, stdout, stderr) = run_text(&["split", s(&root), "--out", s(&out), "--json"]);
    assert_eq!(code, 0, "{stderr}");
    let j: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    for name in ["all", "train", "val"] {
        let official =
            std::fs::read_to_string(shared.join(format!("squeezeseg/ImageSet/{name}.txt")))
                .unwrap();
        let expected: Vec<&str> = official
            .lines()
            .filter(|id| drives.contains(&id[11..15].parse::<u32>().unwrap()))
            .collect();
        let ours = std::fs::read_to_string(out.join(format!("ImageSet/{name}.txt"))).unwrap();
        let ours: Vec<&str> = ours.lines().collect();
        assert_eq!(ours.len(), expected.len(), "{name}.txt");
        assert!(ours == expected, "{name}.txt differs from SqueezeSeg's");
        assert_eq!(j[name], ours.len());
    }
}

#[test]
fn split_options_on_the_fixtures() {
    let t = tmp();
    let out = t.path().join("o");
    let lines = |name: &str| -> Vec<String> {
        std::fs::read_to_string(out.join(format!("ImageSet/{name}.txt")))
            .unwrap()
            .lines()
            .map(String::from)
            .collect()
    };
    assert_eq!(run_text(&["split", s(&fixtures()), "--out", s(&out)]).0, 0);
    assert_eq!(
        lines("all"),
        vec![
            "2011_09_26_0001_0000000000",
            "2011_09_26_0001_0000000045",
            "2011_09_26_0052_0000000000"
        ]
    );
    assert_eq!(lines("train").len(), 3);
    assert!(lines("val").is_empty());
    assert_eq!(
        run_text(&[
            "split",
            s(&fixtures()),
            "--out",
            s(&out),
            "--val-drives",
            "0052"
        ])
        .0,
        0
    );
    assert_eq!(lines("val"), vec!["2011_09_26_0052_0000000000"]);
    assert_eq!(lines("train").len(), 2);
    // A seeded random split is reproducible and keeps drives whole.
    let root = fixtures();
    let random_split = || {
        let args = [
            "split",
            s(&root),
            "--out",
            s(&out),
            "--random-val",
            "0.3",
            "--seed",
            "7",
        ];
        assert_eq!(run_text(&args).0, 0);
    };
    random_split();
    let (train, val) = (lines("train"), lines("val"));
    random_split();
    assert_eq!((lines("train"), lines("val")), (train.clone(), val.clone()));
    assert_eq!(train.len() + val.len(), 3);
    let drives = |v: &[String]| {
        v.iter()
            .map(|id| id[..15].to_string())
            .collect::<BTreeSet<_>>()
    };
    assert!(drives(&train).is_disjoint(&drives(&val)));
    assert_eq!(
        val,
        vec!["2011_09_26_0052_0000000000"],
        "0.3 of 3 frames is nearest to drive 0052's one frame"
    );
    let (code, _, stderr) = run_text(&[
        "split",
        s(&fixtures()),
        "--out",
        s(&out),
        "--val-drives",
        "zero",
    ]);
    assert_eq!(code, 2, "an option out of range is a usage error");
    assert!(stderr.contains("\"zero\" is not a drive"), "{stderr}");
}

#[test]
fn split_never_reads_point_data() {
    let t = tmp();
    let root = fixture_copy(t.path());
    std::fs::write(
        root.join("2011_09_26/2011_09_26_drive_0052_sync/velodyne_points/data/0000000000.bin"),
        b"xyz",
    )
    .unwrap();
    let (code, stdout, _) =
        run_text(&["split", s(&root), "--out", s(&t.path().join("o")), "--json"]);
    assert_eq!(code, 0);
    assert!(stdout.contains("\"all\": 3"), "{stdout}");
}

/// Converts the fixtures with colour and writes a train (drive 0001) / val (drive 0052) ImageSet.
fn converted(t: &Path) -> (std::path::PathBuf, std::path::PathBuf) {
    let out = t.join("conv");
    assert_eq!(
        run_text(&["convert", s(&fixtures()), "--out", s(&out), "--rgb"]).0,
        0
    );
    let sets = t.join("sets");
    assert_eq!(
        run_text(&[
            "split",
            s(&fixtures()),
            "--out",
            s(&sets),
            "--val-drives",
            "52"
        ])
        .0,
        0
    );
    (out, sets.join("ImageSet"))
}

#[test]
fn stats_agree_with_independent_counts() {
    let t = tmp();
    let (out, sets) = converted(t.path());
    let png = t.path().join("balance.png");
    let (code, stdout, stderr) = run_text(&[
        "stats",
        s(&out),
        "--imageset",
        s(&sets),
        "--raw",
        s(&fixtures()),
        "--json",
        "--chart",
        s(&png),
    ]);
    assert_eq!(code, 0, "{stderr}");
    let j: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(j["version"], 2);
    assert_eq!(j["split_order"], serde_json::json!(["train", "val"]));
    let names = ["background", "car", "pedestrian", "cyclist"];
    for (split, ids) in [
        (
            "train",
            vec!["2011_09_26_0001_0000000000", "2011_09_26_0001_0000000045"],
        ),
        ("val", vec!["2011_09_26_0052_0000000000"]),
    ] {
        let mut cells = [0u64; 4];
        let mut points = [0u64; 4];
        let mut range_sum = 0f64;
        let mut rows = [0u64; 64];
        for id in &ids {
            let (_, data) = read_f32(&out.join(format!("lidar_2d/{id}.npy"))).unwrap();
            for (i, c) in data.chunks_exact(9).enumerate() {
                if c[4] > 0.0 {
                    cells[c[5] as usize] += 1;
                    range_sum += c[4] as f64;
                    rows[i / 512] += 1;
                }
            }
            let (drive, frame) = (&id[11..15], &id[16..]);
            let lb = std::fs::read(out.join(format!(
                "labels/2011_09_26_drive_{drive}_sync/{frame}.label"
            )))
            .unwrap();
            for w in lb.chunks_exact(4) {
                points[(u32::from_le_bytes(w.try_into().unwrap()) & 0xffff) as usize] += 1;
            }
        }
        let sj = &j["splits"][split];
        assert_eq!(sj["frames"], ids.len());
        for k in 0..4 {
            assert_eq!(
                sj["cells"][names[k]], cells[k],
                "{split} {} cells",
                names[k]
            );
            assert_eq!(
                sj["points"][names[k]], points[k],
                "{split} {} points",
                names[k]
            );
        }
        let filled: u64 = cells.iter().sum();
        let mean = sj["channel_mean"]["range"].as_f64().unwrap();
        assert!((mean - range_sum / filled as f64).abs() < 1e-9 * mean);
        assert!(
            (sj["row_fill"][10].as_f64().unwrap() - rows[10] as f64 / (512.0 * ids.len() as f64))
                .abs()
                < 1e-12
        );
        let labelled = (cells[1] + cells[2] + cells[3]) as f64;
        assert!(
            (sj["share_of_labelled_cells"]["car"].as_f64().unwrap() - cells[1] as f64 / labelled)
                .abs()
                < 1e-12
        );
    }
    // Tracklet figures: instances are distinct tracklets present at the split's frames.
    let tr = Tracklets::read(&fixture_drive(1).join("tracklet_labels.xml")).unwrap();
    let cars: BTreeSet<usize> = [0, 45]
        .iter()
        .flat_map(|&f| {
            tr.at(f)
                .filter(|(_, t, _)| {
                    kitti2pgm::label::ClassMap::kitti_paper()
                        .class_of_object(t.object_type.as_str())
                        == 1
                })
                .map(|(i, _, _)| i)
        })
        .collect();
    assert_eq!(
        j["splits"]["train"]["tracklets"]["instances"]["car"],
        cars.len()
    );
    // Shares between splits add up; weights are normalised to car = 1.
    let share = &j["class_split_share"]["car"];
    assert!(
        (share["train"].as_f64().unwrap() + share["val"].as_f64().unwrap() - 1.0).abs() < 1e-12
    );
    assert_eq!(j["class_weights"]["inverse_frequency"][1], 1.0);
    assert_eq!(
        j["class_weights"]["reference"],
        serde_json::json!([1.0 / 15.0, 1.0, 10.0, 10.0])
    );
    assert_eq!(j["normalisation"]["from_split"], "train");
    assert_eq!(
        j["normalisation"]["channels"],
        serde_json::json!(["x", "y", "z", "intensity", "range", "r", "g", "b"])
    );
    assert!(j["convert_summary"]["collisions"].as_u64().unwrap() > 0);
    let img = kitti2pgm::raster::read(&png).unwrap();
    assert!(img.width() > 100 && img.height() > 100);
    // The readable table carries the normalisation constants.
    let (code, stdout, _) = run_text(&["stats", s(&out), "--imageset", s(&sets)]);
    assert_eq!(code, 0);
    assert!(
        stdout.contains("INPUT_MEAN") && stdout.contains("car cells"),
        "{stdout}"
    );
}

#[test]
fn stats_is_the_same_whatever_the_thread_count() {
    let t = tmp();
    let (out, sets) = converted(t.path());
    let a = run_text(&[
        "--threads",
        "1",
        "stats",
        s(&out),
        "--imageset",
        s(&sets),
        "--json",
    ])
    .1;
    let b = run_text(&[
        "--threads",
        "3",
        "stats",
        s(&out),
        "--imageset",
        s(&sets),
        "--json",
    ])
    .1;
    assert!(!a.is_empty());
    assert_eq!(a, b);
}

#[test]
fn stats_bad_input() {
    let t = tmp();
    let (out, sets) = converted(t.path());
    // An ImageSet naming frames that are not converted.
    let list = t.path().join("val.txt");
    std::fs::write(
        &list,
        "2011_09_26_0052_0000000000\n2011_09_26_0052_0000000042\n",
    )
    .unwrap();
    let (code, _, stderr) = run_text(&["stats", s(&out), "--imageset", s(&list)]);
    assert_eq!(code, 1);
    assert!(
        stderr.contains("val.txt") && stderr.contains("2011_09_26_0052_0000000042"),
        "{stderr}"
    );
    // A malformed list line.
    std::fs::write(&list, "not-a-frame\n").unwrap();
    let (code, _, stderr) = run_text(&["stats", s(&out), "--imageset", s(&list)]);
    assert_eq!(code, 1);
    assert!(stderr.contains("val.txt:1"), "{stderr}");
    // A folder with no converted frames.
    let (code, _, stderr) = run_text(&["stats", s(t.path())]);
    assert_eq!(code, 1);
    assert!(stderr.contains("lidar_2d"), "{stderr}");
    // Mixed 6- and 9-channel files.
    let six = t.path().join("six");
    assert_eq!(
        run_text(&["convert", s(&fixture_drive(52)), "--out", s(&six)]).0,
        0
    );
    std::fs::copy(
        six.join("lidar_2d/2011_09_26_0052_0000000000.npy"),
        out.join("lidar_2d/2011_09_26_0052_0000000000.npy"),
    )
    .unwrap();
    let (code, _, stderr) = run_text(&["stats", s(&out), "--imageset", s(&sets)]);
    assert_eq!(code, 1);
    assert!(
        stderr.contains("2011_09_26_0052_0000000000.npy")
            && stderr.contains("mixed 6- and 9-channel"),
        "{stderr}"
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
    let img = kitti2pgm::raster::read(&png).unwrap();
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
