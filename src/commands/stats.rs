//! `kitti2pgm stats`: the CLI over [`kitti2pgm::report::stats`].

use std::fmt::Write as _;
use std::path::Path;

use anyhow::Context;
use kitti2pgm::draw::charts::balance_chart;
use kitti2pgm::format::{imageset, png};
use kitti2pgm::report::stats::{stats, SplitFrames, SplitStats, Stats};
use kitti2pgm::report::truth::{GroundTruth, Provenance};

use super::completeness;

use super::{progress, Global};
use crate::cli::StatsArgs;
use crate::Outcome;

fn split_lists(paths: &[std::path::PathBuf]) -> anyhow::Result<Vec<SplitFrames>> {
    let mut out = Vec::new();
    for p in paths {
        let files: Vec<std::path::PathBuf> = if p.is_dir() {
            ["train.txt", "val.txt"]
                .iter()
                .map(|f| p.join(f))
                .filter(|f| f.is_file())
                .collect()
        } else {
            vec![p.clone()]
        };
        if files.is_empty() {
            anyhow::bail!(
                "{}: no train.txt or val.txt in this ImageSet folder",
                p.display()
            );
        }
        for f in files {
            let name = f
                .file_stem()
                .and_then(|s| s.to_str())
                .unwrap_or("split")
                .to_string();
            out.push(SplitFrames {
                name,
                source: Some(f.clone()),
                frames: imageset::read(&f)?,
            });
        }
    }
    Ok(out)
}

pub fn run(a: StatsArgs, g: &Global) -> anyhow::Result<Outcome> {
    if let Some(chart) = &a.chart {
        use kitti2pgm::fs::Role;
        let mut inputs = vec![(Role::Converted, a.dir.as_path())];
        inputs.extend(a.imageset.iter().map(|p| (Role::List, p.as_path())));
        inputs.extend(a.raw.as_deref().map(|p| (Role::Dataset, p)));
        kitti2pgm::fs::refuse_overlap(chart, &inputs)?;
    }
    let gt = GroundTruth::open_with(&a.dir, completeness(a.partial))?;
    if gt.provenance == Provenance::Assumed || gt.partial.is_some() {
        eprintln!("kitti2pgm: {}", gt.provenance_note());
    }
    let splits = split_lists(&a.imageset)?;
    let total = if splits.is_empty() {
        gt.frames.len()
    } else {
        splits.iter().map(|s| s.frames.len()).sum()
    };
    let pb = progress::bar(total as u64, g.progress, "reading");
    let pool = g.pool()?;
    let s = pool
        .install(|| stats(&gt, &splits, a.raw.as_deref(), &|n| pb.inc(n)))
        .with_context(|| format!("statistics of {}", a.dir.display()))?;
    pb.finish_and_clear();
    if let Some(chart) = &a.chart {
        png::write(chart, &balance_chart(&s, &s.class_map))?;
    }
    if a.json {
        println!("{}", serde_json::to_string_pretty(&s)?);
    } else {
        print!("{}", table(&s, a.chart.as_deref()));
    }
    Ok(Outcome::Ok)
}

fn table(s: &Stats, chart: Option<&Path>) -> String {
    let mut t = String::new();
    let _ = writeln!(
        t,
        "maps {}x{}, channels {}",
        s.rows,
        s.cols,
        s.channels.join(",")
    );
    split_rows(&mut t, s);
    if s.split_order.len() > 1 {
        let _ = writeln!(t, "\nshare of each class's cells per split");
        let map = &s.class_map;
        for c in map.labelled().into_iter().map(|c| map.name(c)) {
            let shares: Vec<String> = s
                .split_order
                .iter()
                .map(|n| format!("{n} {:.1}%", 100.0 * s.class_split_share[c][n]))
                .collect();
            let _ = writeln!(t, "  {c:<12} {}", shares.join("  "));
        }
    }
    constants(&mut t, s);
    if let Some(cs) = &s.convert_summary {
        let _ = writeln!(
            t,
            "\nconversion: {} collisions, {} ring fallbacks",
            cs.projection.collisions, cs.projection.ring_fallbacks
        );
    }
    if let Some(p) = chart {
        let _ = writeln!(t, "\nchart: {}", p.display());
    }
    t
}

/// The per-split table: a column per split, a row per figure.
fn split_rows(t: &mut String, s: &Stats) {
    let names = &s.split_order;
    let _ = write!(t, "\n{:<32}", "");
    for n in names {
        let _ = write!(t, "{n:>14}");
    }
    let _ = writeln!(t);
    let row = |t: &mut String, label: &str, f: &dyn Fn(&SplitStats) -> String| {
        let _ = write!(t, "{label:<32}");
        for n in names {
            let _ = write!(t, "{:>14}", f(&s.splits[n]));
        }
        let _ = writeln!(t);
    };
    row(t, "frames", &|x| x.frames.to_string());
    row(t, "fill ratio", &|x| format!("{:.4}", x.fill_ratio));
    let all_have = |f: &dyn Fn(&SplitStats) -> bool| s.splits.values().all(f);
    if all_have(&|x| x.rgb_coverage.is_some()) {
        row(t, "cells with colour", &|x| {
            format!("{:.1}%", 100.0 * x.rgb_coverage.unwrap_or(0.0))
        });
    }
    let map = &s.class_map;
    let all = map.names();
    let labelled: Vec<&str> = map.labelled().into_iter().map(|c| map.name(c)).collect();
    for c in &all {
        row(t, &format!("{c} cells"), &|x| x.cells[*c].to_string());
    }
    if all_have(&|x| x.points.is_some()) {
        for c in &all {
            row(t, &format!("{c} points"), &|x| {
                x.points
                    .as_ref()
                    .map(|p| p[*c].to_string())
                    .unwrap_or_default()
            });
        }
    }
    for c in &labelled {
        row(t, &format!("{c} % of labelled cells"), &|x| {
            format!("{:.2}%", 100.0 * x.share_of_labelled_cells[*c])
        });
        row(t, &format!("{c} frames"), &|x| {
            x.frames_with[*c].to_string()
        });
    }
    if all_have(&|x| x.tracklets.is_some()) {
        for c in &labelled {
            let of =
                |x: &SplitStats, f: &dyn Fn(&kitti2pgm::report::stats::TrackletStats) -> u64| {
                    x.tracklets
                        .as_ref()
                        .map(|tr| f(tr).to_string())
                        .unwrap_or_default()
                };
            row(t, &format!("{c} instances"), &|x| {
                of(x, &|tr| tr.instances[*c])
            });
            row(t, &format!("{c} poses"), &|x| of(x, &|tr| tr.poses[*c]));
        }
    }
}

/// The normalisation constants and class weights.
fn constants(t: &mut String, s: &Stats) {
    let nm = &s.normalisation;
    let _ = writeln!(
        t,
        "\nnormalisation (from {}), channels {}",
        nm.from_split,
        nm.channels.join(",")
    );
    let fmt = |v: &[f64]| {
        v.iter()
            .map(|x| format!("{x:.4}"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let _ = writeln!(t, "  INPUT_MEAN [{}]", fmt(&nm.mean));
    let _ = writeln!(t, "  INPUT_STD  [{}]", fmt(&nm.std));
    let w = &s.class_weights;
    let _ = writeln!(
        t,
        "\nclass weights ({}; from {})",
        s.class_map.names().join(", "),
        w.from_split
    );
    let _ = writeln!(
        t,
        "  inverse frequency       [{}]",
        fmt(&w.inverse_frequency)
    );
    let _ = writeln!(
        t,
        "  sqrt inverse frequency  [{}]",
        fmt(&w.sqrt_inverse_frequency)
    );
    if let Some(r) = &w.reference {
        let _ = writeln!(t, "  reference (SqueezeSeg)  [{}]", fmt(r));
    }
}
