//! READ: the real calibration, tracklet, timestamp and OXTS files.

use kitti2pgm::geom::na;
use kitti2pgm::label::ClassMap;
use kitti2pgm::source::kitti::calib::Calibration;
use kitti2pgm::source::kitti::oxts::Oxts;
use kitti2pgm::source::kitti::tracklets::{
    ObjectType, Occlusion, PoseState, Tracklets, Truncation,
};
use kitti2pgm::source::kitti::{discover, timestamps};
use kitti2pgm::source::Scan;

use crate::util::*;

#[test]
fn calibration_of_2011_09_26() {
    let c = Calibration::read_dir(&fixtures().join("2011_09_26")).unwrap();
    // Values as written in calib_velo_to_cam.txt.
    let r = c.velo_to_cam.velo_to_cam.rotation.matrix();
    assert_eq!(r[(0, 0)], 7.533745e-03);
    assert_eq!(r[(0, 1)], -9.999714e-01);
    assert_eq!(
        c.velo_to_cam.velo_to_cam.translation.vector.z,
        -2.717806e-01
    );
    assert_eq!(c.cam_to_cam.cameras[2].p_rect[(0, 0)], 7.215377e+02);
    assert_eq!(
        c.cam_to_cam.cameras[0].size,
        na::Vector2::new(1392.0, 512.0)
    );
    assert_eq!(
        c.cam_to_cam.cameras[0].size_rect,
        na::Vector2::new(1242.0, 375.0)
    );
    let imu = c.imu_to_velo.as_ref().unwrap();
    assert_eq!(imu.imu_to_velo.translation.vector.x, -8.086759e-01);
    // A point 10 m straight ahead of the velodyne lands near the image centre column of camera 2.
    let m = c.velo_to_image(2);
    let p = m * na::Vector4::new(10.0, 0.0, 0.0, 1.0);
    let (u, v) = (p.x / p.z, p.y / p.z);
    assert!(
        (550.0..700.0).contains(&u) && (150.0..250.0).contains(&v),
        "u={u} v={v}"
    );
}

// The literals are the file's text, digit for digit.
#[allow(clippy::excessive_precision)]
#[test]
fn tracklets_of_drive_0001_every_field() {
    let t = Tracklets::read(&fixture_drive(1).join("tracklet_labels.xml")).unwrap();
    assert_eq!(t.tracklets.len(), 15);
    let first = &t.tracklets[0];
    assert_eq!(first.object_type, ObjectType::Car);
    assert_eq!(first.h, 2.1672349);
    assert_eq!(first.w, 1.7057118);
    assert_eq!(first.l, 4.3293562);
    assert_eq!(first.first_frame, 0);
    assert_eq!(first.poses.len(), 14);
    let p = &first.poses[0];
    assert_eq!(
        p.t,
        [25.212516037456261, 8.6033915444744817, -1.7921571450416216]
    );
    assert_eq!(p.r, [0.0, 0.0, -3.1842001424562025]);
    assert_eq!(p.state, PoseState::Labeled);
    assert_eq!(p.occlusion, Occlusion::Visible);
    assert!(p.occlusion_kf);
    assert_eq!(p.truncation, Truncation::InImage);
    assert_eq!((p.amt_occlusion, p.amt_occlusion_kf), (0.0, 1));
    assert_eq!(
        (p.amt_border_l, p.amt_border_r, p.amt_border_kf),
        (0.0, 1.0, -1)
    );
    assert_eq!(first.poses[1].state, PoseState::Interpolated);
    assert_eq!(first.finished, Some(true));
    // Frame lookup agrees with a scan over all tracklets.
    for f in 0..t.end_frame() {
        let direct = t
            .tracklets
            .iter()
            .filter(|x| x.pose_at(f).is_some())
            .count();
        assert_eq!(t.count_at(f), direct);
        assert_eq!(t.at(f).count(), direct);
    }
}

#[test]
#[ignore = "needs ../shared"]
fn all_36_real_tracklet_files_parse() {
    let shared = needs_shared("kitti");
    let mut types = std::collections::BTreeMap::new();
    let mut n = 0;
    for e in std::fs::read_dir(shared.join("tracklets")).unwrap() {
        let p = e.unwrap().path().join("tracklet_labels.xml");
        let t = Tracklets::read(&p).unwrap_or_else(|e| panic!("{e}"));
        for x in &t.tracklets {
            *types.entry(x.object_type.clone()).or_insert(0) += 1;
            assert!(x.poses.iter().all(|p| p.r[0] == 0.0 && p.r[1] == 0.0));
        }
        n += 1;
    }
    assert_eq!(n, 36);
    // The real spelling `Person (sitting)` is recognised, and nothing falls into `Other`.
    assert!(types.contains_key(&ObjectType::PersonSitting), "{types:?}");
    assert!(
        types.keys().all(|k| !matches!(k, ObjectType::Other(_))),
        "{types:?}"
    );
    let map = ClassMap::kitti_paper();
    let class = |t: ObjectType| map.name(map.class_of_object(t.as_str())).to_string();
    assert_eq!(class(ObjectType::PersonSitting), "pedestrian");
    assert_eq!(class(ObjectType::Van), "car");
    assert_eq!(class(ObjectType::Tram), "background");
}

#[test]
fn timestamps_and_oxts() {
    let ts = timestamps::read(&fixture_drive(1).join("velodyne_points/timestamps.txt")).unwrap();
    assert_eq!(ts.len(), 108);
    let dt = ts[1].unwrap().0 - ts[0].unwrap().0;
    assert!(
        (90_000_000..115_000_000).contains(&dt),
        "10 Hz scans, got {dt} ns"
    );
    let o = Oxts::read(&fixture_drive(1).join("oxts/data/0000000000.txt")).unwrap();
    assert_eq!(o.lat, 49.015003823272);
    assert_eq!(o.lon, 8.4342971002335);
    assert!(o.numsats > 0);
}

#[test]
fn discovery_accepts_root_date_and_drive() {
    let all = discover(&fixtures()).unwrap();
    assert_eq!(
        all.iter().map(|d| d.number).collect::<Vec<_>>(),
        vec![1, 52]
    );
    assert_eq!(discover(&fixtures().join("2011_09_26")).unwrap().len(), 2);
    let one = discover(&fixture_drive(52)).unwrap();
    assert_eq!(one.len(), 1);
    assert_eq!(one[0].name(), "2011_09_26_drive_0052_sync");
    assert_eq!(one[0].scan_frames().unwrap(), vec![0]);
    assert_eq!(one[0].frame_id(7).to_string(), "2011_09_26_0052_0000000007");
}

#[test]
fn real_scan_reads() {
    let s = Scan::read(&fixture_drive(1).join("velodyne_points/data/0000000000.bin")).unwrap();
    assert_eq!(s.file_len, 1936240 / 16);
    assert_eq!(s.len(), s.file_len);
    assert!(s.intensity.iter().all(|r| (0.0..=1.0).contains(r)));
}

/// Issue 49: one drop rule per kind of source, stated once. A KITTI `.bin` with two
/// reflectances outside 0-1 gave 114,278 points through the Python module's `read_cloud` (the
/// point cloud reader) and 114,276 through the converter's reading; every reading function now
/// gives the same points, those two dropped.
#[test]
fn every_reading_function_gives_the_same_points_of_one_file() {
    use kitti2pgm::project::{project_scan, PgmSpec};
    use kitti2pgm::source::kitti::velodyne;
    let src = fixture_drive(1).join("velodyne_points/data/0000000000.bin");
    let mut bytes = std::fs::read(&src).unwrap();
    for (at, v) in [(100usize, 1.5f32), (2000, -0.5)] {
        bytes[at * 16 + 12..at * 16 + 16].copy_from_slice(&v.to_le_bytes());
    }
    let t = tmp();
    let path = t.path().join("0000000000.bin");
    std::fs::write(&path, &bytes).unwrap();
    let n = bytes.len() / 16;
    let scans = [
        Scan::read(&path).unwrap(),
        kitti2pgm::source::read_file(&path, None).unwrap(),
        velodyne::decode(&bytes, &path).unwrap(),
        kitti2pgm::sensor::read_scan(None, &path).unwrap().0,
        project_scan(&PgmSpec::default(), None, &path).unwrap().0,
    ];
    for s in &scans {
        assert_eq!((s.file_len, s.len()), (n, n - 2));
        assert_eq!(
            (s.dropped.as_slice(), s.dropped_out_of_range),
            ([100, 2000].as_slice(), 2)
        );
        assert_eq!(s, &scans[0]);
    }
}

/// Issue 49: one box seam. KITTI's tracklets and object labels are box sources through
/// [`BoxConvention`]s; the label rule gives each box its class by name and its track's
/// instance, the same boxes as the conventions placed.
#[test]
fn tracklets_are_a_box_source_through_kitti_s_convention() {
    use kitti2pgm::label::label_boxes;
    use kitti2pgm::source::boxes::{BoxConvention, BoxRotation, BoxSource};
    let tr = Tracklets::read(&fixture_drive(1).join("tracklet_labels.xml")).unwrap();
    let map = ClassMap::kitti_paper();
    let boxes = tr.boxes_at(0);
    assert_eq!(boxes.len(), tr.count_at(0));
    let labelled = label_boxes(&boxes, &map);
    for ((b, l), (i, t, p)) in boxes.iter().zip(&labelled).zip(tr.at(0)) {
        assert_eq!(
            (b.track, b.class_name.as_str()),
            (i, t.object_type.as_str())
        );
        assert_eq!(l.instance as usize, i + 1);
        assert_eq!(l.class, map.class_of_object(t.object_type.as_str()));
        // KITTI's tracklets turn about z alone: the bottom centre lifted by h/2 is the centre.
        assert_eq!((p.r[0], p.r[1]), (0.0, 0.0));
        let placed = BoxConvention::CENTRED_LWH.place(
            [p.t[0], p.t[1], p.t[2] + t.h / 2.0],
            [t.l, t.w, t.h],
            &BoxRotation::Euler(p.r),
            None,
        );
        assert!((placed.centre() - b.geometry.centre()).norm() < 1e-5);
        assert_eq!(placed.half_extents, b.geometry.half_extents);
    }
    assert!(tr.file().is_some() && tr.unknown_types().is_empty());
}
