//! `kitti2pgm unpack`: a ROS 2 bag's point clouds -> a sequence folder
//! ([`kitti2pgm::convert::unpack`]).

use anyhow::Context;
use kitti2pgm::convert::unpack::{
    unpack, UnpackOptions, UnpackOutcome, UnpackReport, UnpackSummary,
};
use kitti2pgm::source::bag::{Bag, Topic};

use super::Global;
use crate::cli::UnpackArgs;
use crate::Outcome;

fn print_topics(bag: &Bag, topics: &[Topic], json: bool) -> anyhow::Result<()> {
    if json {
        let v: Vec<_> = topics
            .iter()
            .map(|t| {
                serde_json::json!({"topic": t.name, "type": t.type_name,
                                   "encoding": t.encoding, "messages": t.messages})
            })
            .collect();
        println!("{}", serde_json::to_string_pretty(&v)?);
        return Ok(());
    }
    let n = bag.files.len();
    println!(
        "{}: {n} file{}",
        bag.path.display(),
        if n == 1 { "" } else { "s" }
    );
    let w = topics
        .iter()
        .map(|t| t.name.len())
        .max()
        .unwrap_or(5)
        .max(5);
    println!("{:<w$}  {:<36}  {:>8}", "topic", "type", "messages");
    for t in topics {
        println!("{:<w$}  {:<36}  {:>8}", t.name, t.type_name, t.messages);
    }
    // The frames --sensor-frame can name: the static transforms, each as the pose it gives.
    let transforms = kitti2pgm::source::tf::read_static(bag)?;
    if !transforms.is_empty() {
        println!("\nstatic transforms (/tf_static): child in parent as x,y,z,roll,pitch,yaw");
        for t in &transforms {
            let pose = kitti2pgm::sensor::SensorPose::from_isometry(&t.isometry());
            println!("  {} in {}: {pose}", t.child, t.parent);
        }
    }
    Ok(())
}

fn print_summary(s: &UnpackSummary) {
    println!(
        "{} ({}) -> {}",
        s.bag.display(),
        s.topic,
        s.sequence_dir.display()
    );
    println!("messages        {:>10}", s.messages);
    println!("frames written  {:>10}", s.frames_written);
    println!("points          {:>10}", s.points);
    println!("fields          {}", s.fields.join(" "));
    println!("frame ids       {}", s.frame_ids.join(" "));
    if let Some(t) = &s.first_stamp {
        println!("first stamp     {t}");
    }
    if s.removed_stale > 0 {
        println!("removed stale   {:>10}", s.removed_stale);
    }
    if let Some(p) = &s.sensor_pose {
        println!(
            "sensor pose     {} in {}: convert with --sensor-pose {}",
            p.sensor_frame, p.points_frame, p.pose
        );
    }
    if s.skipped_other_types > 0 {
        println!(
            "other types     {:>10}  (messages on {} that are not point clouds, passed over)",
            s.skipped_other_types, s.topic
        );
    }
    for f in &s.failures {
        println!("FAILED frame {:06}: {}", f.frame, f.error);
    }
    for d in &s.damaged {
        println!("DAMAGED {d}");
    }
}

/// The command's outcome for an unpack that ended as `o`: `empty` says a recording held no
/// frame, `none` that no frame unpacked.
pub(super) fn outcome(o: UnpackOutcome, empty: String, none: String) -> Outcome {
    match o {
        UnpackOutcome::Done => Outcome::Ok,
        UnpackOutcome::Partial => Outcome::Partial,
        UnpackOutcome::Empty => Outcome::Failed(empty),
        UnpackOutcome::NoneUnpacked => Outcome::Failed(none),
    }
}

/// Refuses the options of the other kind of recording: `given` (by name), which are for `kind`.
fn refuse_other(input: &std::path::Path, given: &[&str], kind: &str) -> anyhow::Result<()> {
    if given.is_empty() {
        return Ok(());
    }
    anyhow::bail!(
        "{}: {} {} for {kind}",
        input.display(),
        given.join(", "),
        if given.len() == 1 { "is" } else { "are" }
    )
}

pub fn run(a: UnpackArgs, g: &Global) -> anyhow::Result<Outcome> {
    if kitti2pgm::source::nuscenes::is_root(&a.bag) {
        refuse_other(
            &a.bag,
            &a.from_bag.given(),
            "bags (it is a nuScenes root: one scene is one sequence, numbered as the scene)",
        )?;
        return super::unpack_nuscenes::run(a, g);
    }
    refuse_other(
        &a.bag,
        &a.from_nuscenes.given(),
        "a nuScenes root (a folder with v1.0-*/sample_data.json)",
    )?;
    let bag = Bag::open(&a.bag)?;
    if a.list {
        print_topics(&bag, &bag.topics()?, a.json)?;
        return Ok(Outcome::Ok);
    }
    let out = a.out.context("--out ROOT is needed")?;
    kitti2pgm::fs::refuse_overlap(&out, &[(kitti2pgm::fs::Role::Dataset, a.bag.as_path())])?;
    let topic = bag.topic(
        a.from_bag.topic.as_deref(),
        kitti2pgm::source::pointcloud2::TYPE_NAME,
    )?;
    let opts = UnpackOptions {
        out,
        sequence: a.from_bag.sequence.unwrap_or(0),
        overwrite: a.overwrite,
        durability: super::durability(a.sync),
        sensor_frame: a.from_bag.sensor_frame.clone(),
    };
    let pb = super::progress::bar(topic.messages, g.progress, "unpacking");
    let s = g
        .pool()?
        .install(|| unpack(&bag, &topic, &opts, &|_| pb.inc(1)))?;
    pb.finish_and_clear();
    if a.json {
        println!("{}", serde_json::to_string_pretty(&s)?);
    } else {
        print_summary(&s);
    }
    Ok(outcome(
        s.outcome(),
        format!("{} has no message to unpack", s.topic),
        format!("no frame of {} unpacked", s.topic),
    ))
}
