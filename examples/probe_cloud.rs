use kitti2pgm::kitti::velodyne::Scan;
use kitti2pgm::project::*;
use std::time::Instant;
fn main() {
    let scan = Scan::read("../shared/kitti/raw/2011_09_26/2011_09_26_drive_0052_sync/velodyne_points/data/0000000000.bin".as_ref()).unwrap();
    let spec = PgmSpec {
        cols: 2048,
        fov: kitti2pgm::geom::Degrees(360.0),
        ..Default::default()
    };
    let cols = spec.columns();
    let t = |name: &str, f: &mut dyn FnMut() -> usize| {
        let mut best = f64::MAX;
        let mut acc = 0;
        for _ in 0..(std::env::var("N")
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(30))
        {
            let a = Instant::now();
            acc += f();
            best = best.min(a.elapsed().as_secs_f64());
        }
        println!("{name}: {:.3} ms ({acc})", best * 1e3);
    };
    t("atan2_fast only", &mut || {
        scan.points
            .iter()
            .map(|p| (atan2_fast(p.y, p.x) > 0.0) as usize)
            .sum()
    });
    t("atan2f libm", &mut || {
        scan.points
            .iter()
            .map(|p| (p.y.atan2(p.x) > 0.0) as usize)
            .sum()
    });
    t("columns", &mut || {
        scan.points
            .iter()
            .map(|p| cols.fast(p, 0.0).unwrap_or(0))
            .sum()
    });
    t("norm", &mut || {
        scan.points.iter().map(|p| (norm(p) > 5.0) as usize).sum()
    });
    t("rings", &mut || rings(&scan.points).1);
    t("project", &mut || {
        project(&scan.points, &spec).stats.filled_cells as usize
    });
    let mut yaw = vec![0f32; scan.points.len()];
    t("yaw pass", &mut || {
        for (y, p) in yaw.iter_mut().zip(&scan.points) {
            *y = atan2_fast(p.y, p.x);
        }
        yaw.len()
    });
    let mut code = vec![0i32; scan.points.len()];
    let mut rng = vec![0f32; scan.points.len()];
    t("pass1", &mut || {
        for ((c, r), p) in code.iter_mut().zip(rng.iter_mut()).zip(&scan.points) {
            *c = cols.code(p, 0.0f32);
            *r = norm(p);
        }
        code.len()
    });
    t("code only", &mut || {
        for (c, p) in code.iter_mut().zip(&scan.points) {
            *c = cols.code(p, 0.0f32);
        }
        code.len()
    });
    t("norm only", &mut || {
        for (r, p) in rng.iter_mut().zip(&scan.points) {
            *r = norm(p);
        }
        rng.len()
    });
    let (rr, _) = rings(&scan.points);
    let rr = rr.unwrap();
    t("pass2 only", &mut || {
        let mut cp = vec![u32::MAX; spec.cells()];
        let mut cr = vec![0f32; spec.cells()];
        for i in 0..code.len() {
            let c = code[i];
            if c < 0 {
                continue;
            }
            let cell = rr[i] as usize * 2048 + c as usize;
            if cp[cell] == u32::MAX || rng[i] < cr[cell] {
                cp[cell] = i as u32;
                cr[cell] = rng[i];
            }
        }
        cp.len()
    });
    t("alloc 3MB zeroed", &mut || vec![0f32; 64 * 2048 * 6].len());
}
#[allow(dead_code)]
fn unused() {}
