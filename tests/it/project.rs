//! PROJECT: rings, rows, columns and fill on real scans.

use kitti2pgm::project::{project, rings, PgmSpec, RowMode, EMPTY, LASERS};
use kitti2pgm::source::kitti::{discover, Drive};
use kitti2pgm::source::Scan;
use proptest::prelude::*;

use crate::util::*;

/// Every (drive, scan path) available: the shared 30 scans where present, else the fixtures' 3.
fn scans() -> Vec<(Drive, std::path::PathBuf)> {
    let mut out = Vec::new();
    for d in discover(&raw_root()).unwrap() {
        for f in d.scan_frames().unwrap() {
            out.push((d.clone(), d.scan_path(f)));
        }
    }
    assert!(out.len() >= 3);
    out
}

#[test]
fn sixty_four_rings_on_every_full_scan() {
    for (_, path) in scans() {
        let scan = Scan::read(&path).unwrap();
        let (ids, found) = rings(&scan.points);
        assert_eq!(found, LASERS, "{}", path.display());
        let ids = ids.unwrap();
        assert!(
            ids.windows(2).all(|w| w[1] == w[0] || w[1] == w[0] + 1),
            "rings are consecutive"
        );
    }
}

#[test]
fn row_elevation_falls_from_top_to_bottom() {
    for (_, path) in scans() {
        let scan = Scan::read(&path).unwrap();
        let proj = project(&scan.points, &PgmSpec::default());
        assert!(!proj.fallback());
        let mut medians = Vec::new();
        for r in 0..64 {
            let mut el: Vec<f64> = (0..512)
                .filter_map(|c| {
                    let i = proj.cell_point[r * 512 + c];
                    (i != EMPTY).then(|| {
                        let p = scan.points[i as usize];
                        (p.z as f64 / proj.cell_range[r * 512 + c] as f64)
                            .asin()
                            .to_degrees()
                    })
                })
                .collect();
            el.sort_by(f64::total_cmp);
            medians.push(el[el.len() / 2]);
        }
        assert!(
            (1.5..3.5).contains(&medians[0]),
            "row 0 at {} deg in {}",
            medians[0],
            path.display()
        );
        assert!(
            (-24.0..-23.0).contains(&medians[63]),
            "row 63 at {} deg",
            medians[63]
        );
        for r in 1..64 {
            // Neighbouring lasers may invert by up to about 0.2 degrees (they sit at different heights).
            assert!(
                medians[r] < medians[r - 1] + 0.25,
                "rows {} / {r}: {} then {} in {}",
                r - 1,
                medians[r - 1],
                medians[r],
                path.display()
            );
        }
        for r in 8..64 {
            assert!(
                medians[r] < medians[r - 8],
                "elevation must fall over 8 rows"
            );
        }
    }
}

#[test]
fn fill_ratio_matches_the_real_scans() {
    for (drive, path) in scans() {
        let scan = Scan::read(&path).unwrap();
        let rings = project(&scan.points, &PgmSpec::default());
        let fill = rings.stats.filled_cells as f64 / (64.0 * 512.0);
        let range = if drive.number == 1 {
            0.86..0.88
        } else {
            0.74..0.80
        };
        assert!(range.contains(&fill), "fill {fill} of {}", path.display());
        let binned = project(
            &scan.points,
            &PgmSpec {
                row_mode: RowMode::Elevation,
                ..Default::default()
            },
        );
        let binned_fill = binned.stats.filled_cells as f64 / (64.0 * 512.0);
        assert!(
            binned_fill < fill - 0.05,
            "elevation binning {binned_fill} vs rings {fill}"
        );
        assert!(binned.stats.collisions > rings.stats.collisions);
        assert_eq!(
            rings.stats.in_fov,
            rings.stats.filled_cells + rings.stats.collisions
        );
    }
}

#[test]
fn partial_scan_falls_back_to_elevation_binning() {
    let scan = Scan::read(&fixture_drive(52).join("velodyne_points/data/0000000000.bin")).unwrap();
    let half = &scan.points[..scan.len() / 2];
    let p = project(half, &PgmSpec::default());
    assert!(p.fallback());
    assert!(
        p.rings_found < 64 && p.rings_found > 20,
        "{}",
        p.rings_found
    );
    assert!(p.stats.filled_cells > 0);
}

#[test]
fn full_circle_and_other_sizes() {
    let scan = Scan::read(&fixture_drive(1).join("velodyne_points/data/0000000000.bin")).unwrap();
    let full = project(
        &scan.points,
        &PgmSpec {
            fov: kitti2pgm::geom::Degrees(360.0),
            cols: 2048,
            ..Default::default()
        },
    );
    assert!(!full.fallback());
    assert_eq!(
        full.stats.in_fov,
        scan.len() as u64,
        "a 360-degree map takes every point"
    );
    let small = project(
        &scan.points,
        &PgmSpec {
            rows: 32,
            cols: 256,
            ..Default::default()
        },
    );
    assert_eq!(small.cell_point.len(), 32 * 256);
    assert!(small.stats.filled_cells as f64 / (32.0 * 256.0) > 0.9);
}

proptest! {
    #[test]
    fn points_in_the_fov_land_inside_the_map(yaw in -44.99f64..44.99, elev in -24.0f64..2.0, r in 1.0f64..80.0) {
        let (y, e) = (yaw.to_radians(), elev.to_radians());
        let p = kitti2pgm::geom::Point3::new((r * e.cos() * y.cos()) as f32, (r * e.cos() * y.sin()) as f32, (r * e.sin()) as f32);
        let spec = PgmSpec::default();
        let col = spec.column(&p).expect("inside the FOV");
        prop_assert!(col < 512);
        let expected = ((45.0 - yaw) / (90.0 / 512.0)).floor() as usize;
        prop_assert!(col.abs_diff(expected) <= 1);
        prop_assert!(spec.elevation_row(&p, r as f32) < 64);
    }
}

/// The fast column (single-precision atan2, checked near borders) is the definition's on every
/// point of every real scan at hand, for the front and the full map.
#[test]
fn fast_columns_equal_the_definition_on_real_scans() {
    use kitti2pgm::project::{PgmSpec, RowMode};
    let mut bins = Vec::new();
    let mut stack = vec![
        raw_root(),
        fixtures().join("../semantickitti"),
        fixtures().join("../kitti_object"),
    ];
    let sk = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/semantickitti");
    if sk.is_dir() {
        stack.push(sk);
    }
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().is_some_and(|x| x == "bin") {
                bins.push(p);
            }
        }
    }
    assert!(bins.len() >= 5);
    let specs = [
        PgmSpec::default(),
        PgmSpec {
            fov: kitti2pgm::geom::Degrees(360.0),
            cols: 2048,
            row_mode: RowMode::Rings,
            ..Default::default()
        },
    ];
    for bin in bins {
        let scan = Scan::read(&bin).unwrap();
        for spec in &specs {
            for p in &scan.points {
                assert_eq!(
                    spec.column_fast(p),
                    spec.column(p),
                    "{}: {p:?}",
                    bin.display()
                );
            }
        }
    }
}
