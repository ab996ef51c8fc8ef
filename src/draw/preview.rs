//! Pictures of a converted frame: range, intensity, colour (when present) and labels, stacked.
//!
//! Each panel is the map as a person would look at it (row 0 on top, column 0 = left edge of the
//! field of view), rows doubled so that a 64 x 512 map is not a thin strip. Empty cells are black.
//! Labels use the class map's colours (the paper's: background red, car green, pedestrian light
//! blue, cyclist violet).

use crate::raster::RgbImage;

use super::{colormap, draw_map, ROW_SCALE};
use crate::error::{Error, Result};
use crate::label::ClassMap;
use crate::project::Channel;
use crate::report::truth::MapFrame;

const GAP: u32 = 4;

/// Renders a frame to a stacked preview picture (range, intensity, colour when present,
/// labels), labels in the colours of `classes`.
pub fn render(frame: &MapFrame, classes: &ClassMap) -> Result<RgbImage> {
    let map = &frame.map;
    let (h, w, c) = (map.rows, map.cols, map.channels.len());
    let data = &map.data;
    let ch = |name: Channel| {
        map.channels.index(name).ok_or_else(|| {
            Error::Config(format!("frame {} has no {name} channel to draw", frame.id))
        })
    };
    let (range, intensity) = (ch(Channel::Range)?, ch(Channel::Intensity)?);
    let rgb_at = map.channels.index(Channel::R);
    let at = |r: usize, col: usize, ch: usize| data[(r * w + col) * c + ch];
    let max_range = (0..h * w)
        .map(|i| data[i * c + range])
        .fold(0f32, f32::max)
        .max(1e-3);
    let panels = if rgb_at.is_some() { 4 } else { 3 };
    let ph = h as u32 * ROW_SCALE;
    let mut img = RgbImage::new(w as u32, panels * ph + (panels - 1) * GAP);
    let mut draw = |panel: u32, f: &dyn Fn(usize, usize) -> Option<[u8; 3]>| {
        draw_map(&mut img, panel * (ph + GAP), (h, w), |r, col| {
            f(r, col).unwrap_or([0, 0, 0])
        });
    };
    let valid = |r: usize, col: usize| map.mask[r * w + col] != 0;
    // Range: near is bright; square root spreads the near field where most points are.
    draw(0, &|r, col| {
        valid(r, col).then(|| colormap(1.0 - (at(r, col, range) / max_range).sqrt()))
    });
    draw(1, &|r, col| {
        valid(r, col).then(|| colormap(at(r, col, intensity)))
    });
    let mut next = 2;
    if let Some(red) = rgb_at {
        draw(2, &|r, col| {
            let rgb = [at(r, col, red), at(r, col, red + 1), at(r, col, red + 2)];
            (valid(r, col) && rgb.iter().any(|v| *v > 0.0))
                .then(|| rgb.map(|v| (v * 255.0).round() as u8))
        });
        next = 3;
    }
    draw(next, &|r, col| {
        valid(r, col).then(|| classes.colour(map.label[r * w + col]))
    });
    Ok(img)
}

/// A picture of a label map alone (a model's prediction: `rows x cols` class ids, row-major),
/// in the class colours, rows doubled as in [`render`].
pub fn render_labels(labels: &[u8], (rows, cols): (usize, usize), classes: &ClassMap) -> RgbImage {
    let mut img = RgbImage::new(cols as u32, rows as u32 * ROW_SCALE);
    draw_map(&mut img, 0, (rows, cols), |r, c| {
        classes.colour(labels[r * cols + c])
    });
    img
}
