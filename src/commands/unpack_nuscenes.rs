//! `kitti2pgm unpack NUSCENES_ROOT`: a nuScenes root's LIDAR_TOP keyframes -> sequence folders
//! ([`kitti2pgm::convert::unpack::nuscenes`]); called by [`super::unpack`].

use anyhow::Context;
use kitti2pgm::convert::unpack::{unpack_nuscenes, NuScenesOptions, NuScenesSummary, UnpackReport};
use kitti2pgm::source::nuscenes::NuScenes;

use super::Global;
use crate::cli::UnpackArgs;
use crate::Outcome;

fn print_scenes(ds: &NuScenes, json: bool) -> anyhow::Result<()> {
    let rows: Vec<(String, u32, usize, usize)> = ds
        .scenes
        .iter()
        .map(|s| {
            let labelled = s.keyframes.iter().filter(|k| k.labels.is_some()).count();
            (s.name.clone(), s.number, s.keyframes.len(), labelled)
        })
        .collect();
    if json {
        let v: Vec<_> = rows
            .iter()
            .map(|(name, n, k, l)| {
                serde_json::json!({"scene": name, "sequence": format!("{n:02}"),
                                   "keyframes": k, "labelled": l})
            })
            .collect();
        println!("{}", serde_json::to_string_pretty(&v)?);
        return Ok(());
    }
    println!(
        "{} ({}): {} scenes{}",
        ds.root.display(),
        ds.version,
        ds.scenes.len(),
        if ds.lidarseg {
            ", nuScenes-lidarseg labels"
        } else {
            ", no lidarseg labels"
        }
    );
    println!(
        "{:<12}  {:>8}  {:>9}  {:>8}",
        "scene", "sequence", "keyframes", "labelled"
    );
    for (name, n, k, l) in rows {
        println!("{name:<12}  {:>8}  {k:>9}  {l:>8}", format!("{n:02}"));
    }
    Ok(())
}

fn print_summary(s: &NuScenesSummary) {
    println!("{} ({})", s.root.display(), s.nuscenes_version);
    println!("scenes          {:>10}", s.scenes.len());
    println!("frames written  {:>10}", s.frames_written);
    println!("labelled        {:>10}", s.labelled_frames);
    println!("points          {:>10}", s.points);
    if s.removed_stale > 0 {
        println!("removed stale   {:>10}", s.removed_stale);
    }
    for f in &s.failures {
        let scene = f.scene.as_deref().unwrap_or("?");
        println!("FAILED {scene} frame {:06}: {}", f.frame, f.error);
    }
}

pub fn run(a: UnpackArgs, g: &Global) -> anyhow::Result<Outcome> {
    let ds = NuScenes::open(&a.bag, a.from_nuscenes.nuscenes_version.as_deref())?;
    if a.list {
        print_scenes(&ds, a.json)?;
        return Ok(Outcome::Ok);
    }
    let out = a.out.context("--out ROOT is needed")?;
    kitti2pgm::fs::refuse_overlap(&out, &[(kitti2pgm::fs::Role::Dataset, a.bag.as_path())])?;
    let opts = NuScenesOptions {
        out,
        scenes: a.from_nuscenes.scenes,
        overwrite: a.overwrite,
        durability: super::durability(a.sync),
    };
    let total = (ds.scenes.iter())
        .filter(|s| opts.scenes.is_empty() || opts.scenes.contains(&s.name))
        .map(|s| s.keyframes.len() as u64)
        .sum();
    let pb = super::progress::bar(total, g.progress, "unpacking");
    let s = g
        .pool()?
        .install(|| unpack_nuscenes(&ds, &opts, &|| pb.inc(1)))?;
    pb.finish_and_clear();
    if a.json {
        println!("{}", serde_json::to_string_pretty(&s)?);
    } else {
        print_summary(&s);
        if let Some(first) = s.scenes.first() {
            println!("first sequence  {}", first.sequence_dir.display());
        }
    }
    Ok(super::unpack::outcome(
        s.outcome(),
        "no LIDAR_TOP keyframe to unpack".into(),
        "no keyframe unpacked".into(),
    ))
}
