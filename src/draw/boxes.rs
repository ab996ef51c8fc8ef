//! Pictures of a scan with its boxes: a bird's-eye view (the flagged object marked) and the
//! points over the camera image, for `kitti2pgm check --pictures`.

use crate::raster::{Rgb, RgbImage};

use super::{colormap, draw_text, fill_rect};
use crate::geom::{Matrix3x4, Point3, Real, Vector3};
use crate::label::LabelBox;
use crate::project::camera::pixel;

/// A box to draw: its footprint, colour, whether it is the one flagged, and a label.
pub struct Drawn<'a> {
    /// The box.
    pub label_box: &'a LabelBox,
    /// Outline colour.
    pub colour: [u8; 3],
    /// Drawn thick, in red, with its label.
    pub flagged: bool,
    /// Text beside it (object number and type): drawn for a flagged box, and for every box when
    /// [`Drawn::show_text`] says so.
    pub text: String,
    /// Whether the text is drawn though the box is not flagged.
    pub show_text: bool,
}

/// The box's four footprint corners (velodyne x, y), in order around it.
pub fn footprint(b: &LabelBox) -> [(Real, Real); 4] {
    let h = b.cuboid.half_extents;
    let up = b.pose.rotation * Vector3::z();
    let corner = |s: Real, t: Real| {
        let local = if up.z.abs() > 0.7 {
            Point3::new(s * h.x, t * h.y, 0.0)
        } else {
            Point3::new(s * h.x, 0.0, t * h.z)
        };
        let p = b.pose * local;
        (p.x, p.y)
    };
    [
        corner(1.0, 1.0),
        corner(1.0, -1.0),
        corner(-1.0, -1.0),
        corner(-1.0, 1.0),
    ]
}

fn line(img: &mut RgbImage, (x0, y0): (i64, i64), (x1, y1): (i64, i64), c: [u8; 3], thick: i64) {
    let n = (x1 - x0).abs().max((y1 - y0).abs()).max(1);
    for k in 0..=n {
        let x = x0 + (x1 - x0) * k / n;
        let y = y0 + (y1 - y0) * k / n;
        for dx in -thick / 2..=thick / 2 {
            for dy in -thick / 2..=thick / 2 {
                let (px, py) = (x + dx, y + dy);
                if px >= 0 && py >= 0 && (px as u32) < img.width() && (py as u32) < img.height() {
                    img.put_pixel(px as u32, py as u32, Rgb(c));
                }
            }
        }
    }
}

/// A bird's-eye view `size` pixels square, `half_m` metres each side of `centre` (velodyne x
/// up the picture, y to the left), points coloured by `colours` (one a point; by height
/// without), boxes outlined, `title` on top.
pub fn bird_eye(
    points: &[Point3],
    colours: Option<&[[u8; 3]]>,
    boxes: &[Drawn],
    centre: (Real, Real),
    half_m: Real,
    title: &str,
) -> RgbImage {
    const SIZE: u32 = 800;
    let mut img = RgbImage::from_pixel(SIZE, SIZE, Rgb([12, 12, 16]));
    let scale = SIZE as Real / (2.0 * half_m);
    let to_px = |x: Real, y: Real| -> (i64, i64) {
        (
            ((centre.1 - y) * scale + SIZE as Real / 2.0) as i64,
            ((centre.0 - x) * scale + SIZE as Real / 2.0) as i64,
        )
    };
    paint_points(&mut img, points, colours, &to_px);
    for d in boxes
        .iter()
        .filter(|d| !d.flagged)
        .chain(boxes.iter().filter(|d| d.flagged))
    {
        let f = footprint(d.label_box);
        let (colour, thick) = if d.flagged {
            ([255, 40, 40], 3)
        } else {
            (d.colour, 1)
        };
        for k in 0..4 {
            line(
                &mut img,
                to_px(f[k].0, f[k].1),
                to_px(f[(k + 1) % 4].0, f[(k + 1) % 4].1),
                colour,
                thick,
            );
        }
        // The heading: front edge midpoint to centre.
        let mid = ((f[0].0 + f[1].0) / 2.0, (f[0].1 + f[1].1) / 2.0);
        let c = b_centre(d.label_box);
        line(
            &mut img,
            to_px(c.0, c.1),
            to_px(mid.0, mid.1),
            colour,
            thick,
        );
        if d.flagged || d.show_text {
            let (u, v) = to_px(f[0].0, f[0].1);
            draw_text(
                &mut img,
                (u.max(0) as u32).min(SIZE - 80),
                (v.max(0) as u32 + 6).min(SIZE - 10),
                &d.text,
                colour,
                1,
            );
        }
    }
    let (u, v) = to_px(0.0, 0.0);
    line(&mut img, (u - 4, v), (u + 4, v), [255, 255, 255], 1);
    line(&mut img, (u, v - 4), (u, v + 4), [255, 255, 255], 1);
    draw_text(&mut img, 6, 6, title, [255, 255, 255], 1);
    draw_text(
        &mut img,
        6,
        SIZE - 14,
        &format!("{:.0} m across, x forward (up), y left", 2.0 * half_m),
        [180, 180, 180],
        1,
    );
    img
}

/// Each point at its pixel, in its colour (by height without `colours`).
fn paint_points(
    img: &mut RgbImage,
    points: &[Point3],
    colours: Option<&[[u8; 3]]>,
    to_px: &dyn Fn(Real, Real) -> (i64, i64),
) {
    let (w, h) = (img.width() as i64, img.height() as i64);
    for (k, p) in points.iter().enumerate() {
        let (u, v) = to_px(p.x, p.y);
        if u >= 0 && v >= 0 && u < w && v < h {
            let c = match colours {
                Some(c) => c[k],
                None => colormap((p.z + 2.5) / 4.0),
            };
            img.put_pixel(u as u32, v as u32, Rgb(c));
        }
    }
}

fn b_centre(b: &LabelBox) -> (Real, Real) {
    let t = b.pose.translation.vector;
    (t.x, t.y)
}

/// A labelled scan from above: points in their class's colour (the background dimmed), the
/// boxes outlined in theirs with their instance ids, as far around the sensor as the nearest
/// 95% of the points and every box reach (8 to 80 m), `title` on top.
pub fn labelled_bird_eye(
    points: &[Point3],
    classes: &[crate::label::ClassId],
    boxes: &[LabelBox],
    map: &crate::label::ClassMap,
    title: &str,
) -> RgbImage {
    let colours: Vec<[u8; 3]> = (classes.iter())
        .map(|&c| {
            let rgb = map.colour(c);
            if c == map.background {
                rgb.map(|v| v / 2 + 70)
            } else {
                rgb.map(|v| v.max(60))
            }
        })
        .collect();
    let mut ranges: Vec<Real> = points.iter().map(|p| p.coords.xy().norm()).collect();
    ranges.sort_unstable_by(Real::total_cmp);
    let p95 = ranges.get(ranges.len() * 95 / 100).copied().unwrap_or(8.0);
    let reach = (boxes.iter())
        .map(|b| b.pose.translation.vector.xy().norm() + b.cuboid.half_extents.norm())
        .fold(p95, Real::max)
        .clamp(8.0, 80.0);
    let drawn: Vec<Drawn> = (boxes.iter())
        .map(|b| Drawn {
            label_box: b,
            colour: map.colour(b.class).map(|v| v.max(90)),
            flagged: false,
            text: format!("#{} {}", b.instance, map.name(b.class)),
            show_text: true,
        })
        .collect();
    bird_eye(points, Some(&colours), &drawn, (0.0, 0.0), reach, title)
}

/// The scan's points over the camera image, coloured by distance (near yellow, far blue), with
/// `title` on top.
pub fn camera_overlay(
    image: &RgbImage,
    points: &[Point3],
    proj: &Matrix3x4,
    title: &str,
) -> RgbImage {
    let mut img = image.clone();
    for p in points.iter().filter(|p| p.x > 1.0) {
        let Some((u, v)) = pixel(proj, p).filter(|&(u, v)| u >= 0.0 && v >= 0.0) else {
            continue;
        };
        // 2 x 2 pixels a point, so that the points read against the picture.
        let c = colormap(1.0 - (p.coords.norm() / 40.0).min(1.0));
        fill_rect(&mut img, (u as u32, v as u32), (2, 2), c);
    }
    // The title on a dark band (the sky is bright).
    let width = img.width();
    fill_rect(&mut img, (0, 0), (width, 18), [12, 12, 16]);
    draw_text(&mut img, 6, 5, title, [255, 255, 255], 1);
    img
}
