//! `kitti2pgm split`: the CLI over [`kitti2pgm::report::split`].

use anyhow::Context;
use kitti2pgm::pipeline::FrameSelection;
use kitti2pgm::report::imageset;
use kitti2pgm::report::split::split;
use kitti2pgm::write::{atomic_write, create_dir};

use crate::cli::SplitArgs;
use crate::Outcome;

pub fn run(a: SplitArgs) -> anyhow::Result<Outcome> {
    let rule = a.split.rule()?;
    let selection = if a.all_frames {
        FrameSelection::All
    } else {
        FrameSelection::Annotated
    };
    let lists = split(&a.raw_root, selection, &rule)
        .with_context(|| format!("reading {}", a.raw_root.display()))?;
    let dir = a.out.join("ImageSet");
    create_dir(&dir)?;
    for (name, ids) in [
        ("all", &lists.all),
        ("train", &lists.train),
        ("val", &lists.val),
    ] {
        atomic_write(
            &dir.join(format!("{name}.txt")),
            imageset::to_text(ids).as_bytes(),
            false,
        )?;
    }
    if a.json {
        let j = serde_json::json!({
            "out": dir,
            "all": lists.all.len(),
            "train": lists.train.len(),
            "val": lists.val.len(),
            "val_drives": lists.val_drives,
        });
        println!("{}", serde_json::to_string_pretty(&j)?);
    } else {
        println!("{}", dir.display());
        println!("all    {:>8}", lists.all.len());
        println!("train  {:>8}", lists.train.len());
        println!(
            "val    {:>8}  ({} drives: {})",
            lists.val.len(),
            lists.val_drives.len(),
            lists.val_drives.join(" ")
        );
    }
    Ok(Outcome::Ok)
}
