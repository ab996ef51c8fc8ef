//! `kitti2pgm preview`: converted frames to PNG, from `.npy` files or any ground-truth folder.

use anyhow::{bail, Context};
use kitti2pgm::draw::preview::{render, render_labels};
use kitti2pgm::format::layout::OutputDir;
use kitti2pgm::format::npy::read_any;
use kitti2pgm::format::{pgm, png, summary};
use kitti2pgm::label::ClassMap;
use kitti2pgm::report::score::read_cell_prediction;
use kitti2pgm::report::truth::{GroundTruth, MapFrame};

use crate::cli::PreviewArgs;
use crate::Outcome;

/// Per-point predictions drawn against their scans (`--raw`): one picture per frame.
fn run_points(a: &PreviewArgs, raw: &std::path::Path) -> anyhow::Result<Outcome> {
    use kitti2pgm::draw::points::point_prediction_chart;
    use kitti2pgm::report::score::Predictions;
    use kitti2pgm::report::unproject::load_point_frame;
    let gt = a.gt.as_ref().map(OutputDir::new);
    let recorded = match &gt {
        Some(d) => summary::read(&d.summary_path())?.map(|s| s.params.map.class_map),
        None => None,
    };
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let mut written = 0;
    for input in &a.inputs {
        let preds = Predictions::index(input)?;
        if !preds.points {
            bail!(
                "{}: --raw draws per-point predictions (.label files); map predictions are drawn without it",
                input.display()
            );
        }
        for (id, path) in &preds.files {
            let map = recorded
                .clone()
                .unwrap_or_else(|| ClassMap::default_for(id.layout));
            let f = load_point_frame(raw, id, path, &map, gt.as_ref())?;
            let no_truth = vec![None; f.pred.len()];
            let (rings, _) = kitti2pgm::project::rings(&f.scan.points);
            let caption = format!(
                "{id}: per-point prediction{}",
                if f.truth.is_none() {
                    " (no truth here)"
                } else {
                    ""
                }
            );
            let img = point_prediction_chart(
                &f.scan.points,
                rings.as_deref(),
                f.truth.as_deref().unwrap_or(&no_truth),
                &f.pred,
                &map,
                &caption,
            );
            png::write(&a.out.join(format!("{id}.png")), &img)?;
            written += 1;
        }
    }
    if written == 0 {
        bail!("no preview written");
    }
    Ok(Outcome::Ok)
}

pub fn run(a: PreviewArgs) -> anyhow::Result<Outcome> {
    if let Some(raw) = a.raw.clone() {
        return run_points(&a, &raw);
    }
    let is_npy = |p: &std::path::Path| p.is_file() && p.extension().is_some_and(|e| e == "npy");
    let single_file = a.inputs.len() == 1
        && is_npy(&a.inputs[0])
        && a.out
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("png"));
    let png_named = a
        .out
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("png"));
    if png_named && !single_file {
        bail!(
            "{}: several frames make several pictures: give a folder for --out (a .png name takes one .npy)",
            a.out.display()
        );
    }
    if !single_file {
        std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    }
    let (written, failed) = (std::cell::Cell::new(0usize), std::cell::Cell::new(0usize));
    let report = |r: anyhow::Result<()>| match r {
        Ok(()) => written.set(written.get() + 1),
        Err(e) => {
            eprintln!("kitti2pgm: {e:#}");
            failed.set(failed.get() + 1);
        }
    };
    for input in &a.inputs {
        if is_npy(input) {
            report((|| {
                let map = class_map(input)?;
                let out = |stem: &std::ffi::OsStr| {
                    if single_file {
                        a.out.clone()
                    } else {
                        a.out.join(stem).with_extension("png")
                    }
                };
                // A prediction (H x W labels, H x W x K scores): its labels alone.
                if let Some(shape) = prediction_shape(input, &map)? {
                    let p = read_cell_prediction(input, shape, &map)?;
                    let stem = input.file_stem().context("input has no file name")?;
                    png::write(&out(stem), &render_labels(&p.labels, shape, &map))?;
                    return Ok(());
                }
                let f = pgm::read(input)?;
                let stem = input.file_stem().context("input has no file name")?;
                let id = stem.to_string_lossy().parse().unwrap_or_default();
                let frame = MapFrame::from_pgm(id, f, &map, input)?;
                let out = if single_file {
                    a.out.clone()
                } else {
                    a.out.join(stem).with_extension("png")
                };
                png::write(&out, &render(&frame, &map)?)?;
                Ok(())
            })());
            continue;
        }
        let gt = match GroundTruth::open_with(input, super::completeness(a.partial)) {
            Ok(gt) => {
                if let Some(p) = &gt.partial {
                    eprintln!("kitti2pgm: PARTIAL: {p}");
                }
                gt
            }
            Err(e) => {
                report(Err(e.into()));
                continue;
            }
        };
        let map = &gt.params.class_map;
        let drawn = std::sync::atomic::AtomicUsize::new(0);
        let results = gt.map_frames(
            None,
            &|f| {
                let img = render(&f, map)?;
                png::write(&a.out.join(format!("{}.png", f.id)), &img)?;
                drawn.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                Ok(())
            },
            &|_| {},
        );
        // Each picture written counts, also when a later frame of the folder failed.
        let drawn = drawn.into_inner();
        if let Err(e) = results {
            eprintln!(
                "kitti2pgm: {e:#} ({drawn} previews of {} written)",
                input.display()
            );
            failed.set(failed.get() + 1);
        }
        written.set(written.get() + drawn);
    }
    let (written, failed) = (written.get(), failed.get());
    if written == 0 {
        bail!("no preview written");
    }
    if failed > 0 {
        eprintln!(
            "kitti2pgm: {written} previews written into {}, {failed} inputs failed",
            a.out.display()
        );
    }
    Ok(if failed > 0 {
        Outcome::Partial
    } else {
        Outcome::Ok
    })
}

/// The map shape of a `.npy` that holds a prediction (H x W labels, or H x W x K scores of the
/// K classes) rather than a converted frame (H x W x 6 or 9); `None` for a converted frame.
fn prediction_shape(
    npy: &std::path::Path,
    map: &ClassMap,
) -> anyhow::Result<Option<(usize, usize)>> {
    let a = read_any(npy)?;
    let d: Vec<usize> = a.shape.iter().map(|&v| v as usize).collect();
    Ok(match d[..] {
        [h, w] | [h, w, 1] => Some((h, w)),
        [h, w, k] if k == map.len() && !(a.is_float() && (k == 6 || k == 9)) => Some((h, w)),
        _ => None,
    })
}

/// The class map of a converted frame: its convert folder's (`OUT/lidar_2d/<id>.npy`), else
/// the paper's.
fn class_map(npy: &std::path::Path) -> anyhow::Result<ClassMap> {
    let out = npy.parent().and_then(|d| d.parent()).map(OutputDir::new);
    Ok(match out {
        Some(o) => summary::read(&o.summary_path())?
            .map(|s| s.params.map.class_map)
            .unwrap_or_default(),
        None => ClassMap::default(),
    })
}
