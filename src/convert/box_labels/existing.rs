//! The label files already in a sequence when `label` runs: which ones an earlier run wrote
//! (and nobody changed since), which ones it may have written before it was interrupted, and
//! which ones are another source's (refused unless `overwrite`; a dataset's own, always).

use std::collections::{BTreeMap, BTreeSet};
use std::path::PathBuf;

use super::frame::FrameJob;
use crate::error::{Error, Result};
use crate::format::box_labels::LabelledFrame;
use crate::source::kitti::Drive;

/// What the previous run's record says of the label files.
pub(super) struct Previous<'a> {
    /// The label files it wrote, by frame name, with their digests.
    pub(super) frames: &'a BTreeMap<String, LabelledFrame>,
    /// The frames an interrupted run was writing (its record unfinished): their files may hold
    /// its labels, and are written again.
    pub(super) pending: &'a BTreeSet<String>,
}

/// The jobs, each with the record of the label file there when `label` wrote it and nobody
/// changed it since; a label file there that is not such (another tool's, hand-edited) is
/// refused unless `overwrite`, and one the dataset ships always: checked for every frame
/// (the jobs and the `stale` frames to remove) before anything is written.
pub(super) fn refuse_foreign(
    drive: &Drive,
    mut jobs: Vec<FrameJob>,
    stale: &[String],
    previous: &Previous,
    overwrite: bool,
) -> Result<Vec<FrameJob>> {
    let old = previous.frames;
    let ships_labels = drive
        .dir
        .join(crate::source::unpacked::NUSCENES_MARKER)
        .exists();
    let mut foreign = Vec::new();
    let stale_paths = stale.iter().map(|n| {
        let label = drive
            .dir
            .join(crate::source::kitti::sequence::LABELS)
            .join(format!("{n}.label"));
        (n.clone(), label, None)
    });
    let job_paths = jobs
        .iter()
        .enumerate()
        .map(|(i, j)| (format!("{:06}", j.frame), j.label.clone(), Some(i)));
    let all: Vec<(String, PathBuf, Option<usize>)> = job_paths.chain(stale_paths).collect();
    for (name, label, job) in all {
        let Some(now) = crate::fs::inputs::fingerprint(&label)? else {
            continue;
        };
        if previous.pending.contains(&name) {
            continue; // written by the run that was interrupted, or still its predecessor's
        }
        match old.get(&name) {
            Some(o) if o.label.same_content(&now) => {
                if let Some(i) = job {
                    jobs[i].previous = Some(o.clone());
                }
            }
            Some(_) => foreign.push((label, "edited since `kitti2pgm label` wrote it")),
            None => {
                let kitti_scan = job.is_some_and(|i| crate::source::is_kitti_bin(&jobs[i].scan));
                if ships_labels || kitti_scan {
                    return Err(Error::Input {
                        path: label,
                        message: "a label file of the dataset itself (SemanticKITTI's, nuScenes'): `label` never writes over it; label a copy of the scans".into(),
                    });
                }
                foreign.push((label, "not written by `kitti2pgm label`"));
            }
        }
    }
    if foreign.is_empty() || overwrite {
        return Ok(jobs);
    }
    let (first, why) = &foreign[0];
    Err(Error::Input {
        path: first.clone(),
        message: format!(
            "a label file is already there, {why} ({} such file(s) in {}): --overwrite replaces them",
            foreign.len(),
            drive.dir.display()
        ),
    })
}
