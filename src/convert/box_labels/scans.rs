//! Which scan of a sequence each annotated frame is, by name: the scan file's stem
//! (`000042`), the stem of the file a scan link points to (`1673400472138016708` for
//! `000042.pcd -> /data/run1/1673400472138016708.pcd`, the README's way of making a folder of
//! other names a sequence), or a number equal to the frame's (`42`). Never by position.

use std::collections::{BTreeMap, HashMap};
use std::path::Path;

use crate::error::Result;
use crate::source::kitti::Drive;

/// The frames of a sequence by the names a box file may give their scans.
#[derive(Debug, Default)]
pub struct ScanNames {
    /// Name -> frame (`None`: two scans answer to it).
    by_name: HashMap<String, Option<u32>>,
    /// The sequence's frames, ascending.
    pub frames: Vec<u32>,
}

/// How an annotated frame's name was matched.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Match {
    /// The frame of that scan.
    Frame(u32),
    /// No scan of the sequence has that name.
    Missing,
    /// Two scans answer to the name (two links to files of one name).
    Ambiguous,
}

impl ScanNames {
    /// The names of `drive`'s scans.
    pub fn of(drive: &Drive) -> Result<ScanNames> {
        let frames = drive.scan_frames()?;
        let mut by_name: HashMap<String, Option<u32>> = HashMap::new();
        for &f in &frames {
            let path = drive.scan_path(f);
            for name in names_of(&path) {
                by_name
                    .entry(name)
                    .and_modify(|e| {
                        if *e != Some(f) {
                            *e = None;
                        }
                    })
                    .or_insert(Some(f));
            }
        }
        Ok(ScanNames { by_name, frames })
    }

    /// The frame whose scan is called `name`.
    pub fn find(&self, name: &str) -> Match {
        let hit = self.by_name.get(name).copied().or_else(|| {
            // A plain number names the frame of that number (`42` for `000042.pcd`).
            let n: u32 = name
                .parse()
                .ok()
                .filter(|_| name.bytes().all(|b| b.is_ascii_digit()))?;
            self.frames.binary_search(&n).ok().map(|_| Some(n))
        });
        match hit {
            Some(Some(f)) => Match::Frame(f),
            Some(None) => Match::Ambiguous,
            None => Match::Missing,
        }
    }

    /// Frames of `self.frames` that `matched` does not hold.
    pub fn without<T>(&self, matched: &BTreeMap<u32, T>) -> Vec<u32> {
        (self.frames.iter())
            .copied()
            .filter(|f| !matched.contains_key(f))
            .collect()
    }
}

/// A scan's names: its stem without the scan extension, and the same of its link's target.
fn names_of(path: &Path) -> Vec<String> {
    let mut names = vec![stem(path)];
    if let Ok(target) = std::fs::read_link(path) {
        let t = stem(&target);
        if !names.contains(&t) {
            names.push(t);
        }
    }
    names.retain(|n| !n.is_empty());
    names
}

/// A scan file's name without its scan extension (`.pcd.bin`, `.pcd`, `.bin`).
fn stem(path: &Path) -> String {
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned());
    let name = name.unwrap_or_default();
    for ext in [".pcd.bin", ".pcd", ".bin"] {
        if let Some(s) = name.strip_suffix(ext) {
            return s.to_string();
        }
    }
    name
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scans_are_found_by_stem_link_target_and_number() {
        let t = tempfile::tempdir().unwrap();
        let seq = t.path().join("00");
        let velo = seq.join("velodyne");
        std::fs::create_dir_all(&velo).unwrap();
        let data = t.path().join("data");
        std::fs::create_dir(&data).unwrap();
        for (frame, target) in [(0, "1673400472"), (1, "1673400473"), (2, "1673400472")] {
            let t = data.join(format!("{frame}")).join(format!("{target}.pcd"));
            std::fs::create_dir_all(t.parent().unwrap()).unwrap();
            std::fs::write(&t, b"").unwrap();
            std::os::unix::fs::symlink(&t, velo.join(format!("{frame:06}.pcd"))).unwrap();
        }
        let drive = Drive::sequence(&seq).unwrap();
        let names = ScanNames::of(&drive).unwrap();
        assert_eq!(names.find("000001"), Match::Frame(1));
        assert_eq!(names.find("1673400473"), Match::Frame(1));
        assert_eq!(names.find("2"), Match::Frame(2));
        assert_eq!(names.find("1673400472"), Match::Ambiguous);
        assert_eq!(names.find("7"), Match::Missing);
        assert_eq!(names.find("frame"), Match::Missing);
    }
}
