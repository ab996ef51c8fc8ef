//! `kitti2pgm preview`: converted frames to PNG.

use anyhow::{bail, Context};
use kitti2pgm::write::npy::read_f32;

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
            let (shape, data) = read_f32(input)?;
            let img = kitti2pgm::preview::render(&shape, &data)
                .with_context(|| input.display().to_string())?;
            let out = if single_file {
                a.out.clone()
            } else {
                let stem = input.file_stem().context("input has no file name")?;
                a.out.join(stem).with_extension("png")
            };
            kitti2pgm::write::write_png(&out, &img)?;
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
