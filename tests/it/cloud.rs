//! PROJECT from memory: `project_cloud` is the conversion's projection, and augmentation keeps
//! rings and shifts columns exactly.

use kitti2pgm::convert::frame::{load, process, Viz};
use kitti2pgm::plan::{FrameSelection, Plan};
use kitti2pgm::project::camera::{RgbOptions, Sampling};
use kitti2pgm::project::{project_cloud, rings, Augment, Cloud, CloudProjection, PgmSpec, EMPTY};
use kitti2pgm::provenance::MapParams;
use kitti2pgm::simd::Level;

use crate::util::*;

fn spec360() -> PgmSpec {
    PgmSpec {
        fov: kitti2pgm::geom::Degrees(360.0),
        cols: 2048,
        ..Default::default()
    }
}

/// `project_cloud` of a loaded frame's arrays.
fn cloud_map(
    l: &kitti2pgm::convert::frame::LoadedFrame,
    spec: &PgmSpec,
    aug: Option<&Augment>,
) -> CloudProjection {
    let colours = l.point_colours();
    let rgb: Option<Vec<[f32; 3]>> = colours
        .as_ref()
        .map(|c| c.iter().map(|v| v.unwrap_or([0.0; 3])).collect());
    let valid: Option<Vec<bool>> = colours
        .as_ref()
        .map(|c| c.iter().map(Option::is_some).collect());
    let cloud = Cloud {
        labels: Some(&l.labels.points.class),
        instance: Some(&l.labels.points.instance),
        colours: rgb.as_deref(),
        colour_valid: valid.as_deref(),
        ..Cloud::of_points(&l.scan.points, &l.scan.intensity)
    };
    project_cloud(&cloud, spec, aug).unwrap()
}

#[test]
fn cloud_projection_is_the_conversion() {
    let plan = Plan::build(&raw_root(), FrameSelection::Annotated).unwrap();
    for (spec, rgb) in [
        (PgmSpec::default(), false),
        (PgmSpec::default(), true),
        (spec360(), false),
    ] {
        let map = MapParams {
            spec,
            rgb: rgb.then_some(RgbOptions {
                camera: 2,
                sampling: Sampling::Nearest,
            }),
            ..Default::default()
        };
        for &(d, f) in plan.jobs.iter().take(3) {
            let l = load(&plan.drives[d], f, &map, Viz::Off).unwrap();
            let conv = process(
                &l.id,
                &l.scan,
                &l.labels,
                &map,
                None,
                l.camera.as_ref().map(|(p, i)| (p, i)),
            );
            let m = cloud_map(&l, &spec, None);
            assert_eq!(m.frame, conv.pgm, "{} rgb={rgb} cols={}", l.id, spec.cols);
            // The identity augmentation is no augmentation, whatever its seed.
            let id = Augment {
                seed: 77,
                ..Default::default()
            };
            assert_eq!(cloud_map(&l, &spec, Some(&id)).frame, conv.pgm);
            // Given rings are the recovered ones.
            let (r, _) = rings(&l.scan.points);
            let given = Cloud {
                rings: r.as_deref(),
                labels: Some(&l.labels.points.class),
                instance: Some(&l.labels.points.instance),
                ..Cloud::of_points(&l.scan.points, &l.scan.intensity)
            };
            if !rgb {
                assert_eq!(project_cloud(&given, &spec, None).unwrap().frame, conv.pgm);
            }
        }
    }
}

#[test]
fn rotation_by_one_column_shifts_one_column_and_keeps_rows() {
    let plan = Plan::build(&raw_root(), FrameSelection::Annotated).unwrap();
    let (d, f) = plan.jobs[0];
    let spec = spec360();
    let l = load(
        &plan.drives[d],
        f,
        &MapParams {
            spec,
            ..Default::default()
        },
        Viz::Off,
    )
    .unwrap();
    let base = cloud_map(&l, &spec, None);
    let step = std::f64::consts::TAU / spec.cols as f64;
    let rot = cloud_map(
        &l,
        &spec,
        Some(&Augment {
            rotate: step,
            ..Default::default()
        }),
    );
    let (h, w, c) = (spec.rows, spec.cols, base.frame.depth());
    let mut moved = 0;
    for r in 0..h {
        for col in 0..w {
            let a = &base.frame.data[(r * w + (col + 1) % w) * c..][..c];
            let b = &rot.frame.data[(r * w + col) * c..][..c];
            // z, intensity, range and label move with the column; x and y turn.
            assert_eq!(
                [a[2], a[3], a[4], a[5]],
                [b[2], b[3], b[4], b[5]],
                "row {r} col {col}"
            );
            moved += (a[4] > 0.0) as usize;
        }
    }
    assert!(moved > 50_000);
    // Every point keeps its row.
    for (i, (&p, &q)) in base.point_cell.iter().zip(&rot.point_cell).enumerate() {
        assert_eq!(p == EMPTY, q == EMPTY, "point {i}");
        if p != EMPTY {
            assert_eq!(p as usize / w, q as usize / w, "point {i} changed row");
        }
    }
    // A 90-degree map: the same shift, one column leaves and one comes in.
    let spec = PgmSpec::default();
    let base = cloud_map(&l, &spec, None);
    let step = std::f64::consts::FRAC_PI_2 / spec.cols as f64;
    let rot = cloud_map(
        &l,
        &spec,
        Some(&Augment {
            rotate: -step,
            ..Default::default()
        }),
    );
    let c = base.frame.depth();
    for r in 0..spec.rows {
        for col in 1..spec.cols {
            let a = &base.frame.data[(r * spec.cols + col - 1) * c + 4];
            let b = &rot.frame.data[(r * spec.cols + col) * c + 4];
            assert_eq!(a, b);
        }
    }
}

#[test]
fn augmentation_drops_scales_and_refuses_bad_input() {
    let plan = Plan::build(&raw_root(), FrameSelection::Annotated).unwrap();
    let (d, f) = plan.jobs[0];
    let spec = PgmSpec::default();
    let l = load(&plan.drives[d], f, &MapParams::default(), Viz::Off).unwrap();
    let base = cloud_map(&l, &spec, None);
    let aug = Augment {
        drop: 0.5,
        jitter: 0.02,
        scale: 1.1,
        flip: true,
        rotate: 0.3,
        seed: 5,
    };
    let a = cloud_map(&l, &spec, Some(&aug));
    assert_eq!(a.frame, cloud_map(&l, &spec, Some(&aug)).frame, "seeded");
    assert!(a.stats.in_fov < base.stats.in_fov * 7 / 10);
    assert_eq!(a.stats.ring_fallbacks, 0);
    let dropped = a.point_cell.iter().filter(|&&c| c == EMPTY).count();
    assert!(dropped > l.scan.len() / 2);
    // Bad arrays are named.
    let mut pts = l.scan.points.clone();
    pts[7].y = f32::NAN;
    let bad = Cloud::of_points(&pts, &l.scan.intensity);
    let e = project_cloud(&bad, &spec, None).unwrap_err().to_string();
    assert!(e.contains("point 7 is not finite"), "{e}");
    let short = Cloud::of_points(&l.scan.points, &l.scan.intensity[1..]);
    let e = project_cloud(&short, &spec, None).unwrap_err().to_string();
    assert!(e.contains("intensity has"), "{e}");
    let r = vec![64u8; l.scan.len()];
    let e = project_cloud(
        &Cloud {
            rings: Some(&r),
            ..Cloud::of_points(&l.scan.points, &l.scan.intensity)
        },
        &spec,
        None,
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("ring 64 of point 0"), "{e}");
}

/// The AVX2 and baseline paths ([`kitti2pgm::simd`]) project every real scan of the fixtures
/// the same, bit for bit: plain and augmented, by rings, given beams and elevation, 90 and
/// 360 degrees.
#[test]
fn both_code_paths_project_the_same() {
    use kitti2pgm::project::RowMode;
    let plan = Plan::build(&raw_root(), FrameSelection::Annotated).unwrap();
    let narrow = PgmSpec::default();
    let elevation = PgmSpec {
        row_mode: RowMode::Elevation,
        ..spec360()
    };
    let all = Augment {
        rotate: 0.7,
        scale: 1.03,
        flip: true,
        jitter: 0.02,
        drop: 0.1,
        seed: 5,
    };
    let mut scans = 0;
    for &(d, f) in &plan.jobs {
        let l = load(&plan.drives[d], f, &MapParams::default(), Viz::Off).unwrap();
        for spec in [narrow, spec360(), elevation] {
            for aug in [None, Some(all)] {
                let run = || cloud_map(&l, &spec, aug.as_ref());
                let base = kitti2pgm::simd::baseline(run);
                for level in Level::available() {
                    let fast = kitti2pgm::simd::at_most(level, run);
                    let what = format!(
                        "{} {} cols {:?} {aug:?} {level:?}",
                        l.id, spec.cols, spec.row_mode
                    );
                    assert_eq!(fast.frame, base.frame, "{what}");
                    assert_eq!(fast.point_cell, base.point_cell, "{what}");
                    assert_eq!(fast.cell_point, base.cell_point, "{what}");
                    assert_eq!(fast.stats, base.stats, "{what}");
                }
            }
        }
        // Given beams (the recovered rings, scaled to 32 rows).
        let (r, _) = rings(&l.scan.points);
        let given = Cloud {
            rings: r.as_deref(),
            ..Cloud::of_points(&l.scan.points, &l.scan.intensity)
        };
        let half = PgmSpec {
            rows: 32,
            ..spec360()
        };
        let run = || project_cloud(&given, &half, None).unwrap();
        let base = kitti2pgm::simd::baseline(run);
        for level in Level::available() {
            let fast = kitti2pgm::simd::at_most(level, run);
            assert_eq!(fast.frame, base.frame, "{} given rings {level:?}", l.id);
            assert_eq!(
                fast.point_cell, base.point_cell,
                "{} given rings {level:?}",
                l.id
            );
        }
        scans += 1;
    }
    assert!(scans >= 3, "{scans} scans");
}

/// The map's cells sixteen at a time (AVX-512) equal the cell-by-cell loop at the edges of
/// their inputs: the first and last points kept (whose class and instance are read from the
/// values before them), the largest class and instance ids, a handful of points, and maps
/// whose cells are no multiple of sixteen.
#[test]
fn cells_at_the_edges_of_their_inputs_on_every_path() {
    use kitti2pgm::project::RowMode;
    for n in [1usize, 2, 3, 4, 5, 17, 40, 333] {
        // Points on a spiral, each in a cell of its own, the first and the last among them.
        let points: Vec<_> = (0..n)
            .map(|i| {
                let a = (i as f32 + 0.5) * 6.1 / n as f32 - 3.05;
                let r = 5.0 + i as f32 * 0.01;
                kitti2pgm::geom::Point3::new(r * a.cos(), r * a.sin(), -1.0 + 0.003 * i as f32)
            })
            .collect();
        let intensity: Vec<f32> = (0..n).map(|i| (i % 7) as f32 / 7.0).collect();
        let class: Vec<u8> = (0..n).map(|i| [255, 0, 7, 254][i % 4]).collect();
        let instance: Vec<u16> = (0..n).map(|i| [65535, 1, 0, 40000][i % 4]).collect();
        let cloud = Cloud {
            labels: Some(&class),
            instance: Some(&instance),
            ..Cloud::of_points(&points, &intensity)
        };
        for cols in [512, 333, 7] {
            let spec = PgmSpec {
                cols,
                rows: 5,
                row_mode: RowMode::Elevation,
                fov_up: kitti2pgm::geom::Degrees(0.0),
                ..spec360()
            };
            let base = kitti2pgm::simd::baseline(|| project_cloud(&cloud, &spec, None).unwrap());
            for level in Level::available() {
                let fast =
                    kitti2pgm::simd::at_most(level, || project_cloud(&cloud, &spec, None).unwrap());
                assert_eq!(fast.frame, base.frame, "{n} points, {cols} cols, {level:?}");
            }
            if cols == 512 {
                let kept = base.cell_point.iter().filter(|&&c| c != EMPTY).count();
                assert_eq!(kept, n, "every point keeps a cell");
                let c = base.point_cell[n - 1] as usize;
                assert_eq!(base.frame.label[c], class[n - 1]);
                assert_eq!(base.frame.instance[c], instance[n - 1]);
            }
        }
    }
}

/// The same projection whatever the threads: the points' parts and the map's bands change
/// nothing, plain and augmented, with and without the spare bands of a narrow map; the parts
/// by rows (rings in scan order: from the scan, given, or given for fewer rows than beams) and
/// the parts whose keys are merged (elevation rows; given rings out of order).
#[test]
fn threads_change_nothing() {
    use kitti2pgm::project::RowMode;
    let plan = Plan::build(&raw_root(), FrameSelection::Annotated).unwrap();
    let (d, f) = plan.jobs[0];
    let l = load(&plan.drives[d], f, &MapParams::default(), Viz::Off).unwrap();
    let plain = Cloud {
        labels: Some(&l.labels.points.class),
        instance: Some(&l.labels.points.instance),
        ..Cloud::of_points(&l.scan.points, &l.scan.intensity)
    };
    let ring = rings(&l.scan.points).0.expect("a whole scan");
    let upside_down: Vec<u8> = ring.iter().map(|r| 63 - r).collect();
    let elevation = PgmSpec {
        row_mode: RowMode::Elevation,
        ..spec360()
    };
    let half_rows = PgmSpec {
        rows: 32,
        ..spec360()
    };
    let cases = [
        (plain, PgmSpec::default()),
        (plain, spec360()),
        (plain, elevation),
        (
            Cloud {
                rings: Some(&ring),
                ..plain
            },
            half_rows,
        ),
        (
            Cloud {
                rings: Some(&upside_down),
                ..plain
            },
            spec360(),
        ),
    ];
    for (cloud, spec) in cases {
        threads_change_nothing_for(&cloud, spec, l.scan.points.len());
    }
}

fn threads_change_nothing_for(cloud: &Cloud<'_>, spec: PgmSpec, n: usize) {
    use kitti2pgm::project::project_cloud_on;
    let aug = Augment {
        rotate: -1.1,
        scale: 0.98,
        jitter: 0.01,
        drop: 0.05,
        seed: 9,
        ..Default::default()
    };
    assert!(n > 7 * 16_384, "enough points for 7 parts");
    for a in [None, Some(&aug)] {
        let one = project_cloud_on(cloud, &spec, a, 1).unwrap();
        for threads in [0, 2, 3, 7, 64] {
            let many = project_cloud_on(cloud, &spec, a, threads).unwrap();
            let what = format!("{spec:?}, {a:?}, {threads} threads");
            assert_eq!(many.frame, one.frame, "{what}");
            assert_eq!(many.point_cell, one.point_cell, "{what}");
            assert_eq!(many.cell_point, one.cell_point, "{what}");
            assert_eq!(many.stats, one.stats, "{what}");
        }
    }
}
