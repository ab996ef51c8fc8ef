//! Box annotation exports, continued (issue 46): Xtreme1 / BasicAI results, Segments.ai release
//! files (quaternions, yaw, ego poses) and ASAM OpenLABEL 1.0 (Euler ZYX and quaternion
//! cuboids), written as each tool writes them around the real VLP-16 scan and compared point by
//! point with the independent reference of `annotations.rs`.

use kitti2pgm::source::annotations::{self, BoxFormat, ReadOptions};

use super::annotations::TestBox;
use super::annotations::{
    assert_same, centred_refs, labelled, obj, reference, rx_ry_rz, rz_ry_rx, scan, test_boxes,
};
use super::util::tmp;

/// A rotation matrix's quaternion `[qx, qy, qz, qw]` (Shepperd's method, written out).
fn quaternion(m: [[f64; 3]; 3]) -> [f64; 4] {
    let t = m[0][0] + m[1][1] + m[2][2];
    if t > 0.0 {
        let s = (t + 1.0).sqrt() * 2.0;
        [
            (m[2][1] - m[1][2]) / s,
            (m[0][2] - m[2][0]) / s,
            (m[1][0] - m[0][1]) / s,
            s / 4.0,
        ]
    } else if m[0][0] > m[1][1] && m[0][0] > m[2][2] {
        let s = (1.0 + m[0][0] - m[1][1] - m[2][2]).sqrt() * 2.0;
        [
            s / 4.0,
            (m[0][1] + m[1][0]) / s,
            (m[0][2] + m[2][0]) / s,
            (m[2][1] - m[1][2]) / s,
        ]
    } else if m[1][1] > m[2][2] {
        let s = (1.0 + m[1][1] - m[0][0] - m[2][2]).sqrt() * 2.0;
        [
            (m[0][1] + m[1][0]) / s,
            s / 4.0,
            (m[1][2] + m[2][1]) / s,
            (m[0][2] - m[2][0]) / s,
        ]
    } else {
        let s = (1.0 + m[2][2] - m[0][0] - m[1][1]).sqrt() * 2.0;
        [
            (m[0][2] + m[2][0]) / s,
            (m[1][2] + m[2][1]) / s,
            s / 4.0,
            (m[1][0] - m[0][1]) / s,
        ]
    }
}

#[test]
fn xtreme1_results_label_as_the_reference_from_their_ground_truth() {
    let t = tmp();
    let root = t.path().join("dataset");
    std::fs::create_dir_all(root.join("result")).unwrap();
    std::fs::create_dir_all(root.join("point_cloud")).unwrap();
    let boxes = test_boxes();
    let object = |i: usize, (c, s, r): &TestBox| {
        serde_json::json!({"id": format!("obj-{i}"), "type": "3D_BOX", "className": "car",
            "trackId": format!("track-{i}"), "trackName": i.to_string(), "classValues": [],
            "contour": {"pointN": 10, "points": [], "size3D": obj(*s), "center3D": obj(*c),
                        "viewIndex": 0, "rotation3D": obj(*r)},
            "modelConfidence": null, "modelClass": ""})
    };
    let mut gt: Vec<_> = boxes
        .iter()
        .enumerate()
        .map(|(i, b)| object(i, b))
        .collect();
    gt.push(serde_json::json!({"id": "r", "type": "2D_RECT", "className": "car", "contour": {}}));
    let model = vec![object(9, &([0.0; 3], [30.0; 3], [0.0; 3]))];
    let write = |sources: serde_json::Value| {
        std::fs::write(root.join("result/000000.json"), sources.to_string()).unwrap()
    };
    write(serde_json::json!([
        {"version": "Xtreme1 V0.6", "dataId": 1, "sourceName": "Model run", "objects": model},
        {"version": "Xtreme1 V0.6", "dataId": 1, "sourceName": "Ground Truth", "objects": gt},
    ]));
    assert_eq!(annotations::detect(&root), Some(BoxFormat::Xtreme1));
    let a = annotations::read(&root, BoxFormat::Xtreme1, &ReadOptions::default()).unwrap();
    assert_eq!(a.boxes(), 5);
    assert_eq!(a.tracks[0], "track-0");
    let points = scan();
    assert_same(
        &labelled(&a, "000000", &points),
        reference(&points, &centred_refs(&boxes, rx_ry_rz)),
    );
    // Two sources of 3D boxes and none the ground truth: an error naming them.
    write(serde_json::json!([
        {"sourceName": "Model A", "objects": gt}, {"sourceName": "Model B", "objects": model},
    ]));
    let e = annotations::read(&root, BoxFormat::Xtreme1, &ReadOptions::default()).unwrap_err();
    assert!(e.to_string().contains("Model A, Model B"), "{e}");
}

/// A Segments.ai release of one sequence of two frames around the VLP-16 scan: frame 0 with
/// quaternion cuboids in the scan's frame, frame 1 with yaw cuboids in a world where the
/// sensor has an ego pose.
#[test]
fn segments_ai_cuboids_label_as_the_reference_in_the_scan_s_frame() {
    use kitti2pgm::geom::na;
    let t = tmp();
    let boxes = test_boxes();
    let refs = centred_refs(&boxes, rx_ry_rz);
    let quat_cuboids: Vec<_> = (boxes.iter().enumerate())
        .map(|(i, (c, s, r))| {
            let [qx, qy, qz, qw] = quaternion(rx_ry_rz(*r));
            serde_json::json!({"id": i + 1, "category_id": 1 + (i % 2), "type": "cuboid",
                "position": obj(*c), "dimensions": obj(*s), "yaw": r[2],
                "rotation": {"qx": qx, "qy": qy, "qz": qz, "qw": qw},
                "track_id": i + 1, "is_keyframe": true, "index": 0})
        })
        .collect();
    // Frame 1: yaw only, in a world where the sensor sits at (5, -2, 1.5) turned 0.7 rad.
    let yaw_boxes: Vec<_> = boxes
        .iter()
        .map(|(c, s, r)| (*c, *s, [0.0, 0.0, r[2]]))
        .collect();
    let ego = na::Isometry3::new(na::Vector3::new(5.0, -2.0, 1.5), na::Vector3::z() * 0.7);
    let eq = ego.rotation.coords;
    let world: Vec<_> = (yaw_boxes.iter().enumerate())
        .map(|(i, (c, s, r))| {
            let w = ego * na::Point3::new(c[0], c[1], c[2]);
            serde_json::json!({"id": i + 1, "category_id": 1, "type": "cuboid",
                "position": obj([w.x, w.y, w.z]), "dimensions": obj(*s), "yaw": r[2] + 0.7,
                "track_id": i + 1})
        })
        .collect();
    let frame = |name: &str, ego: Option<serde_json::Value>| {
        serde_json::json!({"pcd": {"url": format!("https://x.s3.amazonaws.com/{name}.pcd?sig=1"), "type": "pcd"},
            "ego_pose": ego})
    };
    let pose = serde_json::json!({"position": obj([5.0, -2.0, 1.5]),
        "heading": {"qx": eq.x, "qy": eq.y, "qz": eq.z, "qw": eq.w}});
    let release = serde_json::json!({"name": "v1", "dataset": {
        "name": "own", "task_type": "pointcloud-cuboid-sequence",
        "task_attributes": {"format_version": "0.1", "categories": [{"id": 1, "name": "car"}, {"id": 2, "name": "pedestrian"}]},
        "labelsets": [{"name": "ground-truth"}],
        "samples": [{"name": "drive-1", "attributes": {"frames": [frame("000000", None), frame("000001", Some(pose))]},
            "labels": {"ground-truth": {"label_status": "LABELED", "attributes": {"format_version": "0.2", "frames": [
                {"format_version": "0.2", "annotations": quat_cuboids},
                {"format_version": "0.2", "annotations": world}]}}}}]}});
    let file = t.path().join("release.json");
    std::fs::write(&file, release.to_string()).unwrap();
    assert_eq!(annotations::detect(&file), Some(BoxFormat::SegmentsAi));
    let a = annotations::read(&file, BoxFormat::SegmentsAi, &ReadOptions::default()).unwrap();
    assert_eq!(a.frames["000000"].boxes[1].class_name, "pedestrian");
    assert_eq!(a.tracks.len(), 5, "track ids span the sequence");
    let points = scan();
    assert_same(&labelled(&a, "000000", &points), reference(&points, &refs));
    let yaw_refs = centred_refs(&yaw_boxes, rx_ry_rz);
    assert_same(
        &labelled(&a, "000001", &points),
        reference(&points, &yaw_refs),
    );
    // A quaternion of length 2 is no rotation.
    let bad = release.to_string().replacen(
        &format!("\"qw\":{}", quaternion(rx_ry_rz(boxes[0].2))[3]),
        "\"qw\":2.0",
        1,
    );
    std::fs::write(&file, bad).unwrap();
    let e = annotations::read(&file, BoxFormat::SegmentsAi, &ReadOptions::default()).unwrap_err();
    assert!(
        e.to_string().contains("far from unit length") && e.to_string().contains("annotation 1"),
        "{e}"
    );
}

/// An OpenLABEL file of two frames: Euler cuboids (9 values, ZYX) in frame 0, quaternion
/// cuboids (10 values) in frame 1, each frame naming its scan through its stream's uri.
#[test]
fn openlabel_cuboids_of_both_forms_label_as_the_reference() {
    let t = tmp();
    let boxes = test_boxes();
    let euler = |(c, s, r): &TestBox| vec![c[0], c[1], c[2], r[0], r[1], r[2], s[0], s[1], s[2]];
    let quat = |(c, s, r): &TestBox| {
        let q = quaternion(rz_ry_rx(*r));
        vec![c[0], c[1], c[2], q[0], q[1], q[2], q[3], s[0], s[1], s[2]]
    };
    let frame = |uri: &str, val: &dyn Fn(&TestBox) -> Vec<f64>| {
        let objects: serde_json::Map<String, serde_json::Value> = (boxes.iter().enumerate())
            .map(|(i, b)| {
                (
                    i.to_string(),
                    serde_json::json!({"object_data": {"cuboid": [
                {"name": "shape3D", "val": val(b), "coordinate_system": "lidar"}]}}),
                )
            })
            .collect();
        serde_json::json!({"objects": objects,
            "frame_properties": {"streams": {"lidar": {"uri": uri}}, "timestamp": 0}})
    };
    let objects: serde_json::Map<String, serde_json::Value> = (0..boxes.len())
        .map(|i| {
            (
                i.to_string(),
                serde_json::json!({"name": format!("obj{i}"), "type": "Car"}),
            )
        })
        .collect();
    let doc = serde_json::json!({"openlabel": {"metadata": {"schema_version": "1.0.0"},
        "coordinate_systems": {"lidar": {"type": "sensor_cs", "parent": "", "children": []}},
        "streams": {"lidar": {"type": "lidar"}},
        "objects": objects,
        "frames": {"0": frame("data/000000.pcd", &euler), "1": frame("data/000001.pcd", &quat)}}});
    let file = t.path().join("labels.json");
    std::fs::write(&file, doc.to_string()).unwrap();
    assert_eq!(annotations::detect(&file), Some(BoxFormat::OpenLabel));
    let a = annotations::read(&file, BoxFormat::OpenLabel, &ReadOptions::default()).unwrap();
    assert_eq!(a.boxes(), 10);
    let points = scan();
    let refs = centred_refs(&boxes, rz_ry_rx);
    assert_same(&labelled(&a, "000000", &points), reference(&points, &refs));
    assert_same(&labelled(&a, "000001", &points), reference(&points, &refs));
    // Cuboids in two coordinate systems, and a cuboid of 8 values: errors naming the object.
    let two = doc.to_string().replacen(
        "\"coordinate_system\":\"lidar\"",
        "\"coordinate_system\":\"vehicle\"",
        1,
    );
    std::fs::write(&file, two).unwrap();
    let e = annotations::read(&file, BoxFormat::OpenLabel, &ReadOptions::default()).unwrap_err();
    assert!(e.to_string().contains("coordinate system"), "{e}");
    let mut short = doc.clone();
    short["openlabel"]["frames"]["0"]["objects"]["2"]["object_data"]["cuboid"][0]["val"] =
        serde_json::json!([1, 2, 3, 4, 5, 6, 7, 8]);
    std::fs::write(&file, short.to_string()).unwrap();
    let e = annotations::read(&file, BoxFormat::OpenLabel, &ReadOptions::default()).unwrap_err();
    assert!(
        e.to_string().contains("frame 0 object 2") && e.to_string().contains("8 values"),
        "{e}"
    );
}
