//! Calibration: the matrices' form (read-time checks already refuse rotations that are not
//! orthonormal), the share of front points that land in the image, and the camera/LiDAR
//! alignment judged from depth edges against image edges.

use std::path::Path;

use serde::Serialize;

use super::read::DriveRead;
use super::{CheckName as C, Collector, Severity as S};
use crate::geom::{check_rotation, na, Matrix3x4, Point3};
use crate::project::camera::pixel;
use crate::source::kitti::calib::CAM_TO_CAM;
use crate::source::kitti::DatasetKind;

/// Checks the form of the calibration matrices a drive uses.
pub(crate) fn check_files(r: &DriveRead, c: &mut Collector) {
    let drive = &r.drive;
    if let Some(cal) = r.calib() {
        let file = drive.date_dir().join(CAM_TO_CAM);
        for (i, cam) in cal.cam_to_cam.cameras.iter().enumerate() {
            if let Err(e) = check_rotation(&cam.r) {
                c.add(
                    C::Calibration,
                    S::Error,
                    &file,
                    None,
                    None,
                    format!("R_{i:02} {e}"),
                );
            }
            rect_angle(c, &file, &format!("R_rect_{i:02}"), &cam.r_rect);
            projection(
                c,
                &file,
                &format!("P_rect_{i:02}"),
                &cam.p_rect,
                Some([cam.size_rect.x, cam.size_rect.y]),
            );
        }
    }
    if let Some(fc) = r.frame_calib() {
        frame_calib(c, &drive.calib_path(0), fc);
    }
    for (&f, (_, fc)) in r.objects() {
        frame_calib(c, &drive.calib_path(f), fc);
    }
}

fn frame_calib(c: &mut Collector, file: &Path, fc: &crate::source::kitti::calib::FrameCalib) {
    rect_angle(c, file, "R0_rect", &fc.r0_rect);
    for (i, p) in fc.p.iter().enumerate() {
        projection(c, file, &format!("P{i}"), p, None);
    }
}

fn rect_angle(c: &mut Collector, file: &Path, key: &str, m: &na::Matrix3<f64>) {
    let angle = crate::geom::nearest_rotation(m).angle().to_degrees();
    if angle > c.t().max_rect_angle_deg {
        c.add(C::Calibration, S::Warning, file, None, None,
            format!("{key} rotates by {angle:.2} degrees (above {} degrees; KITTI's rectification is under 1)", c.t().max_rect_angle_deg));
    }
}

/// A rectified projection is `[fx 0 cx tx; 0 fy cy ty; 0 0 1 tz]` with fx, fy > 0.
fn projection(c: &mut Collector, file: &Path, key: &str, p: &Matrix3x4, size: Option<[f64; 2]>) {
    let (fx, fy, cx, cy) = (p[(0, 0)], p[(1, 1)], p[(0, 2)], p[(1, 2)]);
    let form = p[(0, 1)].abs() < 1e-6 * fx.abs().max(1.0)
        && p[(1, 0)].abs() < 1e-6 * fy.abs().max(1.0)
        && p[(2, 0)] == 0.0
        && p[(2, 1)] == 0.0
        && p[(2, 2)] == 1.0
        && fx > 0.0
        && fy > 0.0;
    if !form {
        c.add(C::Calibration, S::Error, file, None, None,
            format!("{key} is not a rectified projection [fx 0 cx tx; 0 fy cy ty; 0 0 1 tz] with fx, fy > 0: {:?}", p.as_slice()));
        return;
    }
    let ratio = fx / fy;
    if ratio.max(1.0 / ratio) > c.t().max_focal_ratio {
        c.add(C::Calibration, S::Warning, file, None, None,
            format!("{key}: fx {fx:.1} and fy {fy:.1} differ by more than a factor {} (square pixels expected)", c.t().max_focal_ratio));
    }
    if let Some([w, h]) = size {
        if !(0.0..=w).contains(&cx) || !(0.0..=h).contains(&cy) {
            c.add(
                C::Calibration,
                S::Error,
                file,
                None,
                None,
                format!("{key}: principal point ({cx:.1}, {cy:.1}) outside the {w}x{h} image"),
            );
        }
    }
}

/// The points a correct camera must see: 8 m or more ahead, within 35 degrees left or right
/// and 10 degrees up or down of the velodyne's forward axis.
pub(crate) fn front(p: &Point3) -> bool {
    let (x, y, z) = (p.x, p.y, p.z);
    x > 8.0 && y.abs() < x * 0.7 && z.abs() < x * 0.176
}

/// Share of the front points that land inside a `w` x `h` image.
pub(crate) fn overlap_share(
    points: &[Point3],
    proj: &Matrix3x4,
    [w, h]: [f64; 2],
) -> Option<(usize, usize)> {
    let mut total = 0;
    let mut inside = 0;
    for p in points.iter().filter(|p| front(p)) {
        total += 1;
        if let Some((u, v)) = pixel(proj, p) {
            inside += (u >= 0.0 && v >= 0.0 && u < w && v < h) as usize;
        }
    }
    (total > 0).then_some((inside, total))
}

/// How well the image's edges fit the scan's depth edges, per drive.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Alignment {
    /// How far the edge strength at the calibrated position stands above its mean over every
    /// image offset within the search radius, in standard deviations (a z-score): about 3 for
    /// KITTI's own calibration, about 0 for the other camera's.
    pub score: f64,
    /// The image offset (pixels, right and down) at which the depth edges meet the strongest
    /// image edges.
    pub best_offset_px: [i32; 2],
    /// Frames used.
    pub frames: usize,
    /// Depth-edge points used.
    pub edge_points: usize,
}

/// The search radius of the alignment, pixels.
pub(crate) const SEARCH_PX: i32 = 20;

/// Edge scores of one frame over every offset in `[-SEARCH_PX, SEARCH_PX]^2` (row-major by dy,
/// then dx) and the number of depth-edge points: depth edges are neighbouring points in scan
/// order whose ranges differ by more than a metre (the nearer one marks the edge).
pub(crate) fn edge_scores(
    points: &[Point3],
    proj: &Matrix3x4,
    image: &crate::raster::RgbImage,
) -> (Vec<f64>, usize) {
    let (w, h) = (image.width() as i32, image.height() as i32);
    let grad = gradient(image);
    let range = |p: &Point3| p.coords.norm();
    let mut pixels = Vec::new();
    for k in 1..points.len() {
        let (a, b) = (&points[k - 1], &points[k]);
        let (ra, rb) = (range(a), range(b));
        if (ra - rb).abs() <= 1.0 || a.x <= 2.0 || b.x <= 2.0 {
            continue;
        }
        let near = if ra < rb { a } else { b };
        if let Some((u, v)) = pixel(proj, near) {
            let (u, v) = (u.round() as i32, v.round() as i32);
            let m = SEARCH_PX + 1;
            if u >= m && v >= m && u < w - m && v < h - m {
                pixels.push((u, v));
            }
        }
    }
    let n = (2 * SEARCH_PX + 1) as usize;
    let mut scores = vec![0.0; n * n];
    for (i, s) in scores.iter_mut().enumerate() {
        let (dy, dx) = ((i / n) as i32 - SEARCH_PX, (i % n) as i32 - SEARCH_PX);
        *s = pixels
            .iter()
            .map(|&(u, v)| grad[((v + dy) * w + u + dx) as usize] as f64)
            .sum();
    }
    (scores, pixels.len())
}

/// The grey image's gradient magnitude, blurred over 5x5 so that the optimum has a basin.
fn gradient(image: &crate::raster::RgbImage) -> Vec<f32> {
    let (w, h) = (image.width() as usize, image.height() as usize);
    let grey: Vec<f32> = image
        .pixels()
        .map(|p| (p[0] as f32 + p[1] as f32 + p[2] as f32) / 3.0)
        .collect();
    let mut g = vec![0.0f32; w * h];
    for y in 1..h.saturating_sub(1) {
        for x in 1..w.saturating_sub(1) {
            let i = y * w + x;
            g[i] = (grey[i + 1] - grey[i - 1]).abs() + (grey[i + w] - grey[i - w]).abs();
        }
    }
    for (step, len) in [(1usize, w), (w, h)] {
        let src = g.clone();
        for (i, v) in g.iter_mut().enumerate() {
            let pos = if step == 1 { i % w } else { i / w };
            let mut sum = 0.0;
            for d in -2i64..=2 {
                let q = pos as i64 + d;
                if q >= 0 && (q as usize) < len {
                    sum += src[(i as i64 + d * step as i64) as usize];
                }
            }
            *v = sum / 5.0;
        }
    }
    g
}

/// The drive's alignment from the summed scores of its sampled frames, and a finding when the
/// calibrated position does not stand out.
pub(crate) fn judge(
    c: &mut Collector,
    file: &Path,
    scores: &[f64],
    frames: usize,
    edge_points: usize,
    first_frame: u32,
) -> Option<Alignment> {
    if edge_points == 0 || scores.is_empty() {
        return None;
    }
    let n = (2 * SEARCH_PX + 1) as usize;
    let (best, _) = scores
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.total_cmp(b.1).then(b.0.cmp(&a.0)))?;
    let mean = scores.iter().sum::<f64>() / scores.len() as f64;
    let sd = (scores.iter().map(|s| (s - mean).powi(2)).sum::<f64>() / scores.len() as f64).sqrt();
    let a = Alignment {
        score: if sd > 0.0 {
            (scores[n * n / 2] - mean) / sd
        } else {
            0.0
        },
        best_offset_px: [(best % n) as i32 - SEARCH_PX, (best / n) as i32 - SEARCH_PX],
        frames,
        edge_points,
    };
    if a.score < c.t().alignment_min_score {
        c.add(C::CameraAlignment, S::Warning, file, Some(first_frame), None,
            format!("the scans' depth edges do not meet the image's edges where the calibration puts them: score {:.2} (below {}; KITTI's own calibration scores about 3), best fit at offset ({}, {}) px: a wrong calibration or swapped cameras ({} frames, {} edge points)",
                a.score, c.t().alignment_min_score, a.best_offset_px[0], a.best_offset_px[1], frames, edge_points));
    }
    Some(a)
}

/// The calibration file of a drive's camera (for findings).
pub(crate) fn camera_file(r: &DriveRead, frame: u32) -> std::path::PathBuf {
    let d = &r.drive;
    match d.dataset {
        DatasetKind::Raw => d.date_dir().join(CAM_TO_CAM),
        _ => d.calib_path(frame),
    }
}
