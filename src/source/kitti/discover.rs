//! READ: finding the drives, sequences or object splits under a root, and naming the folders
//! that cannot be read as one.

use std::path::{Path, PathBuf};

use super::{file_name, is_date, DatasetKind, Drive};
use crate::error::{Error, Result};

/// What [`discover_all`] found under a root.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Discovery {
    /// The drives, sorted by date and number.
    pub drives: Vec<Drive>,
    /// Folders that look like drives or dates but cannot be read as one, with the reason
    /// (a name that is not valid UTF-8, a date folder that cannot be listed).
    pub problems: Vec<(PathBuf, String)>,
}

/// Finds the drives under `root`: a KITTI raw root (date folders), a date folder or one drive
/// folder. Drives come sorted by date and number. Problems with single folders are left out
/// (see [`discover_all`], which names them).
pub fn discover(root: &Path) -> Result<Vec<Drive>> {
    Ok(discover_all(root)?.drives)
}

/// Like [`discover`], and names the folders it could not read as drives: a folder name that is
/// not valid UTF-8, a date folder that cannot be listed. An error when `root` is not a folder
/// or holds no drive at all.
pub fn discover_all(root: &Path) -> Result<Discovery> {
    discover_as(root, None)
}

/// Like [`discover_all`], for the layout `source` when given, else the one `root` shows: KITTI
/// raw (a root, date or drive folder), SemanticKITTI / odometry (a root with `sequences/`, or
/// one sequence folder `<NN>` with `velodyne/`), or the object set (a root with `training/`
/// and/or `testing/`: `training/` is taken when both are there; or one split folder).
pub fn discover_as(root: &Path, source: Option<DatasetKind>) -> Result<Discovery> {
    // Nothing found: a recording that must be unpacked first says so.
    discover_layout(root, source).map_err(|e| match crate::source::Recording::of(root) {
        Some(recording) => Error::Input {
            path: root.into(),
            message: recording.to_string(),
        },
        None => e,
    })
}

/// [`discover_as`] without the hint for recordings to unpack.
fn discover_layout(root: &Path, source: Option<DatasetKind>) -> Result<Discovery> {
    if !root.is_dir() {
        return Err(Error::Input {
            path: root.into(),
            message: if root.exists() {
                "not a folder (give the dataset's root folder)".into()
            } else {
                "no such folder".into()
            },
        });
    }
    let canonical = root.canonicalize().map_err(|e| Error::io(root, e))?;
    let none = |what: &str| Error::Input {
        path: root.into(),
        message: format!("no {what} found here"),
    };
    let found = |drives: Vec<Drive>| Discovery {
        drives,
        problems: Vec::new(),
    };
    match source {
        Some(DatasetKind::Sequence) => {
            let drives = sequences(&canonical)?;
            if drives.is_empty() {
                return Err(none(
                    "SemanticKITTI / odometry sequence (sequences/<NN>/velodyne/)",
                ));
            }
            Ok(found(drives))
        }
        Some(DatasetKind::Object) => {
            let drives = object_splits(&canonical);
            if drives.is_empty() {
                return Err(none(
                    "KITTI object split (training/ or testing/ with velodyne/)",
                ));
            }
            Ok(found(drives))
        }
        Some(DatasetKind::Raw) => raw_drives(root, &canonical),
        None if !raw_like(&canonical)? => {
            let seqs = sequences(&canonical)?;
            if !seqs.is_empty() {
                return Ok(found(seqs));
            }
            let objs = object_splits(&canonical);
            if !objs.is_empty() {
                return Ok(found(objs));
            }
            raw_drives(root, &canonical)
        }
        None => raw_drives(root, &canonical),
    }
}

fn has_scans(d: &Path) -> bool {
    d.join(super::sequence::SCANS).is_dir()
}

/// Whether `dir` is a raw drive, a date folder, or holds date folders.
fn raw_like(dir: &Path) -> Result<bool> {
    Ok(Drive::from_dir(dir).is_some()
        || is_date(file_name(dir))
        || crate::fs::sorted_dir(dir)?
            .iter()
            .any(|p| p.is_dir() && is_date(file_name(p))))
}

/// The sequences at `dir`: itself when it holds `velodyne/`, else `sequences/<NN>` (or `<NN>`)
/// folders with scans. A sequence an unpack began and never finished is refused
/// ([`crate::source::unpacked::refuse_unfinished`]).
fn sequences(dir: &Path) -> Result<Vec<Drive>> {
    let folders = if has_scans(dir) {
        vec![dir.to_path_buf()]
    } else {
        let parent = if dir.join(super::sequence::SEQUENCES).is_dir() {
            dir.join(super::sequence::SEQUENCES)
        } else {
            dir.to_path_buf()
        };
        (crate::fs::sorted_dir(&parent)?.into_iter())
            .filter(|p| has_scans(p))
            .collect()
    };
    let mut drives = Vec::with_capacity(folders.len());
    for p in folders {
        if let Some(d) = Drive::sequence(&p) {
            crate::source::unpacked::refuse_unfinished(&p)?;
            drives.push(d);
        }
    }
    Ok(drives)
}

/// The object split at `dir`: itself when it holds `velodyne/` (and no `labels/`, which a
/// sequence has), else `training/` or, without it, `testing/`.
fn object_splits(dir: &Path) -> Vec<Drive> {
    if has_scans(dir) && !dir.join(super::sequence::LABELS).is_dir() {
        return vec![Drive::object_split(dir)];
    }
    ["training", "testing"]
        .iter()
        .map(|s| dir.join(s))
        .find(|d| has_scans(d))
        .map(|d| Drive::object_split(&d))
        .into_iter()
        .collect()
}

fn not_utf8(p: &Path) -> bool {
    p.file_name().is_some_and(|n| n.to_str().is_none())
}

/// The raw drives at `canonical` (a drive, a date folder, or a root of date folders), and the
/// folders that could not be read as such.
fn raw_drives(root: &Path, canonical: &Path) -> Result<Discovery> {
    let mut found = Discovery::default();
    if let Some(d) = Drive::from_dir(canonical) {
        found.drives.push(d);
        return Ok(found);
    }
    let mut date_dirs = Vec::new();
    if is_date(file_name(canonical)) {
        date_dirs.push(canonical.to_path_buf());
    } else {
        for p in crate::fs::sorted_dir(canonical)? {
            if p.is_dir() && is_date(file_name(&p)) {
                date_dirs.push(p);
            } else if p.is_dir() && not_utf8(&p) {
                found
                    .problems
                    .push((p, "folder name is not valid UTF-8".into()));
            }
        }
    }
    for d in date_dirs {
        drives_of_day(d, &mut found);
    }
    if found.drives.is_empty() && found.problems.is_empty() {
        return Err(Error::Input {
            path: root.into(),
            message: "no KITTI drive found (expected <date>/<date>_drive_<NNNN>_sync/ folders, sequences/<NN>/velodyne/, or training/velodyne/)"
                .into(),
        });
    }
    found.drives.sort();
    Ok(found)
}

/// The drive folders of one date folder, into `found`.
fn drives_of_day(d: PathBuf, found: &mut Discovery) {
    let entries = match crate::fs::sorted_dir(&d) {
        Ok(e) => e,
        Err(e) => {
            found.problems.push((d, e.to_string()));
            return;
        }
    };
    for p in entries.into_iter().filter(|p| p.is_dir()) {
        if let Some(drive) = Drive::from_dir(&p) {
            found.drives.push(drive);
        } else if not_utf8(&p) {
            found.problems.push((
                p,
                "folder name is not valid UTF-8 (a drive folder is <date>_drive_<NNNN>_sync)"
                    .into(),
            ));
        }
    }
}
