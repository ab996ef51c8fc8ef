//! READ: the KITTI raw layout and its files.
//!
//! `RAW_ROOT/<date>/calib_*.txt` and `RAW_ROOT/<date>/<date>_drive_<NNNN>_sync/` with
//! `velodyne_points/data/<frame10>.bin`, `image_0{0..3}/data/<frame10>.png`, `oxts/data/*.txt`,
//! `*/timestamps.txt` and `tracklet_labels.xml`. [`discover`] accepts the root, one date folder
//! or one drive folder. A frame is named by [`FrameId`], SqueezeSeg's `<date>_<drive4>_<frame10>`.

pub mod calib;
pub mod camera;
pub mod oxts;
pub mod timestamps;
pub mod tracklets;
pub mod velodyne;

use std::fmt;
use std::path::{Path, PathBuf};

use serde::Serialize;

use crate::error::{Error, Result};

/// One drive folder (`<date>_drive_<NNNN>_sync`).
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord, Serialize)]
pub struct Drive {
    /// Recording day, `YYYY_MM_DD`.
    pub date: String,
    /// Drive number (the `NNNN`).
    pub number: u32,
    /// The drive folder.
    pub dir: PathBuf,
}

/// A frame's identity: SqueezeSeg's `<date>_<drive4>_<frame10>`, e.g. `2011_09_26_0001_0000000010`.
#[derive(Debug, Clone, Default, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
pub struct FrameId {
    /// Recording day, `YYYY_MM_DD`.
    pub date: String,
    /// Drive number.
    pub drive: u32,
    /// Frame index within the drive.
    pub frame: u32,
}

impl FrameId {
    /// The drive folder of the frame, `<date>_drive_<NNNN>_sync`.
    pub fn drive_name(&self) -> String {
        drive_name(&self.date, self.drive)
    }
}

/// The drive folder name `<date>_drive_<NNNN>_sync`: the one place it is spelled.
pub fn drive_name(date: &str, number: u32) -> String {
    format!("{date}_drive_{number:04}_sync")
}

impl fmt::Display for FrameId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}_{:04}_{:010}", self.date, self.drive, self.frame)
    }
}

impl std::str::FromStr for FrameId {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        let bad = || format!("{s:?} is not a frame id like 2011_09_26_0001_0000000010");
        let (date, rest) = s.split_at_checked(10).ok_or_else(bad)?;
        let rest = rest.strip_prefix('_').ok_or_else(bad)?;
        let (drive, frame) = rest.split_once('_').ok_or_else(bad)?;
        if !is_date(date) || drive.len() != 4 || frame.len() != 10 {
            return Err(bad());
        }
        Ok(FrameId {
            date: date.into(),
            drive: drive.parse().map_err(|_| bad())?,
            frame: frame.parse().map_err(|_| bad())?,
        })
    }
}

fn is_date(s: &str) -> bool {
    let b = s.as_bytes();
    b.len() == 10
        && b.iter().enumerate().all(|(i, c)| {
            if i == 4 || i == 7 {
                *c == b'_'
            } else {
                c.is_ascii_digit()
            }
        })
}

/// Parses `<date>_drive_<NNNN>_sync` into (date, number).
pub fn parse_drive_name(name: &str) -> Option<(String, u32)> {
    let (date, rest) = name.split_at_checked(10)?;
    let num = rest.strip_prefix("_drive_")?.strip_suffix("_sync")?;
    if !is_date(date) || num.len() != 4 || !num.bytes().all(|c| c.is_ascii_digit()) {
        return None;
    }
    Some((date.to_string(), num.parse().ok()?))
}

fn file_name(p: &Path) -> &str {
    p.file_name().and_then(|s| s.to_str()).unwrap_or("")
}

impl Drive {
    /// The drive in folder `dir`, if its name is a drive name.
    pub fn from_dir(dir: &Path) -> Option<Drive> {
        let (date, number) = parse_drive_name(file_name(dir))?;
        Some(Drive {
            date,
            number,
            dir: dir.to_path_buf(),
        })
    }

    /// `<date>_drive_<NNNN>_sync`.
    pub fn name(&self) -> String {
        drive_name(&self.date, self.number)
    }

    /// The date folder holding the calibration files.
    pub fn date_dir(&self) -> PathBuf {
        self.dir.parent().map(Path::to_path_buf).unwrap_or_default()
    }

    /// The id of frame `frame` of this drive.
    pub fn frame_id(&self, frame: u32) -> FrameId {
        FrameId {
            date: self.date.clone(),
            drive: self.number,
            frame,
        }
    }

    /// Path of a velodyne scan.
    pub fn scan_path(&self, frame: u32) -> PathBuf {
        self.dir
            .join(format!("velodyne_points/data/{frame:010}.bin"))
    }

    /// Path of a camera image (camera 0-3).
    pub fn image_path(&self, camera: u8, frame: u32) -> PathBuf {
        self.dir
            .join(format!("image_{camera:02}/data/{frame:010}.png"))
    }

    /// Path of the drive's tracklets.
    pub fn tracklets_path(&self) -> PathBuf {
        self.dir.join("tracklet_labels.xml")
    }

    /// Path of the velodyne timestamps.
    pub fn scan_timestamps_path(&self) -> PathBuf {
        self.dir.join("velodyne_points/timestamps.txt")
    }

    /// Frame indices that have a velodyne scan, ascending.
    pub fn scan_frames(&self) -> Result<Vec<u32>> {
        Ok(self.scan_listing()?.frames)
    }

    /// The velodyne folder's listing: the frames (`<frame10>.bin`), and the files that are not
    /// frames, named so that they are reported instead of silently dropped. No folder: no frame.
    /// A folder that cannot be listed is an error.
    pub fn scan_listing(&self) -> Result<ScanListing> {
        let dir = self.dir.join("velodyne_points/data");
        let mut out = ScanListing::default();
        if !dir.exists() {
            return Ok(out);
        }
        for p in crate::fs::sorted_dir(&dir)? {
            let frame = p
                .file_name()
                .and_then(|n| n.to_str())
                .and_then(|n| n.strip_suffix(".bin"))
                .filter(|stem| stem.len() == 10 && stem.bytes().all(|c| c.is_ascii_digit()))
                .map(|stem| stem.parse().expect("10 digits fit u32"));
            match frame {
                Some(f) => out.frames.push(f),
                None => out.not_frames.push(p),
            }
        }
        out.frames.sort_unstable();
        Ok(out)
    }
}

/// The files of a drive's velodyne folder.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct ScanListing {
    /// Frame indices with a scan, ascending.
    pub frames: Vec<u32>,
    /// Entries that are not `<frame10>.bin` scans (a stray file, a 26-digit name, a folder).
    pub not_frames: Vec<PathBuf>,
}

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
    if !root.is_dir() {
        return Err(Error::Input {
            path: root.into(),
            message: "not a folder".into(),
        });
    }
    let canonical = root.canonicalize().map_err(|e| Error::io(root, e))?;
    let mut found = Discovery::default();
    if let Some(d) = Drive::from_dir(&canonical) {
        found.drives.push(d);
        return Ok(found);
    }
    let not_utf8 = |p: &Path| p.file_name().is_some_and(|n| n.to_str().is_none());
    let mut date_dirs = Vec::new();
    if is_date(file_name(&canonical)) {
        date_dirs.push(canonical.clone());
    } else {
        for p in crate::fs::sorted_dir(&canonical)? {
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
        let entries = match crate::fs::sorted_dir(&d) {
            Ok(e) => e,
            Err(e) => {
                found.problems.push((d, e.to_string()));
                continue;
            }
        };
        for p in entries {
            if !p.is_dir() {
                continue;
            }
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
    if found.drives.is_empty() && found.problems.is_empty() {
        return Err(Error::Input {
            path: root.into(),
            message: "no KITTI drive found (expected <date>/<date>_drive_<NNNN>_sync/ folders)"
                .into(),
        });
    }
    found.drives.sort();
    Ok(found)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_id_round_trips() {
        let id: FrameId = "2011_09_26_0001_0000000010".parse().unwrap();
        assert_eq!(
            id,
            FrameId {
                date: "2011_09_26".into(),
                drive: 1,
                frame: 10
            }
        );
        assert_eq!(id.to_string(), "2011_09_26_0001_0000000010");
        assert!("2011_09_26_1_10".parse::<FrameId>().is_err());
    }

    #[test]
    fn drive_names() {
        assert_eq!(
            parse_drive_name("2011_09_26_drive_0052_sync"),
            Some(("2011_09_26".into(), 52))
        );
        assert_eq!(parse_drive_name("2011_09_26_drive_0052_extract"), None);
    }
}
