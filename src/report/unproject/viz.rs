//! The per-point predictions as a Foxglove file (`unproject --viz`).

use std::path::Path;

use super::{load_point_frame, UnprojectOptions};
use crate::error::Result;
use crate::format::layout::point_prediction_path;
use crate::fs::Role;
use crate::label::ClassId;
use crate::report::score::Predictions;
use crate::report::truth::GroundTruth;
use crate::source::kitti::FrameId;

/// Refuses a visualisation file `viz` that is, lies inside or holds an input of the run: the
/// ground truth, the map predictions, the dataset, or the per-point predictions' folder.
pub fn refuse_viz_over_inputs(
    viz: &Path,
    gt: &GroundTruth,
    preds: &Predictions,
    opts: &UnprojectOptions,
) -> Result<()> {
    crate::fs::refuse_overlap(
        viz,
        &[
            (Role::GroundTruth, &gt.path),
            (Role::Predictions, &preds.root),
            (Role::Dataset, &opts.raw),
            (Role::Predictions, &opts.out),
        ],
    )
}

/// Writes the per-point predictions of `frames` (as [`super::unproject_all`] wrote them under
/// `opts.out`) to an MCAP file for Foxglove (`/kitti2pgm/viz/points`, atomically): each scan's
/// points coloured by their predicted class, the points whose prediction differs from the truth
/// (where there is one) in red with class number `classes.len()`, points outside the map left
/// out. One message per frame, in frame order, 100 ms apart. `path` over an input is refused
/// ([`refuse_viz_over_inputs`]; a caller checks it before the work as well).
pub fn write_viz(
    gt: &GroundTruth,
    preds: &Predictions,
    opts: &UnprojectOptions,
    frames: &[FrameId],
    path: &Path,
) -> Result<()> {
    use crate::format::shard::viz::{VizFile, VizFrame};
    refuse_viz_over_inputs(path, gt, preds, opts)?;
    let map = &gt.params.class_map;
    let wrong = map.len() as ClassId;
    let mut colours: Vec<[u8; 3]> = (0..map.len()).map(|c| map.colour(c as ClassId)).collect();
    colours.push([255, 0, 0]);
    let mut file = VizFile::create(path)?;
    for (k, id) in frames.iter().enumerate() {
        let f = load_point_frame(
            &opts.raw,
            id,
            &point_prediction_path(&opts.out, id),
            map,
            gt.dir.as_ref(),
            gt.params.sensor.as_ref(),
        )?;
        let mut v = VizFrame {
            colours: colours.clone(),
            ..Default::default()
        };
        for (i, p) in f.pred.iter().enumerate() {
            let Some(p) = *p else {
                continue;
            };
            let t = f.truth.as_ref().and_then(|t| t[i]);
            let c = match t {
                Some(t) if map.is_scored(t) && t != p => wrong,
                _ => p,
            };
            v.points.push((f.scan.points[i], f.scan.intensity[i], c));
        }
        let time = k as u64 * 100_000_000;
        file.write(&v, k as u32, time)?;
    }
    file.finish()
}
