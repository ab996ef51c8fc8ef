//! `kitti2pgm inspect`: the CLI over [`kitti2pgm::report::inspect`].

use kitti2pgm::report::inspect::{inspect, ShardInfo};

use crate::cli::InspectArgs;
use crate::Outcome;

pub fn run(a: InspectArgs) -> anyhow::Result<Outcome> {
    let mut infos: Vec<ShardInfo> = Vec::new();
    let mut failed = 0;
    for p in &a.shards {
        match inspect(p) {
            Ok(i) => infos.push(i),
            Err(e) => {
                eprintln!("kitti2pgm: {e}");
                failed += 1;
            }
        }
    }
    if a.json {
        println!("{}", serde_json::to_string_pretty(&infos)?);
    } else {
        infos.iter().for_each(print_info);
    }
    if failed == a.shards.len() {
        return Ok(Outcome::Failed("no shard could be read".into()));
    }
    Ok(if failed > 0 {
        Outcome::Partial
    } else {
        Outcome::Ok
    })
}

/// One shard's account, as `inspect` prints it.
fn print_info(i: &ShardInfo) {
    println!("{}", i.path);
    println!(
        "  frames          {} ({} .. {})",
        i.frames,
        i.first_frame.as_deref().unwrap_or("-"),
        i.last_frame.as_deref().unwrap_or("-")
    );
    if let Some([h, w]) = i.shape {
        println!(
            "  map             {h} x {w}, channels {}",
            i.channels.join(",")
        );
    }
    println!("  split           {}", i.metadata.split);
    println!(
        "  size            {:.1} MB on disk, {:.1} MB uncompressed, ratio {:.2} ({})",
        i.file_bytes as f64 / 1e6,
        i.uncompressed_bytes as f64 / 1e6,
        i.compression_ratio,
        i.compression.join(",")
    );
    println!(
        "  topics          {}",
        i.topics
            .iter()
            .map(|(t, n)| format!("{t} ({n})"))
            .collect::<Vec<_>>()
            .join(", ")
    );
    let points = i.metadata.content == kitti2pgm::format::shard::ShardKind::Points;
    if points {
        println!("  points          {} (point shard)", i.points);
    }
    println!(
        "  {}     {}",
        if points {
            "class points"
        } else {
            "class cells "
        },
        i.class_cells
            .iter()
            .map(|(c, n)| format!("{c} {n}"))
            .collect::<Vec<_>>()
            .join(", ")
    );
    println!(
        "  written by      kitti2pgm {}; drives {}",
        i.metadata.version,
        i.metadata.drives.len()
    );
    if !i.metadata.failed.is_empty() {
        let failed: Vec<String> = i.metadata.failed.iter().map(|f| f.to_string()).collect();
        println!("  failed frames   {}", failed.join(" "));
    }
}
