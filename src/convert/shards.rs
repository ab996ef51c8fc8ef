//! CONVERT into shards: each split's frames cut into shards in frame-id order; a shard's frames
//! are converted in parallel batches and appended in order while the next batch converts. A
//! shard that a re-run finds complete and intact is left as it is.
//!
//! Two kinds ([`ShardKind`]): map shards (`OUT/shards`, projected frames) and point shards
//! (`OUT/points`, the labelled points unprojected). When both are asked for, each pass reads
//! the frames; the map pass writes the `.npy` / `.label` files and counts the frames.

use std::path::Path;

use rayon::prelude::*;

use prost::Message as _;

use super::frame::{load, write_frame_files, Converted, Viz};
use super::resume::Verdict;
use super::{ConvertOptions, FrameOutcome, Run};
use crate::error::Result;
use crate::format::create_dir;
use crate::format::shard::points::PointsOf;
use crate::format::shard::{
    shard_is_intact, FrameMsg, PointsMsg, ShardKind, ShardMetadata, ShardWriter,
};
use crate::plan::split::{assign, Split};
use crate::plan::Failed;
use crate::plan::{DrivePlan, Plan};
use crate::project::rings;
use crate::provenance::ShardParams;
use crate::source::kitti::FrameId;

/// The frames of one shard.
#[derive(Debug, Clone)]
struct ShardPlan {
    split: Split,
    index: usize,
    jobs: Vec<(usize, u32)>,
}

/// What one pass writes: the kind of shards, and whether it also writes the frames' `.npy` /
/// `.label` files and counts the frames (the map pass, or the point pass alone).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Pass {
    pub kind: ShardKind,
    pub primary: bool,
}

impl Pass {
    fn path(&self, opts: &ConvertOptions, split: Split, index: usize) -> std::path::PathBuf {
        match self.kind {
            ShardKind::Maps => opts.out.shard_path(split.as_str(), index),
            ShardKind::Points => opts.out.points_path(split.as_str(), index),
        }
    }
}

/// What every shard of a pass shares: the plan, the options, the shard parameters, the pass
/// and the run's totals and journal.
struct ShardJob<'a, 'r> {
    plan: &'a Plan,
    opts: &'a ConvertOptions,
    sh: &'a ShardParams,
    pass: Pass,
    run: &'a Run<'r>,
}

/// Writes every shard of the plan for one pass (on the current rayon pool).
pub(crate) fn convert_to_shards(
    plan: &Plan,
    opts: &ConvertOptions,
    sh: &ShardParams,
    pass: Pass,
    run: &Run<'_>,
) -> Result<()> {
    let shards = plan_shards(plan, opts, sh, pass.kind)?;
    create_dir(&match pass.kind {
        ShardKind::Maps => opts.out.shards_dir(),
        ShardKind::Points => opts.out.points_dir(),
    })?;
    let drives: Vec<String> = plan.drives.iter().map(|d| d.drive.name()).collect();
    shards.par_iter().for_each(|sp| {
        let path = pass.path(opts, sp.split, sp.index);
        let ids: Vec<FrameId> = sp
            .jobs
            .iter()
            .map(|&(d, f)| plan.drives[d].drive.frame_id(f))
            .collect();
        let job = ShardJob {
            plan,
            opts,
            sh,
            pass,
            run,
        };
        if !opts.overwrite && shard_kept(&job, sp, &ids, &path) {
            run.produced(&path);
            if pass.primary {
                run.kept(ids.len() as u64, crate::plan::SkipReason::InIntactShard);
            }
            run.totals().summary.shards_skipped += 1;
            return;
        }
        let meta = ShardMetadata {
            version: env!("CARGO_PKG_VERSION").into(),
            params: opts.params.clone(),
            drives: drives.clone(),
            frames: ids,
            failed: Vec::new(),
            split: sp.split,
            content: pass.kind,
            inputs: Default::default(),
        };
        let frames = sp.jobs.len() as u64;
        let mut failed_alone = 0u64;
        match write_shard(&job, sp, &path, meta, &mut failed_alone) {
            // Every frame failed (each reported): no empty shard is left behind.
            Ok(reports) if reports.is_empty() => {}
            Ok(reports) => {
                run.produced(&path);
                let mut t = run.totals();
                if pass.primary {
                    reports.iter().for_each(|r| t.add(r));
                }
                t.summary.shards_written += 1;
            }
            // The shard is lost (its temporary file is removed), so are its frames; those that
            // failed on their own were counted already.
            Err(e) => run.failed(Failed::Shard(path.clone()), frames - failed_alone, e),
        }
    });
    Ok(())
}

/// Whether the shard at `path`, planned to hold `sp`'s frames `ids`, is kept as it is: every
/// frame journalled with these parameters from its inputs as they are now (and its .npy /
/// .label files present, when asked for), and the shard intact, made from those inputs. The
/// primary pass counts why frames are converted again.
fn shard_kept(job: &ShardJob<'_, '_>, sp: &ShardPlan, ids: &[FrameId], path: &Path) -> bool {
    let (plan, opts, pass, run) = (job.plan, job.opts, job.pass, job.run);
    let kept = sp.jobs.iter().fold(true, |all, &(d, f)| {
        let verdict = run.journal.verdict(&plan.drives[d], f, opts);
        let keep = if pass.primary {
            run.keeps(verdict)
        } else {
            verdict == Verdict::Keep
        };
        all && keep
    });
    let digests: Option<Vec<(FrameId, u64)>> = kept
        .then(|| {
            ids.iter()
                .map(|id| Some((id.clone(), run.journal.digest(id)?)))
                .collect()
        })
        .flatten();
    digests.is_some_and(|d| shard_is_intact(path, &d, &opts.params, pass.kind))
}

/// Assigns each job to a split by its drive, then cuts each split into shards, in frame-id order.
fn plan_shards(
    plan: &Plan,
    opts: &ConvertOptions,
    sh: &ShardParams,
    kind: ShardKind,
) -> Result<Vec<ShardPlan>> {
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
    let per_shard = match kind {
        ShardKind::Maps => sh.frames_per_shard(&map.spec, map.rgb.is_some()),
        ShardKind::Points => sh.frames_per_point_shard(map.rgb.is_some()),
    };
    let mut out = Vec::new();
    for split in Split::ALL.iter().copied() {
        let jobs: Vec<(usize, u32)> = plan
            .jobs
            .iter()
            .copied()
            .filter(|&(d, f)| {
                let which = if !labelled(&(d, f)) {
                    Split::Test
                } else if val.contains(&plan.drives[d].drive.frame_id(f)) {
                    Split::Val
                } else {
                    Split::Train
                };
                which == split
            })
            .collect();
        for (index, chunk) in jobs.chunks(per_shard).enumerate() {
            out.push(ShardPlan {
                split,
                index,
                jobs: chunk.to_vec(),
            });
        }
    }
    Ok(out)
}

/// One frame of a shard: converted, its message encoded; `.npy` / `.label` files written in
/// the primary pass.
fn shard_frame(
    job: &ShardJob<'_, '_>,
    dp: &DrivePlan,
    f: u32,
    split: Split,
) -> Result<(Converted, Vec<u8>, u64)> {
    let (opts, sh, pass) = (job.opts, job.sh, job.pass);
    let ts = dp.timestamp(f).map(|t| t.0.max(0) as u64);
    // Without a timestamp, frames are spaced at the scanner's 10 Hz.
    let log_time = ts.unwrap_or(f as u64 * 100_000_000);
    let (map, viz) = (&opts.params.map, Viz::from(sh.viz));
    let (p, msg) = match pass.kind {
        ShardKind::Maps => {
            let p = load(dp, f, map, viz)?.into_converted(map, viz);
            let msg = FrameMsg::from_frame(
                &p.pgm,
                &p.report.id,
                &dp.drive.name(),
                f,
                ts.unwrap_or(0),
                split.as_str(),
            );
            (p, msg.encode_to_vec())
        }
        ShardKind::Points => {
            let l = load(dp, f, map, viz)?;
            // Another sensor's beam rows; KITTI's rings from the scan order.
            let ring = match &l.beams {
                Some(b) => Some(b.rows.clone()),
                None => rings(&l.scan.points).0,
            };
            let colours = l.point_colours();
            let msg = PointsMsg::build(
                PointsOf {
                    points: &l.scan.points,
                    intensity: &l.scan.intensity,
                    rings: ring.as_deref(),
                    class: &l.labels.points.class,
                    instance: &l.labels.points.instance,
                    colours: colours.as_deref(),
                    file_index: (!l.scan.dropped.is_empty()).then_some(&l.scan.file_indices()[..]),
                },
                &l.id.to_string(),
                &dp.drive.name(),
                f,
                ts.unwrap_or(0),
                split.as_str(),
            );
            (l.into_converted(map, viz), msg.encode_to_vec())
        }
    };
    if pass.primary {
        write_frame_files(dp, f, &p, opts)?;
        job.run.journal.record(&dp.drive.frame_id(f), &p.inputs)?;
    }
    Ok((p, msg, log_time))
}

/// Converts a shard's frames (in parallel batches) and writes them in order; failed frames are
/// reported, left out and listed in the shard's metadata. The frames' reports are returned, to
/// be counted once the shard is in place; a shard none of whose frames converted is not
/// written.
fn write_shard(
    job: &ShardJob<'_, '_>,
    sp: &ShardPlan,
    path: &Path,
    mut meta: ShardMetadata,
    failed_alone: &mut u64,
) -> Result<Vec<super::FrameReport>> {
    let (plan, sh, pass, run) = (job.plan, job.sh, job.pass, job.run);
    let mut writer = ShardWriter::create(path, sh.compression, sh.viz, pass.kind)?;
    let mut reports = Vec::with_capacity(sp.jobs.len());
    let batch = rayon::current_num_threads().max(1) * 2;
    type Done = Vec<Result<(Converted, Vec<u8>, u64)>>;
    let produce_batch = |jobs: &[(usize, u32)]| -> Done {
        jobs.par_iter()
            .map(|&(d, f)| shard_frame(job, &plan.drives[d], f, sp.split))
            .collect()
    };
    // Appends a finished batch in frame order (sequential: the writer compresses here).
    let mut write_batch =
        |done: Done, jobs: &[(usize, u32)], meta: &mut ShardMetadata| -> Result<()> {
            for (r, &(d, f)) in done.into_iter().zip(jobs) {
                match r {
                    Ok((p, msg, log_time)) => {
                        writer.write(&msg, log_time, p.viz.as_ref())?;
                        let id = plan.drives[d].drive.frame_id(f);
                        meta.inputs.insert(id, run.journal.digest_of(&p.inputs));
                        if pass.primary {
                            (run.progress)(FrameOutcome::Done(&p.report));
                        }
                        reports.push(p.report);
                    }
                    Err(e) => {
                        let id = plan.drives[d].drive.frame_id(f);
                        meta.failed.push(id.clone());
                        if pass.primary {
                            *failed_alone += 1;
                            run.failed(Failed::Frame(id), 1, e);
                        }
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
