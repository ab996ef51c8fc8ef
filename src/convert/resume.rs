//! CONVERT again into the same folder: one conversion at a time, leftovers of an interrupted
//! run removed, finished frames kept.
//!
//! A conversion holds an exclusive lock on `OUT/.kitti2pgm.lock` for as long as it runs, so a
//! second one into the same folder stops with an error instead of racing it. Under that lock,
//! the temporary files (`.tmp-*`) that an interrupted run (kill -9, power cut) left in the output
//! folders are its own leftovers and are removed. A frame whose outputs are all present and whole
//! is skipped when the folder's recorded parameters are the same as this run's
//! (`--overwrite` converts every frame again); outputs are written atomically, so a file that is
//! present is whole, and its size is checked as well.

use std::fs::File;
use std::path::Path;

use super::ConvertOptions;
use crate::error::{Error, Result};
use crate::format::layout::OutputDir;
use crate::format::{npy, summary};
use crate::kitti::velodyne::POINT_BYTES;
use crate::plan::DrivePlan;

/// Why a frame is skipped on resume (the summary's `frames_skipped` key).
pub const KEPT: &str = "already converted by an earlier run with the same parameters";

/// Name of the lock file in the output folder.
pub const LOCK_FILE: &str = ".kitti2pgm.lock";

/// Takes the output folder's lock; it is released when the returned file is dropped.
pub fn lock(out: &OutputDir) -> Result<File> {
    let path = out.root.join(LOCK_FILE);
    let file = File::options()
        .create(true)
        .truncate(false)
        .write(true)
        .open(&path)
        .map_err(|source| Error::Write {
            path: path.clone(),
            source,
        })?;
    match file.try_lock() {
        Ok(()) => Ok(file),
        Err(std::fs::TryLockError::WouldBlock) => Err(Error::Input {
            path: out.root.clone(),
            message: "another kitti2pgm conversion is writing into this folder".into(),
        }),
        Err(std::fs::TryLockError::Error(source)) => Err(Error::Write { path, source }),
    }
}

/// Removes the `.tmp-*` files left in the output folders by an interrupted run; returns how many.
pub fn remove_leftovers(out: &OutputDir) -> Result<u64> {
    let mut dirs = vec![out.root.clone(), out.lidar_dir(), out.shards_dir()];
    let labels = out.root.join(crate::format::layout::LABELS);
    if labels.is_dir() {
        dirs.extend(
            crate::fs::sorted_dir(&labels)?
                .into_iter()
                .filter(|p| p.is_dir()),
        );
    }
    let mut removed = 0;
    for dir in dirs.iter().filter(|d| d.is_dir()) {
        for p in crate::fs::sorted_dir(dir)? {
            let leftover = p
                .file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with(".tmp-"));
            if leftover && p.is_file() {
                std::fs::remove_file(&p).map_err(|source| Error::Write { path: p, source })?;
                removed += 1;
            }
        }
    }
    Ok(removed)
}

/// Whether the folder's recorded parameters (of a finished or interrupted run) are `opts`'.
pub fn same_parameters(opts: &ConvertOptions) -> bool {
    // An unreadable summary (another version's, damaged) means: convert everything again.
    matches!(summary::read(&opts.out.summary_path()), Ok(Some(s)) if s.params == opts.params)
}

/// Whether every output `opts` asks for of this frame is present and of the right size.
pub fn frame_is_complete(dp: &DrivePlan, frame: u32, opts: &ConvertOptions) -> bool {
    let id = dp.drive.frame_id(frame);
    let len = |p: &Path| std::fs::metadata(p).ok().map(|m| m.len());
    let map = &opts.params.map;
    let shape = [
        map.spec.rows as u64,
        map.spec.cols as u64,
        map.channels().len() as u64,
    ];
    let npy_ok =
        !opts.params.npy || len(&opts.out.npy_path(&id)) == Some(npy::file_len_f32(&shape));
    let labels_ok = !opts.params.labels || {
        let points = len(&dp.drive.scan_path(frame)).map(|b| b / POINT_BYTES as u64);
        points.is_some() && len(&opts.out.label_path(&id)) == points.map(|n| n * 4)
    };
    npy_ok && labels_ok
}
