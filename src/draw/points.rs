//! A picture of per-point predictions: bird's-eye views and range views of the truth, the
//! prediction and the errors, in one image.
//!
//! Top: three bird's-eye views (x forward up, y left to the left; 80 x 80 m around the sensor at
//! 0.2 m a pixel, the nearer point drawn last). Below: three range views of the whole scan
//! (rows: the laser rings of the scan order, or elevation bins; 1024 columns over 360 degrees,
//! straight ahead in the middle; rows doubled). Truth and prediction in the class map's colours;
//! errors green where right, red where wrong, grey where not scored (no truth, an ignored class,
//! or no prediction).

use crate::raster::{Rgb, RgbImage};

use super::{draw_text, fill_rect};
use crate::geom::Point3;
use crate::label::{ClassId, ClassMap};

/// Half the side of the bird's-eye view, metres.
const BEV_HALF_M: f32 = 40.0;
/// Metres per bird's-eye pixel.
const BEV_M_PER_PX: f32 = 0.2;
/// Columns of the range view over 360 degrees.
const RANGE_COLS: u32 = 1024;

const RIGHT: [u8; 3] = [60, 170, 70];
const WRONG: [u8; 3] = [230, 40, 40];
const NOT_SCORED: [u8; 3] = [110, 110, 110];

/// What one point shows in each panel.
fn colours(truth: Option<ClassId>, pred: Option<ClassId>, map: &ClassMap) -> [Option<[u8; 3]>; 3] {
    let t = truth.map(|c| map.colour(c));
    let p = pred.map(|c| map.colour(c));
    let e = match (truth, pred) {
        (Some(t), Some(p)) if map.is_scored(t) => Some(if t == p { RIGHT } else { WRONG }),
        _ => Some(NOT_SCORED),
    };
    [t, p, e]
}

/// The picture of one scan's per-point predictions. `rows` gives each point's range-view row
/// (its laser ring, 0-63) when known; elevation bins otherwise. `caption` heads the picture.
pub fn point_prediction_chart(
    points: &[Point3],
    rows: Option<&[u8]>,
    truth: &[Option<ClassId>],
    pred: &[Option<ClassId>],
    map: &ClassMap,
    caption: &str,
) -> RgbImage {
    let side = (2.0 * BEV_HALF_M / BEV_M_PER_PX) as u32;
    let gap = 8u32;
    let head = 20u32;
    let range_h = 64 * super::ROW_SCALE;
    let width = (3 * side + 2 * gap).max(RANGE_COLS);
    let height = head + side + gap + 3 * (range_h + gap);
    let mut img = RgbImage::from_pixel(width, height, Rgb([255, 255, 255]));
    draw_text(&mut img, 4, 6, caption, [0, 0, 0], 1);
    // Panel backgrounds.
    for k in 0..3 {
        fill_rect(&mut img, (k * (side + gap), head), (side, side), [0, 0, 0]);
        let y0 = head + side + gap + k * (range_h + gap);
        fill_rect(&mut img, (0, y0), (RANGE_COLS, range_h), [0, 0, 0]);
    }
    // Farthest first, so that near points are drawn over far ones.
    let mut order: Vec<usize> = (0..points.len()).collect();
    let range = |p: &Point3| (p.x * p.x + p.y * p.y + p.z * p.z).sqrt();
    order.sort_by(|&a, &b| range(&points[b]).total_cmp(&range(&points[a])));
    for &i in &order {
        let p = &points[i];
        let cs = colours(truth[i], pred[i], map);
        // Bird's-eye: x forward is up, y left is left.
        let (u, v) = (
            ((BEV_HALF_M - p.y) / BEV_M_PER_PX) as i64,
            ((BEV_HALF_M - p.x) / BEV_M_PER_PX) as i64,
        );
        if (0..side as i64).contains(&u) && (0..side as i64).contains(&v) {
            for (k, c) in cs.iter().enumerate() {
                if let Some(c) = c {
                    img.put_pixel(k as u32 * (side + gap) + u as u32, head + v as u32, Rgb(*c));
                }
            }
        }
        let (col, row) = range_view_pixel(p, rows.map(|r| r[i]));
        for (k, c) in cs.iter().enumerate() {
            if let Some(c) = c {
                let y0 = head + side + gap + k as u32 * (range_h + gap) + row * super::ROW_SCALE;
                fill_rect(&mut img, (col, y0), (1, super::ROW_SCALE), *c);
            }
        }
    }
    for (k, name) in ["truth", "prediction", "errors (green right, red wrong)"]
        .iter()
        .enumerate()
    {
        draw_text(
            &mut img,
            k as u32 * (side + gap) + 4,
            head + 4,
            name,
            [255, 255, 255],
            1,
        );
    }
    img
}

/// The (column, row) of point `p` in the range view: azimuth over 360 degrees, straight ahead
/// in the middle; its laser `ring` as the row, or an elevation bin when the ring is not known.
fn range_view_pixel(p: &Point3, ring: Option<u8>) -> (u32, u32) {
    let yaw = p.y.atan2(p.x);
    let col = (((0.5 - yaw / (2.0 * std::f32::consts::PI)) * RANGE_COLS as f32) as i64)
        .clamp(0, RANGE_COLS as i64 - 1) as u32;
    let row = match ring {
        Some(r) => r.min(63) as u32,
        None => {
            let range = (p.x * p.x + p.y * p.y + p.z * p.z).sqrt();
            let pitch = (p.z / range.max(1e-6)).asin().to_degrees();
            (((3.0 - pitch) / 28.0 * 64.0) as i64).clamp(0, 63) as u32
        }
    };
    (col, row)
}
