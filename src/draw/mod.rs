//! Pictures: previews of converted frames, the charts of `stats` and `score`, and the small
//! drawing kit they share (a colour map and an 8x8 bitmap font).
//!
//! - [`preview`]: a converted frame, panel by panel;
//! - [`charts`]: the class-balance chart, the confusion matrix, a frame's prediction beside its
//!   ground truth;
//! - [`boxes`]: a scan with its boxes from above or over the camera image; [`labelled`]: the
//!   scans of a sequence labelled from boxes, each with its boxes.
//!
//! Class colours always come from the class map.

pub mod boxes;
pub mod charts;
pub mod labelled;
pub mod points;
pub mod preview;

use crate::raster::{Rgb, RgbImage};

/// Vertical magnification of map pictures (a 64 x 512 map is not a thin strip).
pub const ROW_SCALE: u32 = 2;

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

/// Fills the `w` x `h` rectangle with its top-left corner at (x, y); pixels outside the image
/// are skipped.
pub fn fill_rect(img: &mut RgbImage, (x, y): (u32, u32), (w, h): (u32, u32), colour: [u8; 3]) {
    for py in y..y.saturating_add(h).min(img.height()) {
        for px in x..x.saturating_add(w).min(img.width()) {
            img.put_pixel(px, py, Rgb(colour));
        }
    }
}

/// Draws a `rows x cols` map from pixel row `y0` down, each cell one pixel wide and
/// [`ROW_SCALE`] high, in the colour `colour(row, col)` gives it.
pub fn draw_map(
    img: &mut RgbImage,
    y0: u32,
    (rows, cols): (usize, usize),
    colour: impl Fn(usize, usize) -> [u8; 3],
) {
    for r in 0..rows {
        for c in 0..cols {
            let y = y0 + r as u32 * ROW_SCALE;
            fill_rect(img, (c as u32, y), (1, ROW_SCALE), colour(r, c));
        }
    }
}

/// Width in pixels of `text` drawn by [`draw_text`].
pub fn text_width(text: &str, scale: u32) -> u32 {
    text.chars().count() as u32 * 8 * scale
}
