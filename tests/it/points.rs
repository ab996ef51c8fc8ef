//! Point shards (`convert --format points`): the scan's points with the converter's rings,
//! labels and colours, the map shards' integrity and re-run rules.

use kitti2pgm::format::label_file;
use kitti2pgm::format::shard::{Shard, ShardKind};
use kitti2pgm::project::rings;
use kitti2pgm::report::inspect::inspect;
use kitti2pgm::source::Scan;

use crate::util::*;

#[test]
fn point_shards_hold_the_converters_points_and_labels() {
    let t = tmp();
    let out = t.path().join("out");
    let (code, first, err) = convert_json(
        &fixtures(),
        &out,
        &["--format", "points,labels", "--rgb", "--val-drives", "52"],
    );
    assert_eq!(code, 0, "{err}");
    assert_eq!(first["frames_converted"], 3);
    assert_eq!(first["shards_written"], 2);
    assert!(!out.join("lidar_2d").exists() && !out.join("shards").exists());
    let mut seen = 0;
    for split in ["train", "val"] {
        let path = out.join(format!("points/{split}-00000.mcap"));
        let shard = Shard::open_verified(&path).unwrap();
        let md = shard.metadata().unwrap();
        assert_eq!(md.content, ShardKind::Points);
        assert_eq!(md.split.as_str(), split);
        for p in shard.points().unwrap() {
            seen += 1;
            let (date, drive, frame) = (&p.id[..10], &p.id[11..15], &p.id[16..]);
            let bin = fixtures().join(format!(
                "{date}/{date}_drive_{drive}_sync/velodyne_points/data/{frame}.bin"
            ));
            let scan = Scan::read(&bin).unwrap();
            assert_eq!(p.count as usize, scan.len());
            let pts = p.points_f32();
            for (k, q) in pts.iter().enumerate() {
                let s = scan.points[k];
                assert_eq!(*q, [s.x, s.y, s.z, scan.intensity[k]]);
            }
            assert_eq!(p.ring, rings(&scan.points).0.unwrap());
            // Labels are the .label file's (written beside), point for point.
            let lab = label_file::read_raw(
                &out.join(format!("labels/{date}_drive_{drive}_sync/{frame}.label")),
            )
            .unwrap();
            let idx = p.file_indices();
            assert_eq!(idx, scan.file_indices());
            // Stored only where the scan dropped points (none of the fixture's).
            assert_eq!(p.file_index.is_empty(), scan.dropped.is_empty());
            for (k, &i) in idx.iter().enumerate() {
                assert_eq!(p.label[k] as u32, lab[i as usize] & 0xFFFF);
            }
            assert!(p.label.contains(&1), "cars are labelled");
            assert_eq!(p.rgb.len(), 12 * scan.len());
            let seen_by_camera = p.rgb_valid.iter().filter(|&&v| v == 1).count();
            assert!(seen_by_camera > scan.len() / 10 && seen_by_camera < scan.len() / 2);
        }
        let info = inspect(&path).unwrap();
        assert_eq!(info.metadata.content, ShardKind::Points);
        assert!(info.points > 100_000);
    }
    assert_eq!(seen, 3);

    // A re-run keeps intact point shards; a damaged one is found and rewritten.
    let args = ["--format", "points,labels", "--rgb", "--val-drives", "52"];
    let (_, again, _) = convert_json(&fixtures(), &out, &args);
    assert_eq!(again["shards_skipped"], 2);
    assert_eq!(again["shards_written"], 0);
    let p = out.join("points/train-00000.mcap");
    let mut bytes = std::fs::read(&p).unwrap();
    let mid = bytes.len() / 2;
    bytes[mid] ^= 0x40;
    std::fs::write(&p, &bytes).unwrap();
    let e = inspect(&p).unwrap_err().to_string();
    assert!(
        e.contains("train-00000.mcap") && e.contains("corrupted"),
        "{e}"
    );
    let (_, third, _) = convert_json(&fixtures(), &out, &args);
    assert_eq!(third["shards_written"], 1);
    assert_eq!(third["shards_skipped"], 1);
    assert!(Shard::open_verified(&p).unwrap().points().is_ok());
}

#[test]
fn maps_and_points_together_count_each_frame_once() {
    let t = tmp();
    let out = t.path().join("out");
    let (code, j, err) = convert_json(&fixtures(), &out, &["--format", "npy,mcap,points"]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(j["frames_converted"], 3);
    assert!(out.join("shards/train-00000.mcap").is_file());
    assert!(out.join("points/train-00000.mcap").is_file());
    assert_eq!(std::fs::read_dir(out.join("lidar_2d")).unwrap().count(), 3);
}

#[test]
fn reports_refuse_point_shards_by_name() {
    let t = tmp();
    let out = t.path().join("out");
    let (code, _, err) = convert_json(&fixtures(), &out, &["--format", "points"]);
    assert_eq!(code, 0, "{err}");
    let shard = out.join("points/train-00000.mcap");
    for args in [
        vec!["stats", s(&out)],
        vec!["stats", s(&shard)],
        vec!["preview", s(&shard), "--out", s(&t.path().join("pics"))],
    ] {
        let (code, _, err) = run_text(&args);
        assert_ne!(code, 0, "{args:?}");
        assert!(err.contains("point shard"), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
    }
}

#[test]
fn file_index_is_stored_where_points_were_dropped() {
    let t = tmp();
    let root = fixture_copy(t.path());
    let bin =
        root.join("2011_09_26/2011_09_26_drive_0001_sync/velodyne_points/data/0000000000.bin");
    let mut bytes = std::fs::read(&bin).unwrap();
    bytes[16 * 5..16 * 5 + 4].copy_from_slice(&f32::NAN.to_le_bytes()); // point 5
    std::fs::write(&bin, &bytes).unwrap();
    let out = t.path().join("out");
    let (code, _, err) = convert_json(&root, &out, &["--format", "points"]);
    assert_eq!(code, 0, "{err}");
    let shard = Shard::open_verified(&out.join("points/train-00000.mcap")).unwrap();
    let pts = shard.points().unwrap();
    let p = pts
        .iter()
        .find(|p| p.id == "2011_09_26_0001_0000000000")
        .unwrap();
    let scan = Scan::read(&bin).unwrap();
    assert_eq!(p.file_index.len(), 4 * scan.len());
    assert_eq!(p.file_indices(), scan.file_indices());
    assert_eq!(p.file_indices()[5], 6);
    assert!(pts
        .iter()
        .filter(|q| q.id != p.id)
        .all(|q| q.file_index.is_empty()));
}
