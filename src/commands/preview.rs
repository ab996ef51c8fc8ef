//! `kitti2pgm preview`: converted frames to PNG, from `.npy` files or any ground-truth folder.

use anyhow::{bail, Context};
use kitti2pgm::draw::preview::{render, render_labels};
use kitti2pgm::format::layout::OutputDir;
use kitti2pgm::format::npy::read_any;
use kitti2pgm::format::{pgm, png, summary};
use kitti2pgm::fs::Role;
use kitti2pgm::label::ClassMap;
use kitti2pgm::report::score::read_cell_prediction;
use kitti2pgm::report::truth::{GroundTruth, MapFrame};

use crate::cli::PreviewArgs;
use crate::Outcome;

/// Per-point predictions drawn against their scans (`--raw`): one picture per frame.
fn run_points(a: &PreviewArgs, raw: &std::path::Path) -> anyhow::Result<Outcome> {
    use kitti2pgm::draw::points::point_prediction_chart;
    use kitti2pgm::report::score::{PredictionKind, Predictions};
    use kitti2pgm::report::unproject::load_point_frame;
    let gt = a.gt.as_ref().map(OutputDir::new);
    let recorded = match &gt {
        Some(d) => summary::read(&d.summary_path())?.map(|s| s.params.map),
        None => None,
    };
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let mut written = 0;
    for input in &a.inputs {
        let preds = Predictions::index(input)?;
        if preds.kind != PredictionKind::Points {
            bail!(
                "{}: --raw draws per-point predictions (.label files); map predictions are drawn without it",
                input.display()
            );
        }
        for (id, path) in &preds.files {
            let map = (recorded.as_ref().map(|m| m.class_map.clone()))
                .unwrap_or_else(|| ClassMap::default_for(id.dataset));
            // The scan as its conversion read it: its layout, pose and beam rows.
            let sensor = recorded.as_ref().and_then(|m| m.sensor.as_ref());
            let f = load_point_frame(raw, id, path, &map, gt.as_ref(), sensor)?;
            let no_truth = vec![None; f.pred.len()];
            let rings = match f.beam_rows.clone() {
                Some(rows) => Some(rows),
                None => kitti2pgm::project::rings(&f.scan.points).0,
            };
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

pub fn run(a: PreviewArgs, g: &super::Global) -> anyhow::Result<Outcome> {
    let mut inputs: Vec<(Role, &std::path::Path)> = a
        .inputs
        .iter()
        .map(|p| (Role::Converted, p.as_path()))
        .collect();
    inputs.extend(a.raw.as_deref().map(|p| (Role::Dataset, p)));
    inputs.extend(a.gt.as_deref().map(|p| (Role::GroundTruth, p)));
    kitti2pgm::fs::refuse_overlap(&a.out, &inputs)?;
    if let Some(raw) = a.raw.clone() {
        return run_points(&a, &raw);
    }
    let png_named = a
        .out
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("png"));
    let single_file = a.inputs.len() == 1 && is_npy(&a.inputs[0]) && png_named;
    if png_named && !single_file {
        bail!(
            "{}: several frames make several pictures: give a folder for --out (a .png name takes one .npy)",
            a.out.display()
        );
    }
    if !single_file {
        std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    }
    let pool = g.pool()?;
    let (mut written, mut failed) = (0usize, 0usize);
    for input in &a.inputs {
        let labelled = labelled_sequences(input);
        let (w, f) = if !labelled.is_empty() {
            pool.install(|| preview_labelled(&labelled, &a))
        } else if is_npy(input) {
            match preview_npy(input, &a, single_file) {
                Ok(()) => (1, 0),
                Err(e) => {
                    eprintln!("kitti2pgm: {}", crate::chain_text(&e));
                    (0, 1)
                }
            }
        } else {
            pool.install(|| preview_folder(input, &a))
        };
        written += w;
        failed += f;
    }
    if written == 0 {
        bail!("no preview written");
    }
    if failed > 0 {
        eprintln!(
            "kitti2pgm: {written} previews written into {}, {failed} inputs failed",
            a.out.display()
        );
        return Ok(Outcome::Partial);
    }
    Ok(Outcome::Ok)
}

/// The sequences `kitti2pgm label` labelled at `input`: itself, or its `sequences/<NN>`.
fn labelled_sequences(input: &std::path::Path) -> Vec<std::path::PathBuf> {
    use kitti2pgm::format::box_labels::BOX_LABELS_MARKER;
    if input.join(BOX_LABELS_MARKER).is_file() {
        return vec![input.to_path_buf()];
    }
    let seqs = input.join(kitti2pgm::source::kitti::sequence::SEQUENCES);
    (kitti2pgm::fs::sorted_dir(&seqs)
        .unwrap_or_default()
        .into_iter())
    .filter(|d| d.join(BOX_LABELS_MARKER).is_file())
    .collect()
}

/// Every labelled frame of labelled sequences, from above with its boxes, in parallel:
/// (pictures written, inputs that failed); a frame that fails is said and the rest drawn.
fn preview_labelled(seqs: &[std::path::PathBuf], a: &PreviewArgs) -> (usize, usize) {
    use kitti2pgm::draw::labelled::LabelledSequence;
    use rayon::prelude::*;
    let (mut written, mut failed) = (0, 0);
    for seq in seqs {
        let s = match LabelledSequence::open(seq) {
            Ok(Some(s)) => s,
            Ok(None) => continue,
            Err(e) => {
                eprintln!("kitti2pgm: {e}");
                failed += 1;
                continue;
            }
        };
        let name = s.drive.name();
        let done: Vec<bool> = (s.frames.par_iter())
            .map(|&f| {
                let out = a.out.join(format!("{name}_{f:06}.png"));
                match s.picture(f).and_then(|img| png::write(&out, &img)) {
                    Ok(()) => true,
                    Err(e) => {
                        eprintln!("kitti2pgm: {name} {f:06}: {e}");
                        false
                    }
                }
            })
            .collect();
        written += done.iter().filter(|&&d| d).count();
        failed += done.iter().any(|&d| !d) as usize;
    }
    (written, failed)
}

fn is_npy(p: &std::path::Path) -> bool {
    p.is_file() && p.extension().is_some_and(|e| e == "npy")
}

/// One `.npy`: a converted frame, or a prediction (H x W labels, H x W x K scores) drawn as its
/// labels alone.
fn preview_npy(input: &std::path::Path, a: &PreviewArgs, single_file: bool) -> anyhow::Result<()> {
    let map = class_map(input)?;
    let stem = input.file_stem().context("input has no file name")?;
    let out = if single_file {
        a.out.clone()
    } else {
        a.out.join(stem).with_extension("png")
    };
    if let Some(shape) = prediction_shape(input, &map)? {
        let p = read_cell_prediction(input, shape, &map)?;
        png::write(&out, &render_labels(&p.labels, shape, &map))?;
        return Ok(());
    }
    let f = pgm::read(input)?;
    let id = stem.to_string_lossy().parse().unwrap_or_default();
    let frame = MapFrame::from_pgm(id, f, &map, input)?;
    png::write(&out, &render(&frame, &map)?)?;
    Ok(())
}

/// Every frame of converted data (a convert folder, lidar_2d, shards), in parallel: (pictures
/// written, 1 when the input failed). Each picture written counts, also when a later frame
/// failed.
fn preview_folder(input: &std::path::Path, a: &PreviewArgs) -> (usize, usize) {
    let gt = match GroundTruth::open_with(input, super::completeness(a.partial)) {
        Ok(gt) => gt,
        Err(e) => {
            eprintln!("kitti2pgm: {:#}", anyhow::Error::from(e));
            return (0, 1);
        }
    };
    if let Some(p) = &gt.partial {
        eprintln!("kitti2pgm: PARTIAL: {p}");
    }
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
    let drawn = drawn.into_inner();
    match results {
        Ok(_) => (drawn, 0),
        Err(e) => {
            eprintln!(
                "kitti2pgm: {e} ({drawn} previews of {} written)",
                input.display()
            );
            (drawn, 1)
        }
    }
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
