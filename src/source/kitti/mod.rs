//! READ: the layouts of the KITTI family and their files.
//!
//! Three layouts ([`DatasetKind`]), each a set of "drives" (folders of frames that share a
//! calibration and an annotation):
//!
//! - **KITTI raw**: `RAW_ROOT/<date>/calib_*.txt` and `RAW_ROOT/<date>/<date>_drive_<NNNN>_sync/`
//!   with `velodyne_points/data/<frame10>.bin`, `image_0{0..3}/data/<frame10>.png`,
//!   `oxts/data/*.txt`, `*/timestamps.txt` and `tracklet_labels.xml`. Frame id
//!   `<date>_<drive4>_<frame10>` (SqueezeSeg's).
//! - **SemanticKITTI / KITTI odometry**: `ROOT/sequences/<NN>/` with `velodyne/<frame6>.bin`,
//!   `labels/<frame6>.label`, `calib.txt`, `image_2/<frame6>.png`. Frame id `<seq2>_<frame6>`.
//! - **KITTI 3D object**: `ROOT/training/` (or `testing/`) with `velodyne/<frame6>.bin`,
//!   `image_2/<frame6>.png`, `calib/<frame6>.txt`, `label_2/<frame6>.txt`. Frame id `<frame6>`.
//!
//! [`discover_all`] accepts a root or one drive, sequence or split folder of any of them, and
//! finds the layout (or takes the one forced).

pub mod calib;
pub mod camera;
mod discover;
pub mod object;
pub mod oxts;
pub mod poses;
pub mod sequence;
pub mod timestamps;
pub mod tracklets;
pub mod velodyne;

use std::fmt;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

pub use crate::error::NotAFrameId;
use crate::error::Result;

/// Frame numbers are below this (a million scans: 28 hours at 10 Hz; KITTI's longest drive has
/// under 5,200, and 6-digit names end at 999,999). A scan named beyond it is not a frame, a
/// tracklet reaching beyond it is malformed: no allocation or arithmetic can be driven by a
/// wild frame number.
pub const MAX_FRAME: u32 = 1_000_000;
pub use discover::{discover, discover_all, discover_as, Discovery};

pub use super::dataset::DatasetKind;

/// A folder of frames: a raw drive (`<date>_drive_<NNNN>_sync`), an odometry sequence
/// (`sequences/<NN>`) or an object split (`training/`, `testing/`).
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord, Serialize)]
pub struct Drive {
    /// Which dataset it belongs to (serialised as `layout`, as earlier versions wrote it).
    #[serde(rename = "layout")]
    pub dataset: DatasetKind,
    /// Recording day, `YYYY_MM_DD` (raw); empty otherwise.
    pub date: String,
    /// Drive number (raw `NNNN`), sequence number; 0 for an object split.
    pub number: u32,
    /// The folder.
    pub dir: PathBuf,
}

/// A frame's identity: `<date>_<drive4>_<frame10>` (raw, SqueezeSeg's, e.g.
/// `2011_09_26_0001_0000000010`), `<seq2>_<frame6>` (sequences, `00_000000`) or `<frame6>`
/// (object set).
#[derive(Debug, Clone, Default, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(into = "String", try_from = "String")]
pub struct FrameId {
    /// Which dataset it belongs to.
    pub dataset: DatasetKind,
    /// Recording day, `YYYY_MM_DD` (raw); empty otherwise.
    pub date: String,
    /// Drive or sequence number (0 for the object set).
    pub drive: u32,
    /// Frame index within the drive.
    pub frame: u32,
}

impl FrameId {
    /// A raw frame's id.
    pub fn raw(date: &str, drive: u32, frame: u32) -> FrameId {
        FrameId {
            dataset: DatasetKind::Raw,
            date: date.into(),
            drive,
            frame,
        }
    }

    /// The folder that groups the frame's per-point outputs: the raw drive folder
    /// `<date>_drive_<NNNN>_sync`, the sequence `<NN>`, or `object`.
    pub fn drive_name(&self) -> String {
        match self.dataset {
            DatasetKind::Raw => drive_name(&self.date, self.drive),
            DatasetKind::Sequence => format!("{:02}", self.drive),
            DatasetKind::Object => "object".into(),
        }
    }

    /// The frame number as its files spell it: 10 digits (raw) or 6.
    pub fn frame_name(&self) -> String {
        match self.dataset {
            DatasetKind::Raw => format!("{:010}", self.frame),
            _ => format!("{:06}", self.frame),
        }
    }
}

/// The drive folder name `<date>_drive_<NNNN>_sync`: the one place it is spelled.
pub fn drive_name(date: &str, number: u32) -> String {
    format!("{date}_drive_{number:04}_sync")
}

impl From<FrameId> for String {
    fn from(id: FrameId) -> String {
        id.to_string()
    }
}

impl TryFrom<String> for FrameId {
    type Error = NotAFrameId;
    fn try_from(s: String) -> std::result::Result<FrameId, NotAFrameId> {
        s.parse()
    }
}

impl fmt::Display for FrameId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.dataset {
            DatasetKind::Raw => write!(f, "{}_{:04}_{:010}", self.date, self.drive, self.frame),
            DatasetKind::Sequence => write!(f, "{:02}_{:06}", self.drive, self.frame),
            DatasetKind::Object => write!(f, "{:06}", self.frame),
        }
    }
}

impl std::str::FromStr for FrameId {
    type Err = NotAFrameId;
    fn from_str(s: &str) -> std::result::Result<Self, NotAFrameId> {
        let bad = || NotAFrameId(s.into());
        let digits = |t: &str, n: usize| t.len() == n && t.bytes().all(|c| c.is_ascii_digit());
        let number = |t: &str| t.parse::<u32>().map_err(|_| bad());
        if digits(s, 6) {
            return Ok(FrameId {
                dataset: DatasetKind::Object,
                frame: number(s)?,
                ..Default::default()
            });
        }
        if let Some((seq, frame)) = s.split_once('_') {
            if sequence_number(seq).is_some() && digits(frame, 6) {
                return Ok(FrameId {
                    dataset: DatasetKind::Sequence,
                    date: String::new(),
                    drive: number(seq)?,
                    frame: number(frame)?,
                });
            }
        }
        let (date, rest) = s.split_at_checked(10).ok_or_else(bad)?;
        let rest = rest.strip_prefix('_').ok_or_else(bad)?;
        let (drive, frame) = rest.split_once('_').ok_or_else(bad)?;
        if !is_date(date) || !digits(drive, 4) || !digits(frame, 10) {
            return Err(bad());
        }
        Ok(FrameId::raw(date, number(drive)?, number(frame)?))
    }
}

/// The number of a sequence folder: two digits as SemanticKITTI writes them (`00`-`99`), or up
/// to four without a leading zero (`100`-`9999`: one sequence a nuScenes scene, `scene-1077`).
pub fn sequence_number(name: &str) -> Option<u32> {
    let n: u32 = name.parse().ok()?;
    let digits = (2..=4).contains(&name.len()) && name.bytes().all(|c| c.is_ascii_digit());
    (digits && format!("{n:02}") == name).then_some(n)
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
    /// The raw drive in folder `dir`, if its name is a drive name.
    pub fn from_dir(dir: &Path) -> Option<Drive> {
        let (date, number) = parse_drive_name(file_name(dir))?;
        Some(Drive {
            dataset: DatasetKind::Raw,
            date,
            number,
            dir: dir.to_path_buf(),
        })
    }

    /// The odometry sequence in folder `dir` (named by its number: [`sequence_number`]).
    pub fn sequence(dir: &Path) -> Option<Drive> {
        sequence_number(file_name(dir)).map(|number| Drive {
            dataset: DatasetKind::Sequence,
            date: String::new(),
            number,
            dir: dir.to_path_buf(),
        })
    }

    /// The object-set split in folder `dir` (`training/`, `testing/`).
    pub fn object_split(dir: &Path) -> Drive {
        Drive {
            dataset: DatasetKind::Object,
            date: String::new(),
            number: 0,
            dir: dir.to_path_buf(),
        }
    }

    /// The drive's name: `<date>_drive_<NNNN>_sync`, the sequence `<NN>`, or `object`.
    pub fn name(&self) -> String {
        self.frame_id(0).drive_name()
    }

    /// The date folder holding the calibration files (raw).
    pub fn date_dir(&self) -> PathBuf {
        self.dir.parent().map(Path::to_path_buf).unwrap_or_default()
    }

    /// The id of frame `frame` of this drive.
    pub fn frame_id(&self, frame: u32) -> FrameId {
        FrameId {
            dataset: self.dataset,
            date: self.date.clone(),
            drive: self.number,
            frame,
        }
    }

    /// The folder of the velodyne scans.
    fn scan_dir(&self) -> PathBuf {
        match self.dataset {
            DatasetKind::Raw => self.dir.join("velodyne_points/data"),
            _ => self.dir.join(sequence::SCANS),
        }
    }

    /// Path of a velodyne scan: `<frame>.bin`; in a sequence of another sensor's scans
    /// (point_labeler's layout) the `<frame6>.pcd`, else nuScenes' `<frame6>.pcd.bin`, where
    /// there is no `.bin`.
    pub fn scan_path(&self, frame: u32) -> PathBuf {
        let name = self.frame_id(frame).frame_name();
        let bin = self.scan_dir().join(format!("{name}.bin"));
        if self.dataset == DatasetKind::Sequence && !bin.exists() {
            for ext in ["pcd", "pcd.bin"] {
                let other = self.scan_dir().join(format!("{name}.{ext}"));
                if other.exists() {
                    return other;
                }
            }
        }
        bin
    }

    /// Path of a camera image (camera 0-3).
    pub fn image_path(&self, camera: u8, frame: u32) -> PathBuf {
        let name = self.frame_id(frame).frame_name();
        match self.dataset {
            DatasetKind::Raw => self.dir.join(format!("image_{camera:02}/data/{name}.png")),
            _ => self.dir.join(format!("image_{camera}/{name}.png")),
        }
    }

    /// Path of a sequence frame's per-point labels (`labels/<frame6>.label`).
    pub fn point_labels_path(&self, frame: u32) -> PathBuf {
        let name = self.frame_id(frame).frame_name();
        self.dir.join(format!("labels/{name}.label"))
    }

    /// Path of an object frame's boxes (`label_2/<frame6>.txt`).
    pub fn object_labels_path(&self, frame: u32) -> PathBuf {
        let name = self.frame_id(frame).frame_name();
        self.dir.join(format!("label_2/{name}.txt"))
    }

    /// Path of the calibration: a sequence's `calib.txt`, an object frame's `calib/<frame6>.txt`
    /// (raw calibration is per day: [`Drive::date_dir`]).
    pub fn calib_path(&self, frame: u32) -> PathBuf {
        match self.dataset {
            DatasetKind::Object => {
                let name = self.frame_id(frame).frame_name();
                self.dir.join(format!("calib/{name}.txt"))
            }
            _ => self.dir.join("calib.txt"),
        }
    }

    /// Whether a frame has labels: always for raw drives (a frame without a tracklet pose is
    /// still ground truth: all background); a label file for sequences and object frames.
    pub fn has_labels(&self, frame: u32) -> bool {
        match self.dataset {
            DatasetKind::Raw => true,
            DatasetKind::Sequence => crate::fs::present(&self.point_labels_path(frame)),
            DatasetKind::Object => crate::fs::present(&self.object_labels_path(frame)),
        }
    }

    /// The label files (SemanticKITTI `labels/*.label`, object `label_2/*.txt`) that belong to
    /// no scan of `scans` (sorted): extra files that no conversion reads, named so that a
    /// missing scan does not go unnoticed. Raw drives have none.
    pub fn labels_without_scan(&self, scans: &[u32]) -> Result<Vec<PathBuf>> {
        let (dir, ext) = match self.dataset {
            DatasetKind::Raw => return Ok(Vec::new()),
            DatasetKind::Sequence => (self.dir.join(sequence::LABELS), "label"),
            DatasetKind::Object => (self.dir.join("label_2"), "txt"),
        };
        if !dir.is_dir() {
            return Ok(Vec::new());
        }
        let width = self.frame_id(0).frame_name().len();
        Ok(crate::fs::sorted_dir(&dir)?
            .into_iter()
            .filter(|p| p.extension().is_some_and(|e| e == ext))
            .filter(|p| {
                let frame = p
                    .file_stem()
                    .and_then(|n| n.to_str())
                    .filter(|n| n.len() == width)
                    .and_then(|n| n.parse::<u32>().ok());
                frame.is_none_or(|f| scans.binary_search(&f).is_err())
            })
            .collect())
    }

    /// Path of the drive's tracklets (raw).
    pub fn tracklets_path(&self) -> PathBuf {
        self.dir.join("tracklet_labels.xml")
    }

    /// Path of the velodyne timestamps (raw).
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
        let dir = self.scan_dir();
        let width = self.frame_id(0).frame_name().len();
        let mut out = ScanListing::default();
        if !dir.exists() {
            return Ok(out);
        }
        // A sequence of another sensor may hold PCD or nuScenes `.pcd.bin` files (one per
        // frame); one beside the `.bin` of its frame, or a `.pcd.bin` beside the `.pcd`, is not
        // read ([`Drive::scan_path`] takes the first of `.bin`, `.pcd`, `.pcd.bin`).
        let other = self.dataset == DatasetKind::Sequence;
        for p in crate::fs::sorted_dir(&dir)? {
            let frame = p
                .file_name()
                .and_then(|n| n.to_str())
                .and_then(|n| {
                    let taken = |stem: &str, ext: &str| dir.join(format!("{stem}.{ext}")).exists();
                    if let Some(stem) = n.strip_suffix(".pcd.bin") {
                        return Some(stem)
                            .filter(|s| other && !taken(s, "bin") && !taken(s, "pcd"));
                    }
                    n.strip_suffix(".bin")
                        .or_else(|| n.strip_suffix(".pcd").filter(|s| other && !taken(s, "bin")))
                })
                .filter(|stem| stem.len() == width && stem.bytes().all(|c| c.is_ascii_digit()))
                // 10 digits beyond u32 (9999999999.bin) or beyond any drive's length: not a
                // frame, named as such.
                .and_then(|stem| stem.parse::<u32>().ok())
                .filter(|&f| f < MAX_FRAME);
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
    /// Entries that are not `<frame10>.bin` scans (a stray file, a 26-digit name, a folder; a
    /// sequence's `.pcd` beside the `.bin` of its frame).
    pub not_frames: Vec<PathBuf>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_id_round_trips() {
        let id: FrameId = "2011_09_26_0001_0000000010".parse().unwrap();
        assert_eq!(id, FrameId::raw("2011_09_26", 1, 10));
        assert_eq!(id.to_string(), "2011_09_26_0001_0000000010");
        assert!("2011_09_26_1_10".parse::<FrameId>().is_err());
        for s in ["00_000123", "000042", "1077_000003", "100_000000"] {
            let id: FrameId = s.parse().unwrap();
            assert_eq!(id.to_string(), s);
        }
        assert_eq!("08_000007".parse::<FrameId>().unwrap().drive_name(), "08");
        assert!("0_000007".parse::<FrameId>().is_err());
        // Sequences: two digits, or up to four without a leading zero (one spelling a number).
        for (name, n) in [
            ("00", Some(0)),
            ("08", Some(8)),
            ("61", Some(61)),
            ("1077", Some(1077)),
        ] {
            assert_eq!(sequence_number(name), n);
        }
        for name in ["0", "008", "0061", "12345", "6a", "+1"] {
            assert_eq!(sequence_number(name), None, "{name}");
        }
        assert!("0061_000007".parse::<FrameId>().is_err());
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
