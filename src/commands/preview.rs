//! `kitti2pgm preview`: converted frames to PNG.

use anyhow::{bail, Context};
use kitti2pgm::format::layout::OutputDir;
use kitti2pgm::format::{pgm, png, summary};
use kitti2pgm::label::ClassMap;

use crate::cli::PreviewArgs;
use crate::Outcome;

pub fn run(a: PreviewArgs) -> anyhow::Result<Outcome> {
    let single_file = a.inputs.len() == 1
        && a.out
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("png"));
    if !single_file {
        std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    }
    let mut failed = 0;
    for input in &a.inputs {
        let result = (|| -> anyhow::Result<()> {
            let map = pgm::read(input)?;
            let img = kitti2pgm::draw::preview::render(&map, &class_map(input)?)
                .with_context(|| input.display().to_string())?;
            let out = if single_file {
                a.out.clone()
            } else {
                let stem = input.file_stem().context("input has no file name")?;
                a.out.join(stem).with_extension("png")
            };
            png::write(&out, &img)?;
            Ok(())
        })();
        if let Err(e) = result {
            eprintln!("kitti2pgm: {e:#}");
            failed += 1;
        }
    }
    if failed == a.inputs.len() {
        bail!("no preview written");
    }
    Ok(if failed > 0 {
        Outcome::Partial
    } else {
        Outcome::Ok
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
