//! PLAN: the train/val split, from the tracklets and the list of velodyne files alone (no point data is
//! read, so the whole dataset takes seconds).
//!
//! SqueezeSeg's rule, verified on the real files: `all` = every frame with a velodyne scan and at
//! least one tracklet pose of any object type; `val` = drives 0064 0070 0079 0084 0086 0087 0091
//! 0093 of 2011_09_26; `train` = the rest. Other val drives, or a seeded, drive-disjoint random
//! split with a target val fraction, are options.

use std::collections::BTreeSet;
use std::path::Path;

use serde::{Deserialize, Serialize};

use super::selection::FrameSelection;
use crate::error::{Error, Result};
use crate::kitti::tracklets::Tracklets;
use crate::kitti::{discover, Drive, FrameId};

/// SqueezeSeg's validation drives (all of 2011_09_26).
pub const SQUEEZESEG_VAL: [u32; 8] = [64, 70, 79, 84, 86, 87, 91, 93];

/// A drive key: (date, number).
pub type DriveKey = (String, u32);

/// How drives are assigned to val.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum SplitRule {
    /// These drives are val, the others train.
    Drives(BTreeSet<DriveKey>),
    /// Drives shuffled with `seed`, then taken into val until its share of frames is nearest
    /// `fraction`.
    Random {
        /// Target share of frames in val (0..1).
        fraction: f64,
        /// Shuffle seed.
        seed: u64,
    },
}

impl SplitRule {
    /// SqueezeSeg's split.
    pub fn squeezeseg() -> SplitRule {
        SplitRule::Drives(
            SQUEEZESEG_VAL
                .iter()
                .map(|&n| ("2011_09_26".to_string(), n))
                .collect(),
        )
    }

    /// Parses val drives written as `NNNN` (taken as 2011_09_26) or `<date>_NNNN` / `<date>_drive_NNNN_sync`.
    pub fn parse_drives(list: &[String]) -> Result<SplitRule> {
        let mut set = BTreeSet::new();
        for item in list
            .iter()
            .flat_map(|s| s.split(','))
            .map(str::trim)
            .filter(|s| !s.is_empty())
        {
            let key = if let Some((date, n)) = crate::kitti::parse_drive_name(item) {
                Some((date, n))
            } else if item.len() == 15 && item.as_bytes()[10] == b'_' {
                item[11..].parse().ok().map(|n| (item[..10].to_string(), n))
            } else {
                item.parse().ok().map(|n| ("2011_09_26".to_string(), n))
            };
            set.insert(key.ok_or_else(|| {
                Error::Config(format!(
                    "{item:?} is not a drive (NNNN, <date>_NNNN or <date>_drive_NNNN_sync)"
                ))
            })?);
        }
        Ok(SplitRule::Drives(set))
    }
}

/// The three lists.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct SplitLists {
    /// Every selected frame, sorted.
    pub all: Vec<FrameId>,
    /// Train frames, sorted.
    pub train: Vec<FrameId>,
    /// Val frames, sorted.
    pub val: Vec<FrameId>,
    /// Val drives, as `<date>_drive_NNNN_sync`.
    pub val_drives: Vec<String>,
}

/// The frames of one drive that `selection` picks: scans with at least one tracklet pose, or
/// every scan. Reads the tracklets file when there is one; never reads point data.
pub fn drive_frames(drive: &Drive, selection: FrameSelection) -> Result<Vec<u32>> {
    let scans = drive.scan_frames()?;
    if selection == FrameSelection::All {
        return Ok(scans);
    }
    let path = drive.tracklets_path();
    let t = if path.exists() {
        Tracklets::read(&path)?
    } else {
        Tracklets::default()
    };
    Ok(scans
        .into_iter()
        .filter(|f| selection.keeps(&t, *f))
        .collect())
}

/// splitmix64: a tiny, fully specified generator, so that a seed gives the same split with every
/// version of this tool (a library generator may change its stream between releases).
pub fn splitmix64(state: &mut u64) -> u64 {
    *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The val drives that `rule` picks among `drives` (each with its number of selected frames).
pub fn val_drives(rule: &SplitRule, drives: &[(DriveKey, usize)]) -> Result<BTreeSet<DriveKey>> {
    Ok(match rule {
        SplitRule::Drives(set) => set.clone(),
        SplitRule::Random { fraction, seed } => {
            if !(0.0..=1.0).contains(fraction) {
                return Err(Error::Config(format!(
                    "val fraction {fraction} must be in [0, 1]"
                )));
            }
            let mut order: Vec<usize> = (0..drives.len()).collect();
            let mut state = *seed;
            for i in (1..order.len()).rev() {
                let j = (splitmix64(&mut state) % (i as u64 + 1)) as usize;
                order.swap(i, j);
            }
            let total: usize = drives.iter().map(|(_, n)| n).sum();
            let target = fraction * total as f64;
            let mut taken = 0usize;
            let mut set = BTreeSet::new();
            for i in order {
                let n = drives[i].1;
                if n == 0 {
                    continue;
                }
                // Take the drive when that brings val closer to the target.
                if ((taken + n) as f64 - target).abs() < (taken as f64 - target).abs() {
                    taken += n;
                    set.insert(drives[i].0.clone());
                }
            }
            set
        }
    })
}

/// Builds the lists for the drives under `root`.
pub fn split(root: &Path, selection: FrameSelection, rule: &SplitRule) -> Result<SplitLists> {
    let drives = discover(root)?;
    let mut per_drive: Vec<(Drive, Vec<u32>)> = Vec::with_capacity(drives.len());
    for d in drives {
        let frames = drive_frames(&d, selection)?;
        per_drive.push((d, frames));
    }
    let counts: Vec<(DriveKey, usize)> = per_drive
        .iter()
        .map(|(d, f)| ((d.date.clone(), d.number), f.len()))
        .collect();
    let val = val_drives(rule, &counts)?;
    let mut out = SplitLists::default();
    for (d, frames) in &per_drive {
        let is_val = val.contains(&(d.date.clone(), d.number));
        if is_val && !frames.is_empty() {
            out.val_drives.push(d.name());
        }
        for &f in frames {
            let id = d.frame_id(f);
            out.all.push(id.clone());
            if is_val {
                out.val.push(id)
            } else {
                out.train.push(id)
            }
        }
    }
    out.all.sort();
    out.train.sort();
    out.val.sort();
    Ok(out)
}
