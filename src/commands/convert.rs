//! `kitti2pgm convert`: the CLI over [`kitti2pgm::pipeline`].

use anyhow::Context;
use kitti2pgm::geom::Degrees;
use kitti2pgm::pipeline::{
    convert, ConvertOptions, ConvertSummary, FrameOutcome, FrameSelection, Plan, RgbOptions,
    ShardOptions,
};
use kitti2pgm::project::camera::Sampling;
use kitti2pgm::project::{PgmSpec, RowMode};
use kitti2pgm::report::split::SplitRule;
use kitti2pgm::write::shard::ShardCompression;

use super::{progress, Global};
use crate::cli::{CompressionArg, ConvertArgs, FormatArg, RowModeArg, SamplingArg};
use crate::Outcome;

impl From<&ConvertArgs> for ConvertOptions {
    fn from(a: &ConvertArgs) -> Self {
        ConvertOptions {
            out_dir: a.out.clone(),
            spec: PgmSpec {
                rows: a.rows,
                cols: a.cols,
                fov: Degrees(a.fov_deg),
                fov_up: Degrees(a.fov_up_deg),
                fov_down: Degrees(a.fov_down_deg),
                row_mode: match a.row_mode {
                    RowModeArg::Rings => RowMode::Rings,
                    RowModeArg::Elevation => RowMode::Elevation,
                },
            },
            rgb: a.rgb.then_some(RgbOptions {
                camera: a.camera,
                sampling: match a.rgb_sampling {
                    SamplingArg::Nearest => Sampling::Nearest,
                    SamplingArg::Bilinear => Sampling::Bilinear,
                },
            }),
            selection: if a.all_frames {
                FrameSelection::All
            } else {
                FrameSelection::Annotated
            },
            write_npy: a.format.contains(&FormatArg::Npy),
            write_labels: !a.no_point_labels,
            threads: 0,
            sync: a.sync,
            shards: a.format.contains(&FormatArg::Mcap).then(|| ShardOptions {
                compression: match a.compression {
                    CompressionArg::Lz4 => ShardCompression::Lz4,
                    CompressionArg::Zstd => ShardCompression::Zstd,
                    CompressionArg::None => ShardCompression::None,
                },
                frames_per_shard: a.shard_frames,
                viz: a.viz,
                split: SplitRule::squeezeseg(),
            }),
        }
    }
}

pub fn run(a: ConvertArgs, g: &Global) -> anyhow::Result<Outcome> {
    let mut opts = ConvertOptions::from(&a);
    opts.threads = g.threads;
    if let Some(sh) = opts.shards.as_mut() {
        sh.split = a.split.rule()?;
    }
    opts.validate()?;
    let plan = Plan::build(&a.raw_root, opts.selection)
        .with_context(|| format!("reading {}", a.raw_root.display()))?;
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
    Ok(if summary.frames_failed > 0 {
        Outcome::Partial
    } else {
        Outcome::Ok
    })
}

fn table(s: &ConvertSummary) -> String {
    use std::fmt::Write;
    let mut t = String::new();
    let pct = |a: u64, b: u64| {
        if b == 0 {
            0.0
        } else {
            100.0 * a as f64 / b as f64
        }
    };
    let _ = writeln!(t, "drives              {:>12}", s.drives);
    let _ = writeln!(t, "frames converted    {:>12}", s.frames_converted);
    let _ = writeln!(t, "frames failed       {:>12}", s.frames_failed);
    for (why, n) in &s.frames_skipped {
        let _ = writeln!(t, "frames skipped      {n:>12}  ({why})");
    }
    let _ = writeln!(t, "points              {:>12}", s.points);
    let _ = writeln!(t, "non-finite dropped  {:>12}", s.dropped_nonfinite);
    let _ = writeln!(t, "points in FOV       {:>12}", s.in_fov);
    let _ = writeln!(t, "fill ratio          {:>12.4}", s.fill_ratio());
    let _ = writeln!(
        t,
        "cell collisions     {:>12}  (nearest point kept)",
        s.collisions
    );
    let _ = writeln!(
        t,
        "ring fallbacks      {:>12}  (frames binned by elevation)",
        s.ring_fallbacks
    );
    if s.shards_written + s.shards_skipped > 0 {
        let _ = writeln!(
            t,
            "shards written      {:>12}  ({} left as they were: complete and intact)",
            s.shards_written, s.shards_skipped
        );
    }
    if s.rgb_cells > 0 {
        let _ = writeln!(
            t,
            "cells with colour   {:>12}  ({:.1}% of filled)",
            s.rgb_cells,
            pct(s.rgb_cells, s.filled_cells)
        );
    }
    let _ = writeln!(t, "\nclass        points        %        cells        %");
    let (p, c) = (s.labelled_points.to_array(), s.labelled_cells.to_array());
    let (tp, tc) = (p.iter().sum::<u64>(), c.iter().sum::<u64>());
    for k in kitti2pgm::label::Class::ALL {
        let i = k as usize;
        let _ = writeln!(
            t,
            "{:<10} {:>10} {:>7.3}% {:>12} {:>7.3}%",
            k.name(),
            p[i],
            pct(p[i], tp),
            c[i],
            pct(c[i], tc)
        );
    }
    for f in &s.failures {
        let _ = writeln!(t, "failed: {} ({} frames): {}", f.what, f.frames, f.error);
    }
    t
}
