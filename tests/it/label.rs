//! LABEL: the labeller against an independent inside-box check, and on real frames.

use kitti2pgm::geom::{Point3, Real};
use kitti2pgm::label::{ClassId, ClassMap, LabelBox, Labeller};
use kitti2pgm::source::kitti::tracklets::{
    ObjectType, Occlusion, Pose, PoseState, Tracklet, Tracklets, Truncation,
};
use kitti2pgm::source::Scan;
use proptest::prelude::*;

use kitti2pgm::source::boxes::BoxSource;

use crate::util::*;

/// The paper's class of a tracklet.
fn class_of(t: &Tracklet) -> ClassId {
    ClassMap::kitti_paper().class_of_object(t.object_type.as_str())
}

/// A box of tracklet `i` at `pose`, of the paper's class.
fn lbox(i: usize, t: &Tracklet, pose: &Pose) -> LabelBox {
    LabelBox::of(&t.box_at(pose), class_of(t), i as u16 + 1)
}

fn tracklet(object_type: ObjectType, hwl: [f64; 3], t: [f64; 3], yaw: f64) -> (Tracklet, Pose) {
    let pose = Pose {
        t,
        r: [0.0, 0.0, yaw],
        state: PoseState::Labeled,
        occlusion: Occlusion::Visible,
        occlusion_kf: false,
        truncation: Truncation::InImage,
        amt_occlusion: 0.0,
        amt_occlusion_kf: 0,
        amt_border_l: 0.0,
        amt_border_r: 0.0,
        amt_border_kf: 0,
    };
    let tr = Tracklet {
        object_type,
        h: hwl[0],
        w: hwl[1],
        l: hwl[2],
        first_frame: 0,
        poses: vec![pose.clone()],
        finished: Some(true),
    };
    (tr, pose)
}

/// The definition, in f64, written independently of parry: signed margin to the box
/// (positive inside), so that the test can skip points too close to a face to decide in f32.
fn margin(p: [f64; 3], hwl: [f64; 3], t: [f64; 3], yaw: f64) -> f64 {
    let (dx, dy, dz) = (p[0] - t[0], p[1] - t[1], p[2] - t[2]);
    let (c, s) = (yaw.cos(), yaw.sin());
    let (lx, ly) = (c * dx + s * dy, -s * dx + c * dy);
    let [h, w, l] = hwl;
    (l / 2.0 - lx.abs())
        .min(w / 2.0 - ly.abs())
        .min(dz)
        .min(h - dz)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]
    #[test]
    fn labeller_agrees_with_an_independent_check(
        h in 0.5f64..4.0, w in 0.3f64..3.0, l in 0.3f64..12.0,
        tx in -40.0f64..40.0, ty in -40.0f64..40.0, tz in -3.0f64..1.0,
        yaw in -7.0f64..7.0,
        pts in prop::collection::vec((-6.0f64..6.0, -6.0f64..6.0, -1.0f64..5.0), 200),
    ) {
        let (tr, pose) = tracklet(ObjectType::Car, [h, w, l], [tx, ty, tz], yaw);
        let b = lbox(0, &tr, &pose);
        let lab = Labeller::new(std::slice::from_ref(&b), 0);
        for (dx, dy, dz) in pts {
            let p = [tx + dx, ty + dy, tz + dz];
            let m = margin(p, [h, w, l], [tx, ty, tz], yaw);
            if m.abs() < 1e-3 {
                continue; // within f32 rounding of a face
            }
            let point = Point3::new(p[0] as Real, p[1] as Real, p[2] as Real);
            let got = lab.label_point(&point);
            prop_assert_eq!(got.is_some(), m > 0.0, "point {:?} margin {}", p, m);
            prop_assert_eq!(b.contains(&point), m > 0.0);
            if let Some((class, id)) = got {
                prop_assert_eq!(class, 1);
                prop_assert_eq!(id, 1);
            }
        }
    }

    #[test]
    fn a_box_holds_its_centre_for_any_yaw(yaw in -10.0f64..10.0, h in 0.5f64..4.0) {
        let (tr, pose) = tracklet(ObjectType::Pedestrian, [h, 0.6, 0.8], [5.0, -3.0, -1.5], yaw);
        let b = lbox(3, &tr, &pose);
        let centre = Point3::new(5.0, -3.0, (-1.5 + h / 2.0) as Real);
        prop_assert!(b.contains(&centre));
        prop_assert_eq!(Labeller::new(&[b], 0).label_point(&centre), Some((2, 4)));
    }
}

#[test]
fn overlaps_go_to_the_smallest_box_and_tram_stays_background() {
    let (car, cp) = tracklet(ObjectType::Car, [2.0, 2.0, 4.0], [10.0, 0.0, -1.0], 0.3);
    let (cyc, yp) = tracklet(ObjectType::Cyclist, [1.8, 0.6, 1.8], [10.0, 0.0, -1.0], 0.0);
    let (tram, tp) = tracklet(ObjectType::Tram, [3.0, 3.0, 20.0], [10.0, 0.0, -1.0], 0.0);
    let (van, vp) = tracklet(ObjectType::Van, [2.0, 2.0, 4.0], [10.0, 0.0, -1.0], 0.3);
    let boxes = [
        lbox(0, &tram, &tp),
        lbox(1, &car, &cp),
        lbox(2, &cyc, &yp),
        lbox(3, &van, &vp),
    ];
    let lab = Labeller::new(&boxes, 0);
    assert_eq!(lab.len(), 3, "the tram does not take part");
    assert_eq!(lab.label_point(&Point3::new(10.0, 0.0, -0.5)), Some((3, 3)));
    // In car and van (same size) but not the cyclist: the lower tracklet index wins.
    assert_eq!(lab.label_point(&Point3::new(11.5, 0.5, -0.5)), Some((1, 2)));
    // Only in the tram: background.
    assert_eq!(lab.label_point(&Point3::new(18.0, 0.0, 0.0)), None);
    // Boundaries are inclusive: the bottom face.
    assert!(boxes[2].contains(&Point3::new(10.0, 0.0, -1.0)));
}

/// On real frames, each car's points are exactly those the independent check puts in its box.
#[test]
fn cars_are_labelled_where_the_tracklets_put_them() {
    for (drive, frame) in [(1u32, 0u32), (1, 45), (52, 0)] {
        let dir = fixture_drive(drive);
        let tr = Tracklets::read(&dir.join("tracklet_labels.xml")).unwrap();
        let scan = Scan::read(&dir.join(format!("velodyne_points/data/{frame:010}.bin"))).unwrap();
        let boxes = kitti2pgm::label::label_boxes(&tr.boxes_at(frame), &ClassMap::kitti_paper());
        let labels = Labeller::new(&boxes, 0).label(&scan.points);
        let mut cars_with_points = 0;
        for (i, t, p) in tr.at(frame) {
            if class_of(t) == 0 {
                continue;
            }
            let yaw = p.r[2];
            let mut inside = 0;
            let mut labelled_as_it = 0;
            let mut undecidable = 0;
            for (k, q) in scan.points.iter().enumerate() {
                let m = margin(
                    [q.x as f64, q.y as f64, q.z as f64],
                    [t.h, t.w, t.l],
                    p.t,
                    yaw,
                );
                if m.abs() < 1e-4 {
                    undecidable += 1;
                    continue;
                }
                if m > 0.0 {
                    inside += 1;
                    // Overlaps are rare; a point in this box carries this box's class at least.
                    assert_ne!(labels.class[k], 0);
                }
                if labels.instance[k] as usize == i + 1 {
                    labelled_as_it += 1;
                    assert!(
                        m > 0.0,
                        "point {k} labelled as tracklet {i} lies outside its box"
                    );
                }
            }
            assert!(labelled_as_it <= inside + undecidable);
            assert!(
                labelled_as_it + undecidable >= inside * 95 / 100,
                "tracklet {i}: {labelled_as_it} of {inside}"
            );
            if class_of(t) == 1 && inside > 50 {
                cars_with_points += 1;
            }
        }
        assert!(
            cars_with_points >= 1,
            "drive {drive} frame {frame} has visible cars"
        );
    }
}

/// A small deterministic generator (xorshift), for cases a proptest would take long to shrink.
fn xorshift(state: &mut u64) -> f64 {
    *state ^= *state << 13;
    *state ^= *state >> 7;
    *state ^= *state << 17;
    (*state >> 11) as f64 / (1u64 << 53) as f64
}

/// Labels `points` with `lab` and checks that each point gets what `label_point` gives it;
/// returns the points in a box.
fn label_agrees_with_label_point(lab: &Labeller, points: &[Point3], what: &str) -> usize {
    let labels = lab.label(points);
    let mut labelled = 0;
    for (k, p) in points.iter().enumerate() {
        let want = lab.label_point(p).unwrap_or((0, 0));
        let got = (labels.class[k], labels.instance[k]);
        assert_eq!(got, want, "{what}, point {k} {p:?}");
        labelled += usize::from(want.0 != 0);
    }
    labelled
}

/// `label` (box by box in runs of points, up to `BY_BOX_MAX` boxes) gives every point of real
/// frames what `label_point` (the grid) gives it.
#[test]
fn labelling_a_real_scan_gives_each_point_what_label_point_gives() {
    let classes = ClassMap::kitti_paper();
    for (drive, frame) in [(1u32, 0u32), (1, 45), (52, 0)] {
        let dir = fixture_drive(drive);
        let tr = Tracklets::read(&dir.join("tracklet_labels.xml")).unwrap();
        let scan = Scan::read(&dir.join(format!("velodyne_points/data/{frame:010}.bin"))).unwrap();
        let boxes = kitti2pgm::label::label_boxes(&tr.boxes_at(frame), &classes);
        let lab = Labeller::new(&boxes, 0);
        assert!(lab.len() <= kitti2pgm::label::boxes::BY_BOX_MAX);
        let what = format!("drive {drive} frame {frame}");
        let labelled = label_agrees_with_label_point(&lab, &scan.points, &what);
        assert!(labelled > 100, "{what}: {labelled} points in boxes");
    }
}

/// The same on crowded made-up scenes of 1 to `BY_BOX_MAX` + 6 overlapping boxes of every
/// class (so both paths), with points at the boxes' corners and on their bounding boxes'
/// faces, near them, with a NaN coordinate, and runs of points that end mid-word.
#[test]
fn labelling_a_crowded_scene_gives_each_point_what_label_point_gives() {
    let types = [
        ObjectType::Car,
        ObjectType::Pedestrian,
        ObjectType::Cyclist,
        ObjectType::Van,
        ObjectType::Tram,
    ];
    let mut seed = 0x9e37_79b9_7f4a_7c15u64;
    for n_boxes in (1..=kitti2pgm::label::boxes::BY_BOX_MAX + 6).step_by(7) {
        let mut boxes = Vec::new();
        let mut points = Vec::new();
        for i in 0..n_boxes {
            let mut r = || xorshift(&mut seed);
            let hwl = [0.5 + 2.0 * r(), 0.4 + 2.0 * r(), 0.5 + 5.0 * r()];
            // Boxes crowded into 12 x 12 m, so that many overlap.
            let t = [12.0 * r() - 6.0, 12.0 * r() - 6.0, -2.0 + r()];
            let (tr, pose) = tracklet(types[i % types.len()].clone(), hwl, t, 7.0 * r() - 3.5);
            let b = lbox(i, &tr, &pose);
            let h = b.cuboid.half_extents;
            for corner in 0..8 {
                let s = |bit: u32| if corner >> bit & 1 == 1 { 1.0 } else { -1.0 };
                let c = b.pose * Point3::new(s(0) * h.x, s(1) * h.y, s(2) * h.z);
                points.push(c);
                // On a bounding-box face: the corner's x with the box centre's y and z.
                points.push(Point3::new(c.x, b.pose.translation.y, b.pose.translation.z));
            }
            boxes.push(b);
        }
        let mut r = || xorshift(&mut seed) as Real;
        while points.len() < 2 * 1024 + 333 {
            points.push(Point3::new(
                16.0 * r() - 8.0,
                16.0 * r() - 8.0,
                4.0 * r() - 3.0,
            ));
        }
        // The first box's centre with a NaN coordinate: in no box.
        let c = boxes[0].pose.translation;
        let nan = [
            Point3::new(Real::NAN, c.y, c.z),
            Point3::new(c.x, c.y, Real::NAN),
        ];
        points.extend(nan);
        let lab = Labeller::new(&boxes, 0);
        let labels = lab.label(&points);
        assert!(labels.class[points.len() - 2..].iter().all(|&c| c == 0));
        assert!(nan.iter().all(|p| lab.label_point(p).is_none()));
        let what = format!("{n_boxes} boxes");
        let labelled = label_agrees_with_label_point(&lab, &points, &what);
        assert!(labelled > 0, "{what}: some points inside");
    }
}
