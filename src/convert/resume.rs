//! CONVERT again into the same folder: one conversion at a time, leftovers of an interrupted
//! run removed, finished frames kept only when they provably were made with this run's
//! parameters.
//!
//! A conversion holds an exclusive lock on `OUT/.kitti2pgm.lock` for as long as it runs, so a
//! second one into the same folder stops with an error instead of racing it. Under that lock,
//! the temporary files (`.tmp-*`) that an interrupted run (kill -9, power cut) left in the output
//! folders are its own leftovers and are removed.
//!
//! Provenance is a journal, `OUT/.kitti2pgm-frames`: its first line records the parameters
//! (the exact JSON of [`ConvertParams`]), each further line the id of a frame whose `.npy` and
//! `.label` files were written, whole, with them (appended after the files were renamed into
//! place). A re-run keeps a frame only when the journal's parameters are this run's, the frame
//! is listed, and its files are present and of the right size. A run with other parameters (or
//! `--overwrite`) first removes every converted output of the folder (maps, labels, shards) and
//! starts a new journal, so that a folder never holds artefacts of two parameter sets.

use std::collections::BTreeSet;
use std::fs::File;
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use super::ConvertOptions;
use crate::error::{Error, Result};
use crate::format::layout::{self, OutputDir};
use crate::format::{npy, Durability};
use crate::kitti::velodyne::POINT_BYTES;
use crate::kitti::FrameId;
use crate::params::ConvertParams;
use crate::plan::DrivePlan;

/// Name of the lock file in the output folder.
pub const LOCK_FILE: &str = ".kitti2pgm.lock";

/// Name of the journal of finished frames in the output folder.
pub const JOURNAL_FILE: &str = ".kitti2pgm-frames";

/// First word of the journal's header line (format version 1).
const JOURNAL_MAGIC: &str = "kitti2pgm-frames/1";

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
        Err(std::fs::TryLockError::WouldBlock) => Err(Error::Locked {
            path: out.root.clone(),
        }),
        Err(std::fs::TryLockError::Error(source)) => Err(Error::Write { path, source }),
    }
}

/// The folders a conversion writes frames or shards into (those that exist).
fn output_dirs(out: &OutputDir) -> Result<Vec<PathBuf>> {
    let mut dirs = vec![
        out.root.clone(),
        out.lidar_dir(),
        out.shards_dir(),
        out.points_dir(),
    ];
    let labels = out.root.join(layout::LABELS);
    if labels.is_dir() {
        dirs.extend(
            crate::fs::sorted_dir(&labels)?
                .into_iter()
                .filter(|p| p.is_dir()),
        );
    }
    Ok(dirs.into_iter().filter(|d| d.is_dir()).collect())
}

fn file_name(p: &Path) -> Option<&str> {
    p.file_name().and_then(|n| n.to_str())
}

fn remove(p: &Path) -> Result<()> {
    std::fs::remove_file(p).map_err(|source| Error::Write {
        path: p.into(),
        source,
    })
}

/// Removes the `.tmp-*` files left in the output folders by an interrupted run; returns how many.
pub fn remove_leftovers(out: &OutputDir) -> Result<u64> {
    let mut removed = 0;
    for dir in output_dirs(out)? {
        for p in crate::fs::sorted_dir(&dir)? {
            if file_name(&p).is_some_and(|n| n.starts_with(".tmp-")) && p.is_file() {
                remove(&p)?;
                removed += 1;
            }
        }
    }
    Ok(removed)
}

/// The converted outputs in the folder: `lidar_2d/<id>.npy`, `labels/<drive>/<frame>.label`,
/// `shards/*.mcap` and `points/*.mcap` (other files are left alone).
pub fn converted_outputs(out: &OutputDir) -> Result<Vec<PathBuf>> {
    let mut found = Vec::new();
    let labels = out.root.join(layout::LABELS);
    for dir in output_dirs(out)? {
        let ext = if dir == out.lidar_dir() {
            "npy"
        } else if dir == out.shards_dir() || dir == out.points_dir() {
            "mcap"
        } else if dir.parent() == Some(labels.as_path()) {
            "label"
        } else {
            continue;
        };
        for p in crate::fs::sorted_dir(&dir)? {
            let ours = file_name(&p).is_some_and(|n| !n.starts_with('.'))
                && p.extension().is_some_and(|e| e == ext);
            if ours && p.is_file() {
                found.push(p);
            }
        }
    }
    Ok(found)
}

/// The journal of a folder, as read back: the parameters it was started with (as recorded)
/// and the frames finished under them.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct JournalRecord {
    /// The parameters' JSON, as recorded.
    pub params: String,
    /// Frames whose files were written whole with these parameters.
    pub frames: BTreeSet<String>,
}

impl JournalRecord {
    /// Whether the journal was started with `params`.
    pub fn made_with(&self, params: &ConvertParams) -> bool {
        self.params == params_key(params)
    }
}

/// The parameters as the journal records them: one line of JSON.
fn params_key(params: &ConvertParams) -> String {
    serde_json::to_string(params).expect("the parameters serialise")
}

/// Reads `OUT/.kitti2pgm-frames`; `Ok(None)` when there is none. A last line without its
/// newline (the run was killed while appending it) is not counted.
pub fn read_journal(out: &OutputDir) -> Result<Option<JournalRecord>> {
    let path = out.root.join(JOURNAL_FILE);
    let text = match std::fs::read(&path) {
        Ok(b) => b,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(Error::io(&path, e)),
    };
    let text = String::from_utf8_lossy(&text);
    let mut lines = text.split_inclusive('\n');
    let header = lines.next().unwrap_or("");
    let params = header
        .strip_suffix('\n')
        .and_then(|h| h.strip_prefix(JOURNAL_MAGIC))
        .and_then(|h| h.strip_prefix(' '))
        .ok_or_else(|| Error::NotFormat {
            path: path.clone(),
            format: "a kitti2pgm journal",
            detail: format!("its first line is not `{JOURNAL_MAGIC} PARAMETERS`"),
        })?;
    let frames = lines
        .filter_map(|l| l.strip_suffix('\n'))
        .filter(|l| !l.is_empty())
        .map(str::to_string)
        .collect();
    Ok(Some(JournalRecord {
        params: params.to_string(),
        frames,
    }))
}

/// What a run starts from: the frames it may keep, and what it removed.
#[derive(Debug)]
pub struct Journal {
    file: Mutex<File>,
    path: PathBuf,
    header: String,
    /// Frames recorded by this run.
    recorded: Mutex<BTreeSet<String>>,
    durability: Durability,
    /// Frames an earlier run with the same parameters finished (empty when starting afresh).
    pub finished: BTreeSet<String>,
    /// Converted outputs of other parameters (or of `--overwrite`) removed before converting.
    pub stale_removed: u64,
}

impl Journal {
    /// Opens the folder's journal for this run: continued when it was started with
    /// `opts.params` (and `--overwrite` is off); otherwise every converted output of the
    /// folder is removed and a new journal is started. A folder holding converted outputs but
    /// no record of their parameters (neither journal nor summary) is refused unless
    /// `--overwrite` is given: they are somebody else's files.
    pub fn start(opts: &ConvertOptions) -> Result<Journal> {
        let out = &opts.out;
        let path = out.root.join(JOURNAL_FILE);
        let record = read_journal(out).ok().flatten();
        let continued =
            !opts.overwrite && record.as_ref().is_some_and(|r| r.made_with(&opts.params));
        let mut stale_removed = 0;
        let header = format!("{JOURNAL_MAGIC} {}\n", params_key(&opts.params));
        let finished = if continued {
            record.map(|r| r.frames).unwrap_or_default()
        } else {
            let outputs = converted_outputs(out)?;
            let recorded = record.is_some() || out.summary_path().is_file();
            if !outputs.is_empty() && !recorded && !opts.overwrite {
                return Err(Error::Input {
                    path: out.root.clone(),
                    message: format!(
                        "holds {} converted files (first: {}) but no record of how they were made \
                         ({JOURNAL_FILE} or {}); write into an empty folder, or replace them \
                         with overwrite",
                        outputs.len(),
                        outputs[0].display(),
                        layout::SUMMARY_FILE
                    ),
                });
            }
            for p in &outputs {
                remove(p)?;
            }
            stale_removed = outputs.len() as u64;
            crate::format::atomic_write(&path, header.as_bytes(), Durability::Synced)?;
            BTreeSet::new()
        };
        let file = File::options()
            .append(true)
            .open(&path)
            .map_err(|source| Error::Write {
                path: path.clone(),
                source,
            })?;
        Ok(Journal {
            file: Mutex::new(file),
            path,
            header,
            recorded: Mutex::default(),
            durability: opts.durability,
            finished,
            stale_removed,
        })
    }

    /// Records that `id`'s files were written whole with this run's parameters.
    pub fn record(&self, id: &FrameId) -> Result<()> {
        let mut f = self.file.lock().expect("no panic while holding the lock");
        let werr = |source| Error::Write {
            path: self.path.clone(),
            source,
        };
        f.write_all(format!("{id}\n").as_bytes()).map_err(werr)?;
        self.durability.flush(&f).map_err(werr)?;
        drop(f);
        self.recorded
            .lock()
            .expect("no panic while holding the lock")
            .insert(id.to_string());
        Ok(())
    }

    /// Rewrites the journal in frame order (atomically), so that a finished folder's bytes do
    /// not depend on the thread count: the frames kept from earlier runs and those recorded now.
    pub fn finish(self) -> Result<()> {
        let recorded = self
            .recorded
            .into_inner()
            .expect("no panic while holding the lock");
        let mut text = self.header;
        for id in self.finished.union(&recorded) {
            text.push_str(id);
            text.push('\n');
        }
        drop(self.file);
        crate::format::atomic_write(&self.path, text.as_bytes(), self.durability)
    }

    /// Whether an earlier run with these parameters finished `frame` of `dp` and its files are
    /// still present and of the right size.
    pub fn frame_is_complete(&self, dp: &DrivePlan, frame: u32, opts: &ConvertOptions) -> bool {
        let id = dp.drive.frame_id(frame);
        self.finished.contains(&id.to_string()) && files_present(dp, frame, opts)
    }
}

/// Whether every output `opts` asks for of this frame is present and of the right size.
fn files_present(dp: &DrivePlan, frame: u32, opts: &ConvertOptions) -> bool {
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

/// Removes a frame's `.npy` and `.label` files if present (after it failed: whatever is there
/// was not made by this run).
pub fn remove_frame_files(id: &FrameId, opts: &ConvertOptions) -> Result<()> {
    for p in [opts.out.npy_path(id), opts.out.label_path(id)] {
        if p.is_file() {
            remove(&p)?;
        }
    }
    Ok(())
}
