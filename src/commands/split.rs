//! `kitti2pgm split`: the CLI over [`kitti2pgm::plan::split`].

use kitti2pgm::format::layout::OutputDir;
use kitti2pgm::format::{create_dir, imageset};
use kitti2pgm::plan::split::split;
use kitti2pgm::plan::FrameSelection;

use crate::cli::SplitArgs;
use crate::Outcome;

pub fn run(a: SplitArgs) -> anyhow::Result<Outcome> {
    kitti2pgm::fs::refuse_overlap(
        &a.out,
        &[(kitti2pgm::fs::Role::Dataset, a.raw_root.as_path())],
    )?;
    let source = a.dataset;
    let rule = a.split.rule()?;
    let selection = if a.all_frames {
        FrameSelection::All
    } else {
        FrameSelection::Annotated
    };
    let lists = split(&a.raw_root, selection, rule.as_ref(), source)?;
    let dir = OutputDir::new(&a.out).imageset_dir();
    create_dir(&dir)?;
    for (name, ids) in [
        ("all", &lists.all),
        ("train", &lists.train),
        ("val", &lists.val),
    ] {
        imageset::write(&dir.join(format!("{name}.txt")), ids)?;
    }
    if !lists.test.is_empty() {
        imageset::write(&dir.join("test.txt"), &lists.test)?;
    }
    if a.json {
        let j = serde_json::json!({
            "out": dir,
            "all": lists.all.len(),
            "train": lists.train.len(),
            "val": lists.val.len(),
            "test": lists.test.len(),
            "val_drives": lists.val_drives,
        });
        println!("{}", serde_json::to_string_pretty(&j)?);
    } else {
        println!("{}", dir.display());
        println!("all    {:>8}", lists.all.len());
        println!("train  {:>8}", lists.train.len());
        if lists.val_drives.is_empty() {
            // A frame split (the object set), or no val at all.
            println!("val    {:>8}", lists.val.len());
        } else {
            let units = lists.all.first().map_or("drives", |id| id.dataset.units());
            println!(
                "val    {:>8}  ({} {units}: {})",
                lists.val.len(),
                lists.val_drives.len(),
                lists.val_drives.join(" ")
            );
        }
        if !lists.test.is_empty() {
            println!("test   {:>8}  (frames without labels)", lists.test.len());
        }
    }
    Ok(Outcome::Ok)
}
