//! CONVERT into shards: each split's frames cut into shards in frame-id order; a shard's frames
//! are converted in parallel batches and appended in order while the next batch converts. A
//! shard that a re-run finds complete and intact is left as it is.

use std::path::Path;

use rayon::prelude::*;

use super::frame::{produce, write_frame_files, Produced};
use super::{ConvertOptions, FrameOutcome, Run};
use crate::error::Result;
use crate::format::create_dir;
use crate::format::shard::{shard_is_intact, FrameMsg, ShardMetadata, ShardWriter};
use crate::kitti::FrameId;
use crate::params::ShardParams;
use crate::plan::split::assign;
use crate::plan::Plan;

/// The frames of one shard.
#[derive(Debug, Clone)]
struct ShardPlan {
    split: String,
    index: usize,
    jobs: Vec<(usize, u32)>,
}

/// Writes every shard of the plan (on the current rayon pool).
pub(crate) fn convert_to_shards(
    plan: &Plan,
    opts: &ConvertOptions,
    sh: &ShardParams,
    run: &Run<'_>,
) -> Result<()> {
    let shards = plan_shards(plan, opts, sh)?;
    create_dir(&opts.out.shards_dir())?;
    let drives: Vec<String> = plan.drives.iter().map(|d| d.drive.name()).collect();
    shards.par_iter().for_each(|sp| {
        let path = opts.out.shard_path(&sp.split, sp.index);
        let ids: Vec<String> = sp
            .jobs
            .iter()
            .map(|&(d, f)| plan.drives[d].drive.frame_id(f).to_string())
            .collect();
        let others_present = sp.jobs.iter().all(|&(d, f)| {
            let id = plan.drives[d].drive.frame_id(f);
            (!opts.params.npy || opts.out.npy_path(&id).is_file())
                && (!opts.params.labels || opts.out.label_path(&id).is_file())
        });
        if !opts.overwrite && others_present && shard_is_intact(&path, &ids, &opts.params) {
            run.kept(ids.len() as u64, "already in a complete, intact shard");
            run.totals().summary.shards_skipped += 1;
            return;
        }
        let meta = ShardMetadata {
            version: env!("CARGO_PKG_VERSION").into(),
            params: opts.params.clone(),
            drives: drives.clone(),
            frames: ids,
            failed: Vec::new(),
            split: sp.split.clone(),
        };
        let frames = sp.jobs.len() as u64;
        match write_shard(plan, opts, sh, sp, &path, meta, run) {
            // Every frame failed (each reported): no empty shard is left behind.
            Ok(reports) if reports.is_empty() => {}
            Ok(reports) => {
                let mut t = run.totals();
                reports.iter().for_each(|r| t.add(r));
                t.summary.shards_written += 1;
            }
            // The shard is lost (its temporary file is removed), so are its frames.
            Err(e) => run.failed(format!("shard {}", path.display()), frames, e),
        }
    });
    Ok(())
}

/// Assigns each job to a split by its drive, then cuts each split into shards, in frame-id order.
fn plan_shards(plan: &Plan, opts: &ConvertOptions, sh: &ShardParams) -> Result<Vec<ShardPlan>> {
    // Frames without labels (SemanticKITTI test sequences, object testing/) go to `test`.
    let labelled = |&(d, f): &(usize, u32)| plan.drives[d].drive.has_labels(f);
    let ids: Vec<FrameId> = plan
        .jobs
        .iter()
        .filter(|j| labelled(j))
        .map(|&(d, f)| plan.drives[d].drive.frame_id(f))
        .collect();
    let val = assign(&sh.split, &ids)?;
    let map = &opts.params.map;
    let per_shard = sh.frames_per_shard(&map.spec, map.rgb.is_some());
    let mut out = Vec::new();
    for split in ["train", "val", "test"] {
        let jobs: Vec<(usize, u32)> = plan
            .jobs
            .iter()
            .copied()
            .filter(|&(d, f)| {
                let which = if !labelled(&(d, f)) {
                    "test"
                } else if val.contains(&plan.drives[d].drive.frame_id(f)) {
                    "val"
                } else {
                    "train"
                };
                which == split
            })
            .collect();
        for (index, chunk) in jobs.chunks(per_shard).enumerate() {
            out.push(ShardPlan {
                split: split.into(),
                index,
                jobs: chunk.to_vec(),
            });
        }
    }
    Ok(out)
}

/// Converts a shard's frames (in parallel batches) and writes them in order; failed frames are
/// reported, left out and listed in the shard's metadata. The frames' reports are returned, to
/// be counted once the shard is in place; a shard none of whose frames converted is not
/// written.
fn write_shard(
    plan: &Plan,
    opts: &ConvertOptions,
    sh: &ShardParams,
    sp: &ShardPlan,
    path: &Path,
    mut meta: ShardMetadata,
    run: &Run<'_>,
) -> Result<Vec<super::FrameReport>> {
    let mut writer = ShardWriter::create(path, sh.compression, sh.viz)?;
    let mut reports = Vec::with_capacity(sp.jobs.len());
    let batch = rayon::current_num_threads().max(1) * 2;
    type Done = Vec<Result<(Produced, FrameMsg, u64)>>;
    let produce_batch = |jobs: &[(usize, u32)]| -> Done {
        jobs.par_iter()
            .map(|&(d, f)| {
                let dp = &plan.drives[d];
                let p = produce(dp, f, opts, sh.viz)?;
                write_frame_files(dp, f, &p.out, opts)?;
                let ts = dp.timestamp(f).map(|t| t.0.max(0) as u64);
                // Without a timestamp, frames are spaced at the scanner's 10 Hz.
                let log_time = ts.unwrap_or(f as u64 * 100_000_000);
                let msg = FrameMsg::from_frame(
                    &p.out.pgm,
                    &p.out.report.id,
                    &dp.drive.name(),
                    f,
                    ts.unwrap_or(0),
                    &sp.split,
                );
                Ok((p, msg, log_time))
            })
            .collect()
    };
    // Appends a finished batch in frame order (sequential: the writer compresses here).
    let mut write_batch =
        |done: Done, jobs: &[(usize, u32)], meta: &mut ShardMetadata| -> Result<()> {
            for (r, &(d, f)) in done.into_iter().zip(jobs) {
                match r {
                    Ok((p, msg, log_time)) => {
                        writer.write(&msg, log_time, p.viz.as_ref())?;
                        (run.progress)(FrameOutcome::Done(&p.out.report));
                        reports.push(p.out.report);
                    }
                    Err(e) => {
                        let id = plan.drives[d].drive.frame_id(f).to_string();
                        meta.failed.push(id.clone());
                        run.failed(id, 1, e);
                    }
                }
            }
            Ok(())
        };
    // Pipeline: batch k is written (compressed) while batch k + 1 is produced.
    let mut pending: Option<(Done, &[(usize, u32)])> = None;
    for jobs in sp.jobs.chunks(batch) {
        let (written, done) = rayon::join(
            || match pending.take() {
                Some((d, j)) => write_batch(d, j, &mut meta),
                None => Ok(()),
            },
            || produce_batch(jobs),
        );
        written?;
        pending = Some((done, jobs));
    }
    if let Some((d, j)) = pending.take() {
        write_batch(d, j, &mut meta)?;
    }
    if reports.is_empty() {
        // Dropping the writer removes its temporary file.
        return Ok(reports);
    }
    writer.finish(&meta)?;
    Ok(reports)
}
