//! `kitti2pgm check`: the CLI over [`kitti2pgm::check`].

use std::collections::BTreeMap;
use std::path::Path;

use anyhow::Context as _;
use kitti2pgm::check::{check, CheckName, CheckOptions, CheckReport, Finding, Pictures, Severity};
use kitti2pgm::label::ClassMap;

use super::{progress, Global};
use crate::cli::CheckArgs;
use crate::Outcome;

impl CheckArgs {
    fn options(&self) -> anyhow::Result<CheckOptions> {
        let mut o = CheckOptions {
            layout: self.dataset,
            scans: !self.no_scans,
            imageset: self.imageset.clone(),
            sensor: self.sensor.params()?,
            ..Default::default()
        };
        o.skip = if self.only.is_empty() {
            self.skip.clone()
        } else {
            CheckName::ALL
                .iter()
                .copied()
                .filter(|c| !self.only.contains(c))
                .collect()
        };
        for pair in &self.set {
            o.thresholds.set_pair(pair).with_context(|| {
                format!("--set {pair} (`kitti2pgm check --list` names every threshold)")
            })?;
        }
        if let Some(m) = &self.class_map {
            o.class_map = Some(ClassMap::named_or_file(m)?);
        }
        Ok(o)
    }
}

pub fn run(a: CheckArgs, g: &Global) -> anyhow::Result<Outcome> {
    let opts = a.options()?;
    if a.list {
        list(&opts);
        return Ok(Outcome::Ok);
    }
    let root = a.root.clone().expect("clap requires ROOT without --list");
    if let Some(dir) = &a.pictures {
        use kitti2pgm::fs::Role;
        let mut inputs = vec![(Role::Dataset, root.as_path())];
        inputs.extend(a.imageset.as_deref().map(|p| (Role::List, p)));
        inputs.extend(
            a.sensor
                .sensor_calibration
                .as_deref()
                .map(|p| (Role::Calibration, p)),
        );
        inputs.extend(
            (a.class_map.as_deref())
                .filter(|p| p.is_file())
                .map(|p| (Role::ClassMap, p)),
        );
        kitti2pgm::fs::refuse_overlap(dir, &inputs)?;
    }
    let pb = progress::bar(0, g.progress, "checking scans");
    let pool = g.pool()?;
    let report = pool.install(|| check(&root, &opts, &|n| pb.inc(n)))?;
    pb.finish_and_clear();
    let drawn = match &a.pictures {
        Some(dir) => pictures(&root, &opts, &report, dir, a.max_pictures)?,
        None => 0,
    };
    if a.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print_table(&report, &root);
        if let Some(dir) = &a.pictures {
            println!("pictures: {drawn} written to {}", dir.display());
        }
    }
    Ok(if report.worst().is_some_and(|w| w >= a.fail_on) {
        Outcome::Findings
    } else {
        Outcome::Ok
    })
}

fn list(opts: &CheckOptions) {
    println!("checks (* reads the scans):");
    for c in CheckName::ALL {
        let star = if c.needs_scans() { "*" } else { " " };
        println!("  {star} {:<19} {}", c.as_str(), c.about());
    }
    println!("\nthresholds (--set NAME=VALUE):");
    for (name, v, about) in opts.thresholds.scalars() {
        println!("  {name:<32} {v:>8}  {about}");
    }
    for (kind, r) in &opts.thresholds.sizes {
        println!(
            "  box-size.{kind}.<l|w|h>.<min|max>  l {}-{} m, w {}-{} m, h {}-{} m",
            r.l[0], r.l[1], r.w[0], r.w[1], r.h[0], r.h[1]
        );
    }
}

/// A path relative to the root, for short lines.
fn short(path: &Path, root: &Path) -> String {
    let root = root.canonicalize().unwrap_or_else(|_| root.to_path_buf());
    path.strip_prefix(&root)
        .unwrap_or(path)
        .display()
        .to_string()
}

fn object(f: &Finding) -> String {
    f.object
        .as_ref()
        .map_or("-".into(), |o| format!("#{} {}", o.index, o.kind))
}

fn print_table(r: &CheckReport, root: &Path) {
    let mut by_check: BTreeMap<CheckName, Vec<&Finding>> = BTreeMap::new();
    for f in &r.findings {
        by_check.entry(f.check).or_default().push(f);
    }
    for (check, list) in &by_check {
        let counts: Vec<String> = [Severity::Error, Severity::Warning, Severity::Note]
            .iter()
            .map(|s| (s, list.iter().filter(|f| f.severity == *s).count()))
            .filter(|(_, n)| *n > 0)
            .map(|(s, n)| format!("{n} {s}{}", if n > 1 { "s" } else { "" }))
            .collect();
        println!("== {check} ({}): {}", counts.join(", "), check.about());
        for f in list {
            let frame = f.frame.map_or("-".into(), |n| n.to_string());
            println!(
                "  {:<7} {:<26} {:>6}  {:<18} {}",
                f.severity.as_str(),
                if f.drive.is_empty() { "-" } else { &f.drive },
                frame,
                object(f),
                f.message
            );
            println!("  {:<7} {}", "", short(&f.file, root));
        }
        println!();
    }
    println!(
        "{:<28} {:>6} {:>7} {:>9} {:>13} {:>8} {:>14}",
        "drive", "scans", "images", "annotated", "range", "in-image", "alignment"
    );
    for d in &r.drives {
        let images = d
            .images
            .get("image_02/data")
            .or(d.images.get("image_2"))
            .copied()
            .unwrap_or(0);
        let range = d
            .annotated_range
            .map_or("-".into(), |(a, b)| format!("{a}-{b}"));
        let overlap = d
            .camera_overlap
            .map_or("-".into(), |s| format!("{:.0}%", s * 100.0));
        let align = d.alignment.map_or("-".into(), |a| {
            format!(
                "{:.2} ({},{})",
                a.score, a.best_offset_px[0], a.best_offset_px[1]
            )
        });
        println!(
            "{:<28} {:>6} {:>7} {:>9} {:>13} {:>8} {:>14}",
            d.drive, d.scans, images, d.annotated, range, overlap, align
        );
    }
    println!(
        "\n{} errors, {} warnings, {} notes; {} checks over {} {} ({} scans read)",
        r.count(Severity::Error),
        r.count(Severity::Warning),
        r.count(Severity::Note),
        r.checks.len(),
        r.drives.len(),
        r.layout.units(),
        r.drives.iter().map(|d| d.scans_read).sum::<usize>()
    );
}

fn pictures(
    root: &Path,
    opts: &CheckOptions,
    r: &CheckReport,
    dir: &Path,
    max: usize,
) -> anyhow::Result<usize> {
    std::fs::create_dir_all(dir).map_err(|e| kitti2pgm::Error::Write {
        path: dir.into(),
        source: e,
    })?;
    let mut maker = Pictures::new(root, opts)?;
    let mut per_check: BTreeMap<CheckName, usize> = BTreeMap::new();
    let mut written = 0;
    for f in &r.findings {
        let n = per_check.entry(f.check).or_default();
        if *n >= max {
            continue;
        }
        let Some(img) = maker.draw(f)? else { continue };
        *n += 1;
        let obj = f
            .object
            .as_ref()
            .map_or(String::new(), |o| format!("-obj{}", o.index));
        let name = format!(
            "{}-{}-{:06}{obj}.png",
            f.check,
            f.drive,
            f.frame.unwrap_or(0)
        );
        kitti2pgm::format::png::write(&dir.join(name), &img)?;
        written += 1;
    }
    Ok(written)
}
