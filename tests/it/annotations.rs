//! Box annotation exports (issue 46, the readers): CVAT's Kitti Raw export, Supervisely point
//! clouds and SUSTechPOINTS labels, written as each tool writes them around the real VLP-16 scan
//! of `fixtures/own_lidar`, read, and their points labelled; every point's instance compared
//! with an independent reference built here from each format's documented convention (rotation
//! matrices from sines and cosines, the point taken into the box's frame in double precision).

use std::path::Path;

use kitti2pgm::geom::Point3;
use kitti2pgm::label::{label_boxes, ClassMap, Labeller};
use kitti2pgm::source::annotations::{self, AngleUnit, BoxFormat, CvatSizes, ReadOptions};
use kitti2pgm::source::boxes::BoxOrigin;

use super::util::{fixture, tmp};

/// A box as the reference sees it: centre, half extents along its axes, and its axes (the
/// columns of `r`: box to scan).
pub(super) struct RefBox {
    c: [f64; 3],
    half: [f64; 3],
    r: [[f64; 3]; 3],
    pub(super) instance: u16,
}

impl RefBox {
    /// The box grown by `m` on every side (`label --margin`).
    pub(super) fn grow(&mut self, m: f64) {
        for h in &mut self.half {
            *h += m;
        }
    }
}

fn mat_mul(a: [[f64; 3]; 3], b: [[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let mut m = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            m[i][j] = (0..3).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    m
}

/// `Rx(x) * Ry(y) * Rz(z)`, written out.
pub(super) fn rx_ry_rz([x, y, z]: [f64; 3]) -> [[f64; 3]; 3] {
    let (sx, cx, sy, cy, sz, cz) = (x.sin(), x.cos(), y.sin(), y.cos(), z.sin(), z.cos());
    let rx = [[1.0, 0.0, 0.0], [0.0, cx, -sx], [0.0, sx, cx]];
    let ry = [[cy, 0.0, sy], [0.0, 1.0, 0.0], [-sy, 0.0, cy]];
    let rz = [[cz, -sz, 0.0], [sz, cz, 0.0], [0.0, 0.0, 1.0]];
    mat_mul(rx, mat_mul(ry, rz))
}

/// KITTI's tracklet rotation: `Rz(rz) * Ry(ry) * Rx(rx)`.
pub(super) fn rz_ry_rx([x, y, z]: [f64; 3]) -> [[f64; 3]; 3] {
    let (sx, cx, sy, cy, sz, cz) = (x.sin(), x.cos(), y.sin(), y.cos(), z.sin(), z.cos());
    let rx = [[1.0, 0.0, 0.0], [0.0, cx, -sx], [0.0, sx, cx]];
    let ry = [[cy, 0.0, sy], [0.0, 1.0, 0.0], [-sy, 0.0, cy]];
    let rz = [[cz, -sz, 0.0], [sz, cz, 0.0], [0.0, 0.0, 1.0]];
    mat_mul(rz, mat_mul(ry, rx))
}

/// The reference's boxes of `boxes` (centre, full x, y, z extents, Euler angles composed by
/// `rot`), instance `i + 1` for box `i`.
pub(super) fn centred_refs(boxes: &[TestBox], rot: fn([f64; 3]) -> [[f64; 3]; 3]) -> Vec<RefBox> {
    (boxes.iter().enumerate())
        .map(|(i, (c, s, r))| RefBox {
            c: *c,
            half: s.map(|v| v / 2.0),
            r: rot(*r),
            instance: i as u16 + 1,
        })
        .collect()
}

/// Each point's instance by the reference (smallest box wins, then the earlier), and the points
/// within 1 mm of a face of a box that holds or nearly holds them (single and double precision
/// may disagree there: left out of the comparison).
pub(super) fn reference(points: &[Point3], boxes: &[RefBox]) -> (Vec<u16>, Vec<bool>) {
    let mut out = vec![0u16; points.len()];
    let mut edge = vec![false; points.len()];
    for (k, p) in points.iter().enumerate() {
        let mut best: Option<(f64, u16)> = None;
        for b in boxes {
            let d = [
                p.x as f64 - b.c[0],
                p.y as f64 - b.c[1],
                p.z as f64 - b.c[2],
            ];
            // q = R^T d: the point in the box's frame.
            let q: Vec<f64> = (0..3)
                .map(|j| (0..3).map(|i| b.r[i][j] * d[i]).sum())
                .collect();
            let margin = (0..3)
                .map(|i| b.half[i] - q[i].abs())
                .fold(f64::INFINITY, f64::min);
            if margin.abs() < 1e-3 {
                edge[k] = true;
            }
            let vol = b.half.iter().product::<f64>();
            if margin >= 0.0 && best.is_none_or(|(v, _)| vol < v) {
                best = Some((vol, b.instance));
            }
        }
        out[k] = best.map_or(0, |b| b.1);
    }
    (out, edge)
}

/// The real VLP-16 scan's points.
pub(super) fn scan() -> Vec<Point3> {
    let path = fixture("own_lidar/sequences/00/velodyne/000000.pcd");
    kitti2pgm::source::read_file(&path, None).unwrap().points
}

/// Labels `points` with the boxes of frame `scan` of `a` (every class a class of its own, so
/// that the instance decides): each point's instance.
pub(super) fn labelled(a: &annotations::Annotations, scan: &str, points: &[Point3]) -> Vec<u16> {
    let mut map = ClassMap::kitti_paper();
    for b in &a.frames[scan].boxes {
        map.object_types.insert(b.class_name.clone(), 1);
    }
    let boxes = label_boxes(&a.frames[scan].boxes, &map);
    Labeller::new(&boxes, 0).label(points).instance
}

/// Asserts the labeller's instances equal the reference's on every point off the faces, that
/// few points lie on them, and that the boxes hold points at all.
pub(super) fn assert_same(got: &[u16], (want, edge): (Vec<u16>, Vec<bool>)) {
    let mut compared = 0;
    for k in 0..got.len() {
        if !edge[k] {
            assert_eq!(got[k], want[k], "point {k}");
            compared += 1;
        }
    }
    assert!(
        compared > got.len() * 99 / 100,
        "{compared} of {}",
        got.len()
    );
    assert!(
        want.iter().filter(|&&i| i > 0).count() > 100,
        "the boxes hold points"
    );
}

/// Boxes around the scan's points: (centre, sizes x y z, Euler x y z), some turned about all
/// three axes, two overlapping (the smaller wins), one across the seam behind the sensor.
/// A test box: centre, full x, y, z extents, Euler angles x, y, z (radians).
pub(super) type TestBox = ([f64; 3], [f64; 3], [f64; 3]);

pub(super) fn test_boxes() -> Vec<TestBox> {
    vec![
        ([-0.6, 0.0, 0.1], [2.0, 1.6, 1.2], [0.0, 0.0, 0.6]),
        ([-0.5, 0.1, 0.0], [0.8, 0.6, 0.6], [0.1, -0.2, 1.1]),
        ([-7.0, 0.0, 0.5], [4.0, 6.0, 3.0], [0.0, 0.0, 0.3]),
        ([0.0, -7.0, 0.5], [8.0, 3.0, 4.0], [0.3, 0.2, -0.4]),
        ([1.5, 6.0, 0.5], [3.0, 4.0, 3.0], [0.0, 0.5, 2.0]),
    ]
}

pub(super) fn obj(x: [f64; 3]) -> serde_json::Value {
    serde_json::json!({"x": x[0], "y": x[1], "z": x[2]})
}

#[test]
fn sustechpoints_labels_the_points_its_boxes_hold() {
    let t = tmp();
    let scene = t.path().join("scene");
    std::fs::create_dir_all(scene.join("label")).unwrap();
    std::fs::create_dir_all(scene.join("lidar")).unwrap();
    // As the tool writes a frame: a list of objects with obj_type, obj_id and psr.
    let objs: Vec<_> = (test_boxes().iter().enumerate())
        .map(|(i, (p, s, r))| {
            let kind = ["Car", "Pedestrian", "Truck", "Car", "Bus"][i];
            serde_json::json!({"obj_type": kind,
                "obj_id": (10 + i).to_string(),
                "psr": {"position": obj(*p), "scale": obj(*s), "rotation": obj(*r)}})
        })
        .collect();
    std::fs::write(
        scene.join("label/000000.json"),
        serde_json::to_vec(&objs).unwrap(),
    )
    .unwrap();
    let a = annotations::read(&scene, BoxFormat::SusTechPoints, &ReadOptions::default()).unwrap();
    assert_eq!(annotations::detect(&scene), Some(BoxFormat::SusTechPoints));
    assert_eq!(a.tracks, ["10", "11", "12", "13", "14"]);
    let refs = centred_refs(&test_boxes(), rx_ry_rz);
    let points = scan();
    assert_same(&labelled(&a, "000000", &points), reference(&points, &refs));
}

#[test]
fn supervisely_labels_the_points_its_cuboids_hold() {
    let t = tmp();
    let ds = t.path().join("project/ds0");
    std::fs::create_dir_all(ds.join("ann")).unwrap();
    std::fs::write(t.path().join("project/meta.json"), b"{\"classes\": []}").unwrap();
    // As the tool writes an annotation: objects (key, classTitle) and cuboid_3d figures.
    let boxes = test_boxes();
    let objects: Vec<_> = (0..boxes.len())
        .map(|i| serde_json::json!({"key": format!("k{i}"), "classTitle": "car"}))
        .collect();
    let mut figures: Vec<_> = (boxes.iter().enumerate())
        .map(|(i, (p, s, r))| {
            serde_json::json!({"key": format!("f{i}"), "objectKey": format!("k{i}"),
                "geometryType": "cuboid_3d",
                "geometry": {"position": obj(*p), "rotation": obj(*r), "dimensions": obj(*s)}})
        })
        .collect();
    figures.push(
        serde_json::json!({"objectKey": "k0", "geometryType": "point_cloud",
        "geometry": {"indices": [1, 2]}}),
    );
    let ann = serde_json::json!({"description": "", "key": "v", "tags": [],
        "objects": objects, "figures": figures});
    std::fs::write(
        ds.join("ann/000000.pcd.json"),
        serde_json::to_vec(&ann).unwrap(),
    )
    .unwrap();
    let root = t.path().join("project");
    let a = annotations::read(&root, BoxFormat::Supervisely, &ReadOptions::default()).unwrap();
    assert_eq!(
        (a.boxes(), annotations::detect(&root)),
        (5, Some(BoxFormat::Supervisely))
    );
    let refs = centred_refs(&boxes, rx_ry_rz);
    let points = scan();
    assert_same(&labelled(&a, "000000", &points), reference(&points, &refs));
}

#[test]
fn labelcloud_labels_the_points_its_boxes_hold_in_degrees_by_default() {
    let t = tmp();
    let labels = t.path().join("project/labels");
    std::fs::create_dir_all(&labels).unwrap();
    std::fs::write(
        labels.join("_classes.json"),
        br#"{"classes": [{"name": "car", "id": 0}]}"#,
    )
    .unwrap();
    let boxes = test_boxes();
    // As the tool writes a label (centroid_abs): degrees, dimensions length / width / height.
    let write = |to_unit: f64| {
        let objects: Vec<_> = (boxes.iter())
            .map(|(c, s, r)| {
                serde_json::json!({"name": "car", "centroid": obj(*c),
                    "dimensions": {"length": s[0], "width": s[1], "height": s[2]},
                    "rotations": obj(r.map(|a| a * to_unit))})
            })
            .collect();
        let label = serde_json::json!({"folder": "pointclouds", "filename": "000000.pcd",
            "path": "pointclouds/000000.pcd", "objects": objects});
        std::fs::write(labels.join("000000.json"), label.to_string()).unwrap();
    };
    let refs = centred_refs(&boxes, rz_ry_rx);
    let points = scan();
    let root = t.path().join("project");
    write(180.0 / std::f64::consts::PI);
    let a = annotations::read(&root, BoxFormat::LabelCloud, &ReadOptions::default()).unwrap();
    assert_eq!(annotations::detect(&root), Some(BoxFormat::LabelCloud));
    assert_same(&labelled(&a, "000000", &points), reference(&points, &refs));
    // centroid_rel: radians, read with the option; read as degrees, the labels change.
    write(1.0);
    let radians = ReadOptions {
        angles: Some(AngleUnit::Radians),
        ..Default::default()
    };
    let a = annotations::read(&root, BoxFormat::LabelCloud, &radians).unwrap();
    let got = labelled(&a, "000000", &points);
    assert_same(&got, reference(&points, &refs));
    let a = annotations::read(&root, BoxFormat::LabelCloud, &ReadOptions::default()).unwrap();
    assert!(
        labelled(&a, "000000", &points) != got,
        "the unit changes the labels"
    );
}

/// Boxes drawn in a vehicle frame (the sensor 1.2 m forward, 1.5 m up, turned 10 degrees):
/// read with the inverse of the sensor's pose, they label the scan as the same boxes in the
/// scan's frame do.
#[test]
fn boxes_of_a_vehicle_frame_are_brought_into_the_scan_s() {
    use kitti2pgm::geom::na;
    let t = tmp();
    let labels = t.path().join("labels");
    std::fs::create_dir_all(&labels).unwrap();
    let yaw = 10f64.to_radians();
    let sensor = na::Isometry3::new(na::Vector3::new(1.2, 0.0, 1.5), na::Vector3::z() * yaw);
    let boxes: Vec<_> = (test_boxes().into_iter())
        .map(|(c, s, r)| (c, s, [0.0, 0.0, r[2]]))
        .collect();
    let objects: Vec<_> = (boxes.iter())
        .map(|(c, s, r)| {
            let v = sensor * na::Point3::new(c[0], c[1], c[2]);
            serde_json::json!({"name": "car", "centroid": obj([v.x, v.y, v.z]),
                "dimensions": {"length": s[0], "width": s[1], "height": s[2]},
                "rotations": obj([0.0, 0.0, (r[2] + yaw).to_degrees()])})
        })
        .collect();
    let label = serde_json::json!({ "objects": objects });
    std::fs::write(labels.join("000000.json"), label.to_string()).unwrap();
    let opts = ReadOptions {
        to_scan: Some(sensor.inverse()),
        ..Default::default()
    };
    let a = annotations::read(&labels, BoxFormat::LabelCloud, &opts).unwrap();
    let refs = centred_refs(&boxes, rz_ry_rx);
    let points = scan();
    let moved = labelled(&a, "000000", &points);
    assert_same(&moved, reference(&points, &refs));
    let unmoved = annotations::read(&labels, BoxFormat::LabelCloud, &Default::default()).unwrap();
    assert!(labelled(&unmoved, "000000", &points) != moved);
}

/// A CVAT Kitti Raw export of the boxes (yaw only, as CVAT's cuboids): tracklet XML with
/// `frame_list.txt`; `sizes` written in Datumaro's order, positions at the centres.
fn cvat_export(dir: &Path, boxes: &[TestBox]) {
    let mut xml = String::from(
        "<?xml version=\"1.0\" encoding=\"UTF-8\" standalone=\"yes\" ?>\n<!DOCTYPE boost_serialization>\n\
         <boost_serialization signature=\"serialization::archive\" version=\"9\">\n<tracklets class_id=\"0\" \
         tracking_level=\"0\" version=\"0\">\n",
    );
    xml += &format!(
        "<count>{}</count><item_version>1</item_version>\n",
        boxes.len()
    );
    for (p, s, r) in boxes {
        // Datumaro's exporter: h = scale y, w = scale x, l = scale z.
        xml += &format!(
            "<item><objectType>car</objectType><h>{}</h><w>{}</w><l>{}</l><first_frame>0</first_frame>\
             <poses><count>1</count><item_version>2</item_version><item><tx>{}</tx><ty>{}</ty><tz>{}</tz>\
             <rx>{}</rx><ry>{}</ry><rz>{}</rz><state>2</state><occlusion>0</occlusion><occlusion_kf>1</occlusion_kf>\
             <truncation>0</truncation><amt_occlusion>-1</amt_occlusion><amt_border_l>-1</amt_border_l>\
             <amt_border_r>-1</amt_border_r><amt_occlusion_kf>-1</amt_occlusion_kf><amt_border_kf>-1</amt_border_kf>\
             </item></poses><finished>1</finished></item>\n",
            s[1], s[0], s[2], p[0], p[1], p[2], r[0], r[1], r[2]
        );
    }
    xml += "</tracklets>\n</boost_serialization>\n";
    std::fs::create_dir_all(dir.join("velodyne_points/data")).unwrap();
    std::fs::write(dir.join("tracklet_labels.xml"), xml).unwrap();
    std::fs::write(dir.join("frame_list.txt"), "0 scan_a\n").unwrap();
}

#[test]
fn cvat_kitti_raw_takes_datumaro_s_sizes_and_centres_and_each_option_changes_the_labels() {
    let t = tmp();
    let boxes: Vec<_> = test_boxes()
        .into_iter()
        .map(|(p, s, r)| (p, s, [0.0, 0.0, r[2]]))
        .collect();
    cvat_export(t.path(), &boxes);
    let points = scan();
    let refs = |sizes: &dyn Fn([f64; 3]) -> [f64; 3], lift: bool| -> Vec<RefBox> {
        (boxes.iter().enumerate())
            .map(|(i, (c, s, r))| {
                let half = sizes(*s).map(|v| v / 2.0);
                let rot = rz_ry_rx(*r);
                let c = if lift {
                    // The bottom centre: the centre is h/2 up the box's own z.
                    [0, 1, 2].map(|k| c[k] + rot[k][2] * half[2])
                } else {
                    *c
                };
                RefBox {
                    c,
                    half,
                    r: rot,
                    instance: i as u16 + 1,
                }
            })
            .collect()
    };
    let read = |opts: ReadOptions| {
        let a = annotations::read(t.path(), BoxFormat::CvatKittiRaw, &opts).unwrap();
        assert_eq!(
            a.frames.keys().collect::<Vec<_>>(),
            ["scan_a"],
            "named by frame_list.txt"
        );
        labelled(&a, "scan_a", &points)
    };
    // CVAT's default: the sizes are the cuboid's own x, y, z, the position its centre.
    let default = read(ReadOptions::default());
    assert_same(&default, reference(&points, &refs(&|s| s, false)));
    // KITTI's order read from the same file: x = l (written scale z), y = w (x), z = h (y).
    let kitti = read(ReadOptions {
        sizes: Some(CvatSizes::Kitti),
        ..Default::default()
    });
    assert_same(
        &kitti,
        reference(&points, &refs(&|s| [s[2], s[0], s[1]], false)),
    );
    // The bottom centre (KITTI's origin) lifts every box by half its height.
    let bottom = read(ReadOptions {
        origin: Some(BoxOrigin::BottomCentre),
        ..Default::default()
    });
    assert_same(&bottom, reference(&points, &refs(&|s| s, true)));
    assert!(
        default != kitti && default != bottom,
        "each option changes the labels"
    );
}

#[test]
fn bad_boxes_are_named_with_their_file_and_object() {
    let t = tmp();
    let scene = t.path().join("scene");
    std::fs::create_dir_all(scene.join("label")).unwrap();
    std::fs::create_dir_all(scene.join("lidar")).unwrap();
    let psr = |s: f64| {
        serde_json::json!({"position": obj([1.0, 2.0, 0.0]),
        "scale": obj([s, 1.0, 1.0]), "rotation": obj([0.0, 0.0, 0.0])})
    };
    let file = scene.join("label/000007.json");
    let sustech = || annotations::read(&scene, BoxFormat::SusTechPoints, &ReadOptions::default());
    for (s, says) in [(0.0, "positive"), (-2.0, "positive"), (1e9, "implausible")] {
        let objs = serde_json::json!([{"obj_type": "Car", "obj_id": "3", "psr": psr(s)}]);
        std::fs::write(&file, objs.to_string()).unwrap();
        let e = sustech().unwrap_err().to_string();
        assert!(
            e.contains("000007.json") && e.contains("obj_id 3") && e.contains(says),
            "{e}"
        );
    }
    // NaN cannot be written in JSON; a string where a number is.
    std::fs::write(&file, r#"[{"obj_type": "Car", "obj_id": "3", "psr": {"position": {"x": "nan", "y": 0, "z": 0}}}]"#).unwrap();
    let e = sustech().unwrap_err().to_string();
    assert!(e.contains("position") && e.contains("no number"), "{e}");
    let two = serde_json::json!([{"obj_type": "Car", "obj_id": "3", "psr": psr(1.0)},
                                 {"obj_type": "Car", "obj_id": "3", "psr": psr(2.0)}]);
    std::fs::write(&file, two.to_string()).unwrap();
    assert!(sustech().unwrap_err().to_string().contains("twice"));
    for text in ["", "[{\"obj_type\": \"Car\", \"psr\""] {
        std::fs::write(&file, text).unwrap();
        let e = sustech().unwrap_err().to_string();
        assert!(e.contains("000007.json"), "{e}");
    }
    // A format given under another's name says what it looks like.
    std::fs::write(&file, serde_json::json!([]).to_string()).unwrap();
    let e = annotations::read(&scene, BoxFormat::Supervisely, &ReadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("looks like sustechpoints"), "{e}");
    let cvat = t.path().join("cvat");
    cvat_export(&cvat, &[([0.0; 3], [1.0, -2.0, 1.0], [0.0; 3])]);
    let e = annotations::read(&cvat, BoxFormat::CvatKittiRaw, &ReadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("tracklet_labels.xml") && e.contains("positive"),
        "{e}"
    );
    let e = annotations::read(&cvat, BoxFormat::SusTechPoints, &ReadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("looks like cvat-kitti-raw"), "{e}");
}

/// Datumaro's own test assets (../shared/boxes): the Supervisely project reads (two frames,
/// their classes); the CVAT export's negative sizes are named, not labelled with.
#[test]
#[ignore = "needs ../shared"]
fn datumaro_s_assets_read_as_their_tools_wrote_them() {
    let shared = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/boxes/datumaro");
    let sly = shared.join("sly_pointcloud_dataset");
    let a = annotations::read(&sly, BoxFormat::Supervisely, &ReadOptions::default()).unwrap();
    assert_eq!(a.frames.keys().collect::<Vec<_>>(), ["frame1", "frame2"]);
    let classes: std::collections::BTreeSet<&str> = (a.frames.values())
        .flat_map(|f| f.boxes.iter().map(|b| b.class_name.as_str()))
        .collect();
    assert!(
        classes.iter().all(|c| ["car", "bus"].contains(c)),
        "{classes:?}"
    );
    assert_eq!(
        annotations::detect(&shared.join("kitti_dataset/kitti_raw")),
        Some(BoxFormat::CvatKittiRaw)
    );
    let e = annotations::read(
        &shared.join("kitti_dataset/kitti_raw"),
        BoxFormat::CvatKittiRaw,
        &ReadOptions::default(),
    )
    .unwrap_err()
    .to_string();
    // Its first fault: a count that disagrees with its items (or a negative size).
    assert!(
        e.contains("tracklet_labels.xml") && (e.contains("positive") || e.contains("<count>")),
        "{e}"
    );
}
