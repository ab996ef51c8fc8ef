//! CONVERT again into the same folder: one conversion at a time, leftovers of an interrupted
//! run removed, finished frames kept only when they provably were made with this run's
//! parameters.
//!
//! A conversion holds an exclusive lock on `OUT/.kitti2pgm.lock` for as long as it runs, so a
//! second one into the same folder stops with an error instead of racing it. Under that lock,
//! the temporary files (`.tmp-*`) that an interrupted run (kill -9, power cut) left in the output
//! folders are its own leftovers and are removed.
//!
//! Provenance is a journal, `OUT/.kitti2pgm-frames` ([`crate::format::journal`]): the
//! parameters and the dataset root, then each frame whose files were written whole with them
//! (appended after the files were renamed into place), with every input it was made from. A
//! re-run keeps a frame only when the journal's parameters and root are this run's, the frame is
//! listed, its files are present and of the right size, and every input it read is as it was
//! (same content; a file that appeared where it found none counts as changed) ([`Verdict`]).
//! A run with other parameters, another root, an older journal (or `--overwrite`) first
//! removes every converted output of the folder (maps, labels, shards) and starts a new journal,
//! so that a folder never holds artefacts of two parameter sets or two datasets.

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::fs::File;
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use super::ConvertOptions;
use crate::error::{Error, Result};
use crate::format::journal::{self, JournalRecord, JOURNAL_FILE};
use crate::format::layout::{self, OutputDir};
use crate::format::{npy, Durability};
use crate::fs::inputs::Change;
use crate::fs::{Fingerprint, Inputs};
use crate::plan::{DrivePlan, Reconverted, Restart};
use crate::source::kitti::FrameId;

/// Name of the lock file in the output folder.
pub const LOCK_FILE: &str = ".kitti2pgm.lock";

/// Takes the output folder's lock; it is released when the returned file is dropped.
pub fn lock(out: &OutputDir) -> Result<File> {
    lock_dir(&out.root)
}

/// Takes the lock of the folder `dir` (a conversion's output, an unpack's root: one writer at a
/// time); it is released when the returned file is dropped (or its process dies).
pub fn lock_dir(dir: &Path) -> Result<File> {
    let path = dir.join(LOCK_FILE);
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
        Err(std::fs::TryLockError::WouldBlock) => Err(Error::Locked { path: dir.into() }),
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

/// Reads the folder's journal (`OUT/.kitti2pgm-frames`); `Ok(None)` when there is none.
pub fn read_journal(out: &OutputDir) -> Result<Option<JournalRecord>> {
    journal::read(&out.root.join(JOURNAL_FILE))
}

/// What a run does with one planned frame.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Verdict {
    /// Keep its files: the journal proves they were made with these parameters from the inputs
    /// as they are now.
    Keep,
    /// Convert it (again, when the reason is given).
    Convert(Option<(Reconverted, Option<Change>)>),
}

/// A fingerprint of an input as it is now, or why it cannot be taken.
type Now = std::result::Result<Option<Fingerprint>, String>;

/// What a run starts from: the frames it may keep, and what it removed.
#[derive(Debug)]
pub struct Journal {
    file: Mutex<File>,
    path: PathBuf,
    header: String,
    /// The dataset root as given and resolved (input paths are recorded relative to it).
    root: [PathBuf; 2],
    /// Frames converted, or proved unchanged, by this run, with their inputs.
    recorded: Mutex<BTreeMap<FrameId, Inputs>>,
    durability: Durability,
    /// Frames an earlier run with the same parameters and root finished (empty when starting
    /// afresh), not yet proved unchanged.
    finished: BTreeMap<FrameId, Inputs>,
    /// Inputs fingerprinted this run (a drive's tracklets serve all its frames).
    now: Mutex<HashMap<PathBuf, Now>>,
    /// Converted outputs of other parameters, another root or an older journal (or of
    /// `--overwrite`) removed before converting.
    pub stale_removed: u64,
    /// Why the earlier run's outputs were removed, if they were.
    pub restarted: Option<Restart>,
}

impl Journal {
    /// Opens the folder's journal for this run of `root`: continued when it was started with
    /// `opts.params` from the same root (and `--overwrite` is off); otherwise every converted
    /// output of the folder is removed and a new journal is started. A folder holding converted
    /// outputs but no record of their parameters (neither journal nor summary) is refused unless
    /// `--overwrite` is given: they are somebody else's files.
    pub fn start(opts: &ConvertOptions, root: &Path) -> Result<Journal> {
        let out = &opts.out;
        let path = out.root.join(JOURNAL_FILE);
        let resolved_root = crate::fs::resolved(root);
        let record = read_journal(out).ok().flatten();
        let restart = match &record {
            _ if opts.overwrite => Some(Restart::Overwrite),
            None => None,
            Some(r) if r.root.is_none() => Some(Restart::OldJournal),
            Some(r) if r.params != journal::params_key(&opts.params) => Some(Restart::Parameters),
            Some(r) if !r.made_with(&opts.params, &resolved_root) => Some(Restart::Root),
            Some(_) => None,
        };
        let mut stale_removed = 0;
        let header = journal::header(&opts.params, &resolved_root);
        let finished = match (restart, record) {
            (None, Some(r)) => r
                .frames
                .into_iter()
                .filter_map(|(id, inputs)| Some((id, inputs?)))
                .collect(),
            (_, record) => {
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
                BTreeMap::new()
            }
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
            root: [root.to_path_buf(), resolved_root],
            recorded: Mutex::default(),
            durability: opts.durability,
            finished,
            now: Mutex::default(),
            stale_removed,
            restarted: restart,
        })
    }

    /// Records that `id`'s files were written whole with this run's parameters from `inputs`
    /// (paths as read); returns the digest of the inputs as recorded (relative to the root).
    pub fn record(&self, id: &FrameId, inputs: &Inputs) -> Result<u64> {
        let inputs = self.relative(inputs);
        let digest = inputs.digest();
        let mut f = self.file.lock().expect("no panic while holding the lock");
        let werr = |source| Error::Write {
            path: self.path.clone(),
            source,
        };
        f.write_all(journal::frame_line(id, &inputs).as_bytes())
            .map_err(werr)?;
        self.durability.flush(&f).map_err(werr)?;
        drop(f);
        self.recorded().insert(id.clone(), inputs);
        Ok(digest)
    }

    fn recorded(&self) -> std::sync::MutexGuard<'_, BTreeMap<FrameId, Inputs>> {
        self.recorded
            .lock()
            .expect("no panic while holding the lock")
    }

    /// `inputs` (paths as read) as the journal records them: relative to the root.
    fn relative(&self, inputs: &Inputs) -> Inputs {
        inputs.relative_to(&[&self.root[0], &self.root[1]])
    }

    /// The digest of `inputs` (paths as read) as the journal records them.
    pub fn digest_of(&self, inputs: &Inputs) -> u64 {
        self.relative(inputs).digest()
    }

    /// The digest of the inputs this run recorded or proved for `id`.
    pub fn digest(&self, id: &FrameId) -> Option<u64> {
        self.recorded().get(id).map(Inputs::digest)
    }

    /// The fingerprint of `path` now (each path fingerprinted once a run).
    fn now(&self, path: &Path) -> Result<Option<Fingerprint>> {
        let cached = self
            .now
            .lock()
            .expect("no panic while holding the lock")
            .get(path)
            .cloned();
        let now = match cached {
            Some(n) => n,
            None => {
                let n = crate::fs::fingerprint(path).map_err(|e| e.to_string());
                self.now
                    .lock()
                    .expect("no panic while holding the lock")
                    .insert(path.to_path_buf(), n.clone());
                n
            }
        };
        now.map_err(|e| Error::Input {
            path: path.into(),
            message: e,
        })
    }

    /// Whether frame `frame` of `dp` is kept or converted, and why: kept when this run already
    /// recorded it, or when an earlier run finished it, every file `opts` asks for is present
    /// and of the right size, and every input it was made from is as it was.
    pub fn verdict(&self, dp: &DrivePlan, frame: u32, opts: &ConvertOptions) -> Verdict {
        let id = dp.drive.frame_id(frame);
        if self.recorded().contains_key(&id) {
            return Verdict::Keep;
        }
        let Some(inputs) = self.finished.get(&id) else {
            return Verdict::Convert(None);
        };
        if !files_present(dp, frame, opts) {
            return Verdict::Convert(Some((Reconverted::OutputMissing, None)));
        }
        match inputs.first_change(&self.root[1], &|p| self.now(p)) {
            Some(change) => Verdict::Convert(Some((Reconverted::InputChanged, Some(change)))),
            None => {
                self.recorded().insert(id, inputs.clone());
                Verdict::Keep
            }
        }
    }

    /// Frames an earlier run finished that this run neither kept nor converted (no longer
    /// planned: their scan went, their annotation changed): their files no longer match the
    /// inputs.
    pub fn unplanned(&self, planned: &BTreeSet<FrameId>) -> Vec<FrameId> {
        self.finished
            .keys()
            .filter(|id| !planned.contains(*id))
            .cloned()
            .collect()
    }

    /// Rewrites the journal in frame order (atomically), so that a finished folder's bytes do
    /// not depend on the thread count: the frames this run recorded or proved unchanged.
    pub fn finish(self) -> Result<()> {
        let recorded = self
            .recorded
            .into_inner()
            .expect("no panic while holding the lock");
        let text = journal::encode(&self.header, &recorded);
        drop(self.file);
        crate::format::atomic_write(&self.path, text.as_bytes(), self.durability)
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
        let layout = map.sensor.as_ref().and_then(|s| s.layout().ok().flatten());
        let points = crate::source::points_in_file_as(&dp.drive.scan_path(frame), layout.as_ref());
        points.is_some() && len(&opts.out.label_path(&id)) == points.map(|n| n * 4)
    };
    npy_ok && labels_ok
}

/// Removes a frame's `.npy` and `.label` files if present (after it failed: whatever is there
/// was not made by this run); returns how many.
pub fn remove_frame_files(id: &FrameId, opts: &ConvertOptions) -> Result<u64> {
    let mut removed = 0;
    for p in [opts.out.npy_path(id), opts.out.label_path(id)] {
        if p.is_file() {
            remove(&p)?;
            removed += 1;
        }
    }
    Ok(removed)
}
