//! `kitti2pgm convert`: the CLI over [`kitti2pgm::convert`].

use anyhow::Context;
use kitti2pgm::convert::{convert, ConvertOptions, FrameOutcome};
use kitti2pgm::format::layout::OutputDir;
use kitti2pgm::format::summary::ConvertSummary;
use kitti2pgm::label::ClassMap;
use kitti2pgm::plan::split::SplitRule;
use kitti2pgm::plan::{FrameSelection, Plan};
use kitti2pgm::project::camera::RgbOptions;
use kitti2pgm::project::{MapChoice, RowMode};
use kitti2pgm::provenance::{ConvertParams, MapParams, ShardParams};
use kitti2pgm::source::kitti::DatasetKind;

use super::{progress, Global};
use crate::cli::{ConvertArgs, FormatArg};
use crate::Outcome;

impl ConvertArgs {
    /// The library's parameters (validated by the library).
    fn params(&self, class_map: ClassMap, layout: DatasetKind) -> kitti2pgm::Result<ConvertParams> {
        let shard_params = ShardParams {
            compression: self.compression,
            frames_per_shard: self.shard_frames,
            viz: self.viz,
            split: self
                .split
                .rule()?
                .unwrap_or_else(|| SplitRule::default_for(layout)),
        };
        let mut sensor = self.sensor.params()?;
        if self.ouster_columns {
            let s = sensor.ok_or_else(|| {
                kitti2pgm::Error::Config(
                    "--ouster-columns needs the unit's metadata: --sensor-calibration FILE.json"
                        .into(),
                )
            })?;
            sensor = Some(s.with_ouster_columns()?);
        }
        let mut choice = self.map_choice();
        // One row per beam unless --rows says otherwise.
        choice.rows = choice.rows.or(sensor.as_ref().map(|s| s.beams));
        // Ouster's columns: its columns per frame, a full turn.
        if let Some(w) = sensor.as_ref().and_then(|s| s.own_columns()) {
            choice.cols = choice.cols.or(Some(w));
            choice.fov_deg = choice.fov_deg.or(Some(360.0));
        }
        Ok(ConvertParams {
            map: MapParams {
                spec: choice.spec(Some(layout)),
                rgb: self.rgb.then_some(RgbOptions {
                    camera: self.camera,
                    sampling: self.rgb_sampling,
                }),
                selection: if self.all_frames {
                    FrameSelection::All
                } else {
                    FrameSelection::Annotated
                },
                class_map,
                sensor,
            },
            npy: self.format.contains(&FormatArg::Npy),
            // Per-point labels go with the .npy maps (SqueezeSeg's layout); shards carry their
            // own labels.
            labels: (self.format.contains(&FormatArg::Npy)
                || self.format.contains(&FormatArg::Labels))
                && !self.no_point_labels,
            shards: self
                .format
                .contains(&FormatArg::Mcap)
                .then(|| shard_params.clone()),
            point_shards: self
                .format
                .contains(&FormatArg::Points)
                .then_some(shard_params),
        })
    }
}

impl ConvertArgs {
    /// The sensor model asked for: `--sensor` or `--sensor-calibration`.
    /// The map asked for: `--preset` and the single values.
    fn map_choice(&self) -> MapChoice {
        MapChoice {
            preset: self.preset,
            rows: self.rows,
            cols: self.cols,
            fov_deg: self.fov_deg,
            fov_up_deg: self.fov_up_deg,
            fov_down_deg: self.fov_down_deg,
            row_mode: self.row_mode,
        }
    }

    /// The class map: `--class-map`'s, else the one `kitti2pgm label` recorded beside the
    /// labels, else the default of the input's layout.
    fn class_map(&self, plan: &Plan) -> anyhow::Result<ClassMap> {
        if let Some(name_or_path) = &self.class_map {
            return Ok(ClassMap::named_or_file(name_or_path)?);
        }
        Ok(kitti2pgm::format::box_labels::default_class_map(plan)?)
    }
}

pub fn run(a: ConvertArgs, g: &Global) -> anyhow::Result<Outcome> {
    let source = a.dataset;
    let selection = if a.all_frames {
        FrameSelection::All
    } else {
        FrameSelection::Annotated
    };
    let mut plan = Plan::build_as(&a.raw_root, selection, source)?;
    // The boxes a labelled sequence was made from, for --viz.
    for e in kitti2pgm::format::box_labels::attach_imported_boxes(&mut plan) {
        eprintln!("kitti2pgm: warning: {e} (the labels convert; --viz shows no boxes)");
    }
    let opts = ConvertOptions {
        out: OutputDir::new(&a.out),
        params: a.params(a.class_map(&plan)?, plan.layout())?,
        threads: g.threads,
        durability: super::durability(a.sync),
        overwrite: a.overwrite,
        map_origin: Some(a.map_choice().origin(Some(plan.layout()))),
    };
    opts.params.validate()?;
    // A class map given as a file is an input too (the library checks the dataset and the
    // calibration table).
    if let Some(file) = a.class_map.as_deref().filter(|p| p.is_file()) {
        kitti2pgm::fs::refuse_overlap(&a.out, &[(kitti2pgm::fs::Role::ClassMap, file)])?;
    }
    // A split the user named must name frames that are there.
    if let Some(rule) = a.split.rule()? {
        let mut ids: Vec<_> = plan.frame_ids().collect();
        ids.sort();
        rule.check_against(&ids)?;
    }
    let pb = progress::bar(plan.jobs.len() as u64, g.progress, "converting");
    let summary = convert(&plan, &opts, &|o| match o {
        FrameOutcome::Done(_) => pb.inc(1),
        FrameOutcome::Failed(f) => {
            pb.suspend(|| eprintln!("kitti2pgm: {}: {}", f.what, f.error));
            pb.inc(f.frames.min(1));
        }
        FrameOutcome::Skipped(n) => pb.inc(n),
    })
    .with_context(|| format!("converting into {}", a.out.display()))?;
    pb.finish_and_clear();
    if a.json {
        println!("{}", serde_json::to_string_pretty(&summary)?);
    } else {
        print!("{}", table(&summary));
    }
    for p in &summary.not_frames {
        eprintln!("kitti2pgm: {p}: not a <frame10>.bin scan, skipped");
    }
    for p in &summary.labels_without_scan {
        eprintln!("kitti2pgm: {p}: labels of no scan (is the scan missing?), not read");
    }
    for (t, n) in &summary.unknown_object_types {
        let map = &summary.params.map.class_map;
        let class = map.name(map.class_of_object(t));
        eprintln!("kitti2pgm: {n} tracklet(s) of unknown object type {t:?}, labelled {class}");
    }
    if summary.frames_without_labels > 0 {
        let map = &summary.params.map.class_map;
        eprintln!(
            "kitti2pgm: {} frame(s) have no labels: converted with every point {}",
            summary.frames_without_labels,
            map.name(map.background)
        );
    }
    if summary.has_failures() && summary.frames_converted == 0 && summary.shards_skipped == 0 {
        return Ok(Outcome::Failed(format!(
            "nothing converted: every frame failed ({} failure(s) above)",
            summary.failures.len()
        )));
    }
    Ok(if summary.has_failures() {
        Outcome::Partial
    } else {
        Outcome::Ok
    })
}

fn pct(a: u64, b: u64) -> f64 {
    if b == 0 {
        0.0
    } else {
        100.0 * a as f64 / b as f64
    }
}

fn table(s: &ConvertSummary) -> String {
    use std::fmt::Write;
    let mut t = String::new();
    let spec = &s.params.map.spec;
    let beams = s
        .params
        .map
        .sensor
        .as_ref()
        .map(|m| match m.ouster_columns {
            true => format!(
                "the beams of {}, columns Ouster's own (measurement ids, destaggered)",
                m.name
            ),
            false => format!("the beams of {}", m.name),
        });
    let rows = match (spec.row_mode, beams) {
        (RowMode::Rings, Some(b)) => b,
        (RowMode::Rings, None) => "from the laser rings".into(),
        (RowMode::Elevation, _) => "by elevation".into(),
    };
    let shape = format!(
        "{} x {} x {}",
        spec.rows,
        spec.cols,
        s.params.map.channels().len()
    );
    let origin = s
        .map_origin
        .as_ref()
        .map_or("given directly".to_string(), ToString::to_string);
    let _ = writeln!(
        t,
        "map                 {shape:>12}  ({} deg, rows {rows}; {origin})",
        spec.fov.0
    );
    let _ = writeln!(t, "{:<20}{:>12}", s.source.units(), s.drives);
    let _ = writeln!(t, "frames converted    {:>12}", s.frames_converted);
    let _ = writeln!(t, "frames failed       {:>12}", s.frames_failed);
    for (why, n) in &s.frames_skipped {
        let _ = writeln!(t, "frames skipped      {n:>12}  ({why})");
    }
    resume_rows(&mut t, s);
    points_and_cells(&mut t, s);
    class_rows(&mut t, s);
    if !s.not_frames.is_empty() {
        let _ = writeln!(t, "not scans, skipped  {:>12}", s.not_frames.len());
    }
    for (ty, n) in &s.unknown_object_types {
        let _ = writeln!(t, "unknown object type {n:>12}  ({ty:?} tracklets)");
    }
    for f in &s.failures {
        let _ = writeln!(t, "failed: {} ({} frames): {}", f.what, f.frames, f.error);
    }
    t
}

/// What a re-run converted again and why, what it removed first.
fn resume_rows(t: &mut String, s: &ConvertSummary) {
    use std::fmt::Write;
    if let Some(why) = s.restarted {
        let _ = writeln!(
            t,
            "earlier outputs     {:>12}  (removed first: {why})",
            s.stale_removed
        );
    }
    for (why, n) in &s.reconverted {
        let _ = writeln!(t, "reconverted         {n:>12}  ({why})");
    }
    const SHOWN: usize = 5;
    for c in s.changed_inputs.iter().take(SHOWN) {
        let _ = writeln!(t, "  changed input: {c}");
    }
    if s.changed_inputs.len() > SHOWN {
        let _ = writeln!(
            t,
            "  ... and {} more changed inputs (convert_summary.json lists them all)",
            s.changed_inputs.len() - SHOWN
        );
    }
}

/// Points read and dropped, the projection's counts, shards and colour.
fn points_and_cells(t: &mut String, s: &ConvertSummary) {
    use std::fmt::Write;
    let p = &s.projection;
    let _ = writeln!(t, "points              {:>12}", s.points);
    let _ = writeln!(t, "non-finite dropped  {:>12}", s.dropped_nonfinite);
    if s.dropped_out_of_range > 0 {
        let max = kitti2pgm::source::kitti::velodyne::MAX_RANGE_M;
        let _ = writeln!(t, "beyond {max} m dropped {:>12}", s.dropped_out_of_range);
    }
    let _ = writeln!(t, "points in FOV       {:>12}", p.in_fov);
    let _ = writeln!(t, "fill ratio          {:>12.4}", s.fill_ratio());
    let _ = writeln!(
        t,
        "cell collisions     {:>12}  (nearest point kept)",
        p.collisions
    );
    if let Some(sensor) = &s.params.map.sensor {
        let _ = writeln!(
            t,
            "sensor model        {:>12}  ({} beams; rows from its ring field in {} frames, from \
             its beam table in {})",
            sensor.name, sensor.beams, p.ring_field_frames, p.beam_table_frames
        );
        let _ = writeln!(
            t,
            "points off model    {:>12}  (fit no beam: not in the sensor's frame?)",
            p.off_model
        );
    } else {
        let _ = writeln!(
            t,
            "ring fallbacks      {:>12}  (frames binned by elevation)",
            p.ring_fallbacks
        );
    }
    if s.shards_written + s.shards_skipped > 0 {
        let _ = writeln!(
            t,
            "shards written      {:>12}  ({} left as they were: complete and intact)",
            s.shards_written, s.shards_skipped
        );
    }
    if s.rgb_cells > 0 {
        let share = pct(s.rgb_cells, p.filled_cells);
        let _ = writeln!(
            t,
            "cells with colour   {:>12}  ({share:.1}% of filled)",
            s.rgb_cells
        );
    }
}

/// Labelled points and cells per class.
fn class_rows(t: &mut String, s: &ConvertSummary) {
    use std::fmt::Write;
    let _ = writeln!(
        t,
        "\nclass            points        %        cells        %"
    );
    let (pts, cells) = (&s.labelled_points, &s.labelled_cells);
    let (tp, tc) = (pts.values().sum::<u64>(), cells.values().sum::<u64>());
    for name in s.params.map.class_map.names() {
        let (np, nc) = (pts[name], cells[name]);
        let _ = writeln!(
            t,
            "{name:<14} {np:>10} {:>7.3}% {nc:>12} {:>7.3}%",
            pct(np, tp),
            pct(nc, tc)
        );
    }
}
