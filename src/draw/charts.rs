//! Charts: the class balance of `stats`, the confusion matrix and the worst frames of `score`.

use super::{draw_map, draw_text, fill_rect, text_width, ROW_SCALE};
use crate::label::ClassId;
use crate::label::ClassMap;
use crate::report::score::{Confusion, FrameMaps};
use crate::report::stats::Stats;

/// A picture of the confusion matrix: rows = truth, columns = prediction, each cell shaded by
/// its share of the row (recall view), with the count and the share written in it.
pub fn confusion_chart(c: &Confusion, map: &ClassMap) -> crate::raster::RgbImage {
    let k = c.k();
    let (cell, left, top) = (120u32, 112u32, 64u32);
    let mut img = crate::raster::RgbImage::from_pixel(
        left + k as u32 * cell + 16,
        top + k as u32 * cell + 40,
        crate::raster::Rgb([255, 255, 255]),
    );
    let black = [0, 0, 0];
    draw_text(&mut img, left, 8, "prediction", black, 1);
    draw_text(&mut img, 8, 8, "truth", black, 1);
    for i in 0..k {
        let name = map.name(i as u8);
        draw_text(
            &mut img,
            left + i as u32 * cell + (cell - text_width(name, 1).min(cell)) / 2,
            top - 20,
            name,
            black,
            1,
        );
        draw_text(
            &mut img,
            8,
            top + i as u32 * cell + cell / 2 - 4,
            name,
            black,
            1,
        );
    }
    for g in 0..k {
        let row: u64 = c.m[g].iter().sum();
        for p in 0..k {
            let share = if row == 0 {
                0.0
            } else {
                c.m[g][p] as f64 / row as f64
            };
            let shade = (255.0 - share * 200.0) as u8;
            let colour = if g == p {
                [shade, 255, shade]
            } else {
                [255, shade, shade]
            };
            let (x0, y0) = (left + p as u32 * cell, top + g as u32 * cell);
            fill_rect(&mut img, (x0, y0), (cell - 2, cell - 2), colour);
            let count = c.m[g][p].to_string();
            let pct = format!("{:.1}%", share * 100.0);
            draw_text(
                &mut img,
                x0 + (cell - text_width(&count, 1)) / 2,
                y0 + cell / 2 - 12,
                &count,
                black,
                1,
            );
            draw_text(
                &mut img,
                x0 + (cell - text_width(&pct, 1)) / 2,
                y0 + cell / 2 + 4,
                &pct,
                black,
                1,
            );
        }
    }
    let miou = format!("mIoU {:.3}", c.miou_for(map));
    draw_text(&mut img, left, top + k as u32 * cell + 12, &miou, black, 1);
    img
}

/// Side-by-side picture of one frame: prediction above ground truth, in the class colours
/// (empty cells black), rows doubled, with a caption.
pub fn frame_chart(
    id: &str,
    maps: &FrameMaps,
    (rows, cols): (usize, usize),
    miou: Option<f64>,
    map: &ClassMap,
) -> crate::raster::RgbImage {
    let ph = rows as u32 * ROW_SCALE;
    let caption = 20u32;
    let mut img = crate::raster::RgbImage::from_pixel(
        cols as u32,
        2 * (ph + caption),
        crate::raster::Rgb([255, 255, 255]),
    );
    let m = miou
        .map(|v| format!("{v:.3}"))
        .unwrap_or_else(|| "-".into());
    draw_text(
        &mut img,
        4,
        6,
        &format!("{id} prediction, mIoU {m}"),
        [0, 0, 0],
        1,
    );
    draw_text(&mut img, 4, ph + caption + 6, "ground truth", [0, 0, 0], 1);
    for (panel, labels) in [&maps.pred, &maps.truth].iter().enumerate() {
        let y0 = panel as u32 * (ph + caption) + caption;
        draw_map(&mut img, y0, (rows, cols), |r, c| {
            let i = r * cols + c;
            if maps.truth[i] == u8::MAX {
                [0, 0, 0]
            } else {
                map.colour(labels[i])
            }
        });
    }
    img
}

/// A bar chart of the class balance: one group of bars per split (each labelled class: share
/// of the labelled cells, linear 0-100%, value on top), class colours as in the previews, a
/// light line every 10%, the split name and frame count under each group, a legend on top.
pub fn balance_chart(s: &Stats, map: &ClassMap) -> crate::raster::RgbImage {
    let classes = map.labelled();
    let nc = classes.len().max(1) as u32;
    let (gap, group_gap, h, left, bottom) = (8u32, 48u32, 300u32, 48u32, 40u32);
    let bar = (168 / nc).max(12);
    let n = s.split_order.len().max(1) as u32;
    let group = nc * bar + (nc - 1) * gap;
    let w = left + n * group + (n - 1) * group_gap + 24;
    let w = w.max(420);
    let legend = legend_layout(&classes, map, left, w);
    let top = legend.last().map_or(22, |&(_, _, y)| y) + 34;
    let mut img = crate::raster::RgbImage::from_pixel(
        w,
        top + h + bottom,
        crate::raster::Rgb([255, 255, 255]),
    );
    let black = [0, 0, 0];
    draw_text(
        &mut img,
        left,
        6,
        "share of labelled cells per split",
        black,
        1,
    );
    for &(class, lx, ly) in &legend {
        fill_rect(&mut img, (lx, ly), (12, 12), map.colour(class));
        draw_text(&mut img, lx + 16, ly + 2, map.name(class), black, 1);
    }
    percent_grid(&mut img, (left, w - 8), (top, h));
    for (g, name) in s.split_order.iter().enumerate() {
        let split = &s.splits[name];
        let x_group = left + g as u32 * (group + group_gap);
        for (b, &class) in classes.iter().enumerate() {
            let v = split
                .share_of_labelled_cells
                .get(map.name(class))
                .copied()
                .unwrap_or(0.0);
            let bh = (v * h as f64).round() as u32;
            let x0 = x_group + b as u32 * (bar + gap);
            fill_rect(&mut img, (x0, top + h - bh), (bar, bh), map.colour(class));
            let label = format!("{:.1}%", v * 100.0);
            // Values only where they fit above their bar (the table and JSON have them all).
            if text_width(&label, 1) > bar + gap {
                continue;
            }
            let lx = x0 + bar.saturating_sub(text_width(&label, 1)) / 2;
            draw_text(
                &mut img,
                lx,
                (top + h - bh).saturating_sub(12),
                &label,
                black,
                1,
            );
        }
        let caption = format!("{name} ({} frames)", split.frames);
        let cx = x_group + group.saturating_sub(text_width(&caption, 1)) / 2;
        draw_text(&mut img, cx, top + h + 12, &caption, black, 1);
    }
    img
}

/// Where each class's legend entry goes: (class, x, y), wrapping to the picture's width `w`
/// (the 19 classes of SemanticKITTI take lines).
fn legend_layout(
    classes: &[ClassId],
    map: &ClassMap,
    left: u32,
    w: u32,
) -> Vec<(ClassId, u32, u32)> {
    let mut legend = Vec::with_capacity(classes.len());
    let (mut lx, mut ly) = (left, 22u32);
    for &class in classes {
        let item = 16 + text_width(map.name(class), 1) + 20;
        if lx > left && lx + item > w {
            (lx, ly) = (left, ly + 16);
        }
        legend.push((class, lx, ly));
        lx += item;
    }
    legend
}

/// The 0-100% axis of a bar chart from `left` to `right` over the `h` pixels below `top`: a
/// light line every 10% (black at 0), labelled every 20%.
fn percent_grid(
    img: &mut crate::raster::RgbImage,
    (left, right): (u32, u32),
    (top, h): (u32, u32),
) {
    let black = [0, 0, 0];
    for t in 0..=10 {
        let y = top + h - t * h / 10;
        let colour = if t == 0 { black } else { [225, 225, 225] };
        fill_rect(img, (left, y), (right.saturating_sub(left), 1), colour);
        if t % 2 == 0 {
            let label = format!("{}%", t * 10);
            let x = left.saturating_sub(text_width(&label, 1) + 4);
            draw_text(img, x, y.saturating_sub(4), &label, black, 1);
        }
    }
}
