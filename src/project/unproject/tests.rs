//! The kNN and the cell method on small maps and on a real scan.

use super::*;

fn semantic() -> ClassMap {
    ClassMap::semantic_kitti()
}

#[test]
fn weights_are_one_minus_the_normalised_gaussian() {
    let w = KnnParams::default().weights();
    assert_eq!(w.len(), 25);
    let g: f32 = w.iter().map(|v| 1.0 - v).sum();
    assert!((g - 1.0).abs() < 1e-5);
    assert!(w[12] < w[0], "the centre weighs least");
    assert_eq!(w[0], w[24]);
}

#[test]
fn cell_and_knn_on_a_tiny_map() {
    // 3 x 3 map, every cell filled at range 10 with class 9 (road), but the centre cell
    // says 1 (car); the point there is at range 10 too.
    let cell_range = vec![10.0f32; 9];
    let mut pred = vec![9u8; 9];
    pred[4] = 1;
    let m = PointsInMap {
        rows: 3,
        cols: 3,
        point_cell: &[4, EMPTY],
        point_range: &[10.0, 5.0],
        cell_range: &cell_range,
    };
    let map = semantic();
    let cell = unproject(&m, &pred, &Method::Cell, &map).unwrap();
    assert_eq!(cell, vec![Some(1), None]);
    let knn = unproject(&m, &pred, &Method::Knn(KnnParams::default()), &map).unwrap();
    // Its 8 neighbours at distance 0 outvote it; padding (16 cells) is 10 m away x weight.
    assert_eq!(knn, vec![Some(9), None]);
    let bad = unproject(&m, &pred[..8], &Method::Cell, &map).unwrap_err();
    assert!(bad.to_string().contains("8 entries, expected 9"));
    let even = KnnParams {
        window: 4,
        ..Default::default()
    };
    assert!(unproject(&m, &pred, &Method::Knn(even), &map).is_err());
}

/// A map without columns (or rows) holds no point: every kernel says so, the seam wrapped or
/// not (the padded grid once indexed its first column there).
#[test]
fn an_empty_map_holds_no_point() {
    for (rows, cols) in [(4, 0), (0, 8)] {
        let m = PointsInMap {
            rows,
            cols,
            point_cell: &[EMPTY, EMPTY],
            point_range: &[3.0, 4.0],
            cell_range: &[],
        };
        for wrap_columns in [false, true] {
            let p = KnnParams {
                wrap_columns,
                ..Default::default()
            };
            for kernel in KnnKernel::available() {
                assert_eq!(knn_with(&m, &[], &p, &semantic(), kernel), vec![None, None]);
            }
            let knn = unproject(&m, &[], &Method::Knn(p), &semantic()).unwrap();
            assert_eq!(knn, vec![None, None]);
        }
    }
}

/// The kernels read the map without bounds tests, so `knn_with` (public, for the benches)
/// refuses a point outside the map rather than read past it.
#[test]
#[should_panic(expected = "point 1 is in cell 2, beyond the map's 2")]
fn knn_with_refuses_a_point_outside_the_map() {
    let m = PointsInMap {
        rows: 1,
        cols: 2,
        point_cell: &[0, 2],
        point_range: &[3.0, 4.0],
        cell_range: &[3.0, 0.0],
    };
    knn_with(
        &m,
        &[1, 1],
        &KnnParams::default(),
        &semantic(),
        KnnKernel::best(),
    );
}

/// The scalar and the eight- and sixteen-lane kernels give the same class to every point of a real
/// scan, for the usual windows, with and without the cutoff and the seam wrapped, for a
/// class map whose class 0 may win and one where it may not, on a 360-degree map and on a
/// 90-degree one (most points outside), with predictions at random, ranges rounded to whole
/// metres (many ties among distances: the keys cannot decide, the exact path does), and cell
/// ranges no point has (every point voted for on its own, none through its cell's winner), and
/// with cells emptied under their points.
#[test]
fn the_lane_kernels_are_the_scalar_one_point_for_point() {
    /// How the cell ranges differ from the map's.
    #[derive(Debug, Clone, Copy)]
    enum Off {
        No,
        Scaled,
        Emptied,
    }
    use crate::project::{norm, project_with_point_cells, MapPreset};
    use crate::source::Scan;
    let bin = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("fixtures/semantickitti/sequences/00/velodyne/000000.bin");
    let scan = Scan::read(&bin).unwrap();
    let mut state = 2026u64;
    for (preset, rounded, cells_off) in [
        (MapPreset::Full, false, Off::No),
        (MapPreset::Squeezeseg, false, Off::No),
        (MapPreset::Full, true, Off::No),
        (MapPreset::Full, false, Off::Scaled),
        (MapPreset::Full, false, Off::Emptied),
    ] {
        let spec = preset.spec();
        let proj = project_with_point_cells(&scan.points, &spec);
        let round = |r: f32| if rounded { r.round() } else { r };
        let point_range: Vec<f32> = scan.points.iter().map(|p| round(norm(p))).collect();
        let cell_range: Vec<f32> = (proj.cell_range.iter().enumerate())
            .map(|(i, &r)| match cells_off {
                Off::No => round(r),
                Off::Scaled => r * 1.0001,
                // Every seventh cell empty, its points kept (the centre of their windows
                // infinitely far, yet at distance 0).
                Off::Emptied => r * (i % 7 != 0) as u8 as f32,
            })
            .collect();
        let m = PointsInMap {
            rows: spec.rows,
            cols: spec.cols,
            point_cell: &proj.point_cell,
            point_range: &point_range,
            cell_range: &cell_range,
        };
        for map in [semantic(), ClassMap::kitti_paper()] {
            let pred: Vec<ClassId> = (0..spec.rows * spec.cols)
                .map(|_| (crate::rng::splitmix64(&mut state) % map.len() as u64) as ClassId)
                .collect();
            for (window, cutoff, wrap) in [
                (5, 1.0, false),
                (3, 0.0, true),
                (7, 0.5, false),
                (5, 0.0, true),
            ] {
                let p = KnnParams {
                    k: window,
                    window,
                    sigma: 1.0,
                    cutoff,
                    wrap_columns: wrap,
                };
                let a = knn_with(&m, &pred, &p, &map, KnnKernel::Scalar);
                for kernel in KnnKernel::available() {
                    let b = knn_with(&m, &pred, &p, &map, kernel);
                    assert_eq!(a.len(), b.len());
                    let differ = a.iter().zip(&b).filter(|(x, y)| x != y).count();
                    let what = format!(
                        "{kernel:?}: {preset:?} {rounded} {cells_off:?} {}",
                        map.name
                    );
                    assert_eq!(differ, 0, "{what} {p:?}");
                }
            }
        }
    }
}

/// On a real scan the keys decide nearly every block, in every lane kernel (the exact path is
/// the rare one: were it taken always, the classes would be the same and the speed gone).
#[cfg(target_arch = "x86_64")]
#[test]
fn the_keys_decide_nearly_every_block_of_a_real_scan() {
    use crate::project::{norm, project_with_point_cells, MapPreset};
    use crate::source::Scan;
    let bin = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("fixtures/semantickitti/sequences/00/velodyne/000000.bin");
    let scan = Scan::read(&bin).unwrap();
    let spec = MapPreset::Full.spec();
    let proj = project_with_point_cells(&scan.points, &spec);
    let point_range: Vec<f32> = scan.points.iter().map(norm).collect();
    let m = PointsInMap::of(&proj, &point_range);
    let pred: Vec<ClassId> = (0..spec.rows * spec.cols)
        .map(|i| (i % 19 + 1) as ClassId)
        .collect();
    let p = KnnParams::default();
    let lanes = [(KnnKernel::Avx2, 8), (KnnKernel::Avx512, 16)];
    for (kernel, lanes) in lanes
        .into_iter()
        .filter(|(k, _)| KnnKernel::available().contains(k))
    {
        keys::BLOCKS.with(|b| b.set((0, 0)));
        knn_with(&m, &pred, &p, &semantic(), kernel);
        let (all, exact) = keys::BLOCKS.with(|b| b.get());
        // 64 x 2048 cells in blocks of `lanes`, and the points behind a nearer one.
        assert!(all > 64 * 2048 / lanes, "{kernel:?}: {all} blocks");
        assert!(
            exact * 100 < all,
            "{kernel:?}: {exact} of {all} blocks taken exactly"
        );
    }
}

/// The lane kernels' sorting networks sort every 0-1 input (so every input: the 0-1
/// principle), and its merge (the smaller of each kept key and the added one opposite it, then
/// the bitonic sorter) gives the `k` smallest of both, sorted, on random keys with ties.
#[cfg(target_arch = "x86_64")]
#[test]
fn the_kernels_networks_sort_and_merge() {
    let run = |net: &[(u8, u8)], v: &mut [i32]| {
        for &(i, j) in net {
            let (a, b) = (v[i as usize], v[j as usize]);
            (v[i as usize], v[j as usize]) = (a.min(b), a.max(b));
        }
    };
    for n in 0..=8usize {
        for bits in 0..1u32 << n {
            let mut v: Vec<i32> = (0..n).map(|i| (bits >> i & 1) as i32).collect();
            run(vectors::network(n), &mut v);
            assert!(v.is_sorted(), "network({n}) leaves {v:?} from {bits:b}");
        }
        // Rising then falling: 0s, 1s, 0s.
        for a in 0..=n {
            for b in 0..=n - a {
                let mut v: Vec<i32> = (0..n).map(|i| (i >= a && i < a + b) as i32).collect();
                run(vectors::bitonic(n), &mut v);
                assert!(v.is_sorted(), "bitonic({n}) leaves {v:?}");
            }
        }
    }
    let mut seed = 7u64;
    let mut next = move || {
        seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (seed >> 59) as i32
    };
    for k in [3usize, 5, 7] {
        for add_n in [k - 1, k] {
            for _ in 0..2000 {
                let mut kept: Vec<i32> = (0..k).map(|_| next()).collect();
                let mut add: Vec<i32> = (0..add_n).map(|_| next()).collect();
                kept.sort();
                add.sort();
                let mut want: Vec<i32> = kept.iter().chain(&add).copied().collect();
                want.sort();
                want.truncate(k);
                for (i, slot) in kept.iter_mut().enumerate() {
                    if k - 1 - i < add_n {
                        *slot = (*slot).min(add[k - 1 - i]);
                    }
                }
                run(vectors::bitonic(k), &mut kept);
                assert_eq!(kept, want, "merge of {k} and {add_n}");
            }
        }
    }
}
