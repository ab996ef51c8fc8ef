//! Pictures of a converted frame: range, intensity, colour (when present) and labels, stacked.
//!
//! Each panel is the map as a person would look at it (row 0 on top, column 0 = left edge of the
//! field of view), rows doubled so that a 64 x 512 map is not a thin strip. Empty cells are black.
//! Labels use the paper's colours (background red, car green, pedestrian light blue, cyclist violet).

use image::{Rgb, RgbImage};

use crate::error::{Error, Result};
use crate::label::Class;

/// Vertical magnification of each panel.
pub const ROW_SCALE: u32 = 2;
const GAP: u32 = 4;

/// A sequential colour map (dark blue -> green -> yellow), `t` in [0, 1].
pub fn colormap(t: f32) -> [u8; 3] {
    const STOPS: [[f32; 3]; 5] = [
        [68.0, 1.0, 84.0],
        [59.0, 82.0, 139.0],
        [33.0, 145.0, 140.0],
        [94.0, 201.0, 98.0],
        [253.0, 231.0, 37.0],
    ];
    let t = t.clamp(0.0, 1.0) * (STOPS.len() - 1) as f32;
    let i = (t.floor() as usize).min(STOPS.len() - 2);
    let f = t - i as f32;
    std::array::from_fn(|k| (STOPS[i][k] * (1.0 - f) + STOPS[i + 1][k] * f).round() as u8)
}

/// Renders an H x W x C map (SqueezeSeg channel order) to a stacked preview picture.
pub fn render(shape: &[u64], data: &[f32]) -> Result<RgbImage> {
    let [h, w, c] = match shape {
        [h, w, c] if *c == 6 || *c == 9 => [*h as usize, *w as usize, *c as usize],
        other => {
            return Err(Error::Config(format!(
                "cannot draw a map of shape {other:?}: expected H x W x 6 or 9"
            )))
        }
    };
    let at = |r: usize, col: usize, ch: usize| data[(r * w + col) * c + ch];
    let max_range = (0..h * w)
        .map(|i| data[i * c + 4])
        .fold(0f32, f32::max)
        .max(1e-3);
    let panels = if c == 9 { 4 } else { 3 };
    let ph = h as u32 * ROW_SCALE;
    let mut img = RgbImage::new(w as u32, panels * ph + (panels - 1) * GAP);
    let mut draw = |panel: u32, f: &dyn Fn(usize, usize) -> Option<[u8; 3]>| {
        for r in 0..h {
            for col in 0..w {
                let px = f(r, col).unwrap_or([0, 0, 0]);
                for k in 0..ROW_SCALE {
                    img.put_pixel(
                        col as u32,
                        panel * (ph + GAP) + r as u32 * ROW_SCALE + k,
                        Rgb(px),
                    );
                }
            }
        }
    };
    let valid = |r: usize, col: usize| at(r, col, 4) > 0.0;
    // Range: near is bright; square root spreads the near field where most points are.
    draw(0, &|r, col| {
        valid(r, col).then(|| colormap(1.0 - (at(r, col, 4) / max_range).sqrt()))
    });
    draw(1, &|r, col| valid(r, col).then(|| colormap(at(r, col, 3))));
    let mut next = 2;
    if c == 9 {
        draw(2, &|r, col| {
            let rgb = [at(r, col, 6), at(r, col, 7), at(r, col, 8)];
            (valid(r, col) && rgb.iter().any(|v| *v > 0.0))
                .then(|| rgb.map(|v| (v * 255.0).round() as u8))
        });
        next = 3;
    }
    draw(next, &|r, col| {
        valid(r, col).then(|| {
            Class::from_id(at(r, col, 5) as u8)
                .unwrap_or_default()
                .colour()
        })
    });
    Ok(img)
}

/// Draws ASCII `text` with its top-left corner at (x, y), each font pixel `scale` x `scale`
/// (font8x8's public-domain 8x8 glyphs). Pixels outside the image are skipped.
pub fn draw_text(img: &mut RgbImage, x: u32, y: u32, text: &str, colour: [u8; 3], scale: u32) {
    for (i, ch) in text.chars().enumerate() {
        let glyph = font8x8::legacy::BASIC_LEGACY
            .get(ch as usize)
            .copied()
            .unwrap_or([0; 8]);
        for (row, bits) in glyph.iter().enumerate() {
            for col in 0..8u32 {
                if bits >> col & 1 == 0 {
                    continue;
                }
                for dy in 0..scale {
                    for dx in 0..scale {
                        let (px, py) = (
                            x + (i as u32 * 8 + col) * scale + dx,
                            y + row as u32 * scale + dy,
                        );
                        if px < img.width() && py < img.height() {
                            img.put_pixel(px, py, Rgb(colour));
                        }
                    }
                }
            }
        }
    }
}

/// Width in pixels of `text` drawn by [`draw_text`].
pub fn text_width(text: &str, scale: u32) -> u32 {
    text.chars().count() as u32 * 8 * scale
}
