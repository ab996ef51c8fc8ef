//! PLAN: the train/val split, from the tracklets and the list of velodyne files alone (no point data is
//! read, so the whole dataset takes seconds).
//!
//! SqueezeSeg's rule, verified on the real files: `all` = every frame with a velodyne scan and at
//! least one tracklet pose of any object type; `val` = drives 0064 0070 0079 0084 0086 0087 0091
//! 0093 of 2011_09_26; `train` = the rest. Other val drives, or a seeded, drive-disjoint random
//! split with a target val fraction, are options.
//!
//! SemanticKITTI: the dataset's own split (`semantic-kitti.yaml`: valid = sequence 08; train =
//! the other labelled sequences); scans without labels (the test sequences 11-21) go to `test`.
//! KITTI object: a seeded random split of the frames (each frame is its own unit), or a given
//! ImageSet list of val frames; frames without `label_2` go to `test`.

use std::collections::BTreeSet;
use std::path::Path;

use serde::{Deserialize, Serialize};

use super::selection::FrameSelection;
use crate::error::{Error, Result};
use crate::source::kitti::tracklets::Tracklets;
use crate::source::kitti::{discover_as, DatasetKind, Drive, FrameId};

/// SqueezeSeg's validation drives (all of 2011_09_26).
pub const SQUEEZESEG_VAL: [u32; 8] = [64, 70, 79, 84, 86, 87, 91, 93];

/// A drive key: (date, number).
pub type DriveKey = (String, u32);

/// Which part of the data a frame is in.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Split {
    /// Trained on.
    #[default]
    Train,
    /// Validated on.
    Val,
    /// Without labels (SemanticKITTI test sequences, object `testing/`).
    Test,
}

crate::named_enum!(Split, "split", [
    Train => "train" [] "trained on",
    Val => "val" [] "validated on",
    Test => "test" [] "without labels",
]);

/// How drives are assigned to val.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum SplitRule {
    /// These drives are val, the others train.
    Drives(BTreeSet<DriveKey>),
    /// These odometry / SemanticKITTI sequences are val, the others train.
    Sequences(BTreeSet<u32>),
    /// These frames are val (an ImageSet list), the others train.
    Frames(BTreeSet<FrameId>),
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
    /// The default rule for a layout: SqueezeSeg's (raw), SemanticKITTI's own (sequences), a
    /// seeded half-and-half frame split (object).
    pub fn default_for(layout: DatasetKind) -> SplitRule {
        match layout {
            DatasetKind::Raw => SplitRule::squeezeseg(),
            DatasetKind::Sequence => SplitRule::semantic_kitti(),
            DatasetKind::Object => SplitRule::Random {
                fraction: 0.5,
                seed: 0,
            },
        }
    }

    /// SemanticKITTI's split, from the dataset's own `semantic-kitti.yaml`: its `valid`
    /// sequences are val.
    pub fn semantic_kitti() -> SplitRule {
        #[derive(Deserialize)]
        struct Yaml {
            split: YamlSplit,
        }
        #[derive(Deserialize)]
        struct YamlSplit {
            valid: Vec<u32>,
        }
        let y: Yaml = serde_norway::from_str(crate::label::classes::SEMANTIC_KITTI_YAML)
            .expect("the embedded semantic-kitti.yaml has a split");
        SplitRule::Sequences(y.split.valid.into_iter().collect())
    }

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
            let key = if let Some((date, n)) = crate::source::kitti::parse_drive_name(item) {
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

impl SplitRule {
    /// Checks a rule the user gave against the frames it splits: every drive, sequence or frame
    /// it names must be among them (a typo, `--val-drives 9999`, or sequences named for a raw
    /// root would otherwise leave val silently empty).
    pub fn check_against(&self, frames: &[FrameId]) -> Result<()> {
        let missing: Vec<String> = match self {
            SplitRule::Drives(set) => set
                .iter()
                .filter(|k| {
                    !frames
                        .iter()
                        .any(|id| id.dataset == DatasetKind::Raw && unit(id) == **k)
                })
                .map(|(date, n)| format!("drive {date}_{n:04}"))
                .collect(),
            SplitRule::Sequences(set) => set
                .iter()
                .filter(|&&n| {
                    !frames
                        .iter()
                        .any(|id| id.dataset == DatasetKind::Sequence && id.drive == n)
                })
                .map(|n| format!("sequence {n:02}"))
                .collect(),
            SplitRule::Frames(set) => set
                .iter()
                .filter(|id| frames.binary_search(id).is_err())
                .map(|id| format!("frame {id}"))
                .collect(),
            SplitRule::Random { .. } => Vec::new(),
        };
        match missing.first() {
            None => Ok(()),
            Some(first) => Err(Error::Config(format!(
                "the val split names {first}{}, not among the {} frames found: nothing would go to val for {}",
                match missing.len() {
                    1 => String::new(),
                    n => format!(" and {} more", n - 1),
                },
                frames.len(),
                if missing.len() == 1 { "it" } else { "them" },
            ))),
        }
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
    /// Frames without labels (SemanticKITTI test sequences, object `testing/`), sorted.
    pub test: Vec<FrameId>,
    /// Val drives (or sequences), by name.
    pub val_drives: Vec<String>,
}

/// The frames of one drive that `selection` picks: scans with at least one tracklet pose, or
/// every scan. Reads the tracklets file when there is one; never reads point data.
pub fn drive_frames(drive: &Drive, selection: FrameSelection) -> Result<Vec<u32>> {
    let scans = drive.scan_frames()?;
    if selection == FrameSelection::All || drive.dataset != DatasetKind::Raw {
        return Ok(scans);
    }
    let path = drive.tracklets_path();
    let t = if crate::fs::present(&path) {
        Tracklets::read(&path)?
    } else {
        Tracklets::default()
    };
    Ok(scans
        .into_iter()
        .filter(|f| selection.keeps(&t, *f))
        .collect())
}

pub use crate::rng::splitmix64;

/// The unit a frame is split with: its drive (raw, sequences), or itself (object set).
fn unit(id: &FrameId) -> DriveKey {
    match id.dataset {
        DatasetKind::Object => (String::new(), id.frame),
        _ => (id.date.clone(), id.drive),
    }
}

/// The val frames among `frames` (sorted ids) under `rule`.
pub fn assign(rule: &SplitRule, frames: &[FrameId]) -> Result<BTreeSet<FrameId>> {
    let is_val: Box<dyn Fn(&FrameId) -> bool> = match rule {
        SplitRule::Drives(set) => {
            Box::new(move |id| id.dataset == DatasetKind::Raw && set.contains(&unit(id)))
        }
        SplitRule::Sequences(set) => {
            Box::new(move |id| id.dataset == DatasetKind::Sequence && set.contains(&id.drive))
        }
        SplitRule::Frames(set) => Box::new(move |id| set.contains(id)),
        SplitRule::Random { fraction, seed } => {
            if !(0.0..=1.0).contains(fraction) {
                return Err(Error::Config(format!(
                    "val fraction {fraction} must be in [0, 1]"
                )));
            }
            let mut counts: std::collections::BTreeMap<DriveKey, usize> = Default::default();
            for id in frames {
                *counts.entry(unit(id)).or_default() += 1;
            }
            let units: Vec<(DriveKey, usize)> = counts.into_iter().collect();
            let mut order: Vec<usize> = (0..units.len()).collect();
            let mut state = *seed;
            for i in (1..order.len()).rev() {
                let j = (splitmix64(&mut state) % (i as u64 + 1)) as usize;
                order.swap(i, j);
            }
            let total: usize = units.iter().map(|(_, n)| n).sum();
            let target = fraction * total as f64;
            let mut taken = 0usize;
            let mut set = BTreeSet::new();
            for i in order {
                let n = units[i].1;
                // Take the unit when that brings val closer to the target.
                if ((taken + n) as f64 - target).abs() < (taken as f64 - target).abs() {
                    taken += n;
                    set.insert(units[i].0.clone());
                }
            }
            Box::new(move |id| set.contains(&unit(id)))
        }
    };
    Ok(frames.iter().filter(|id| is_val(id)).cloned().collect())
}

/// Builds the lists for the drives under `root` (any layout; `source` forces one) with `rule`,
/// or the layout's default ([`SplitRule::default_for`]).
pub fn split(
    root: &Path,
    selection: FrameSelection,
    rule: Option<&SplitRule>,
    source: Option<DatasetKind>,
) -> Result<SplitLists> {
    let drives = discover_as(root, source)?.drives;
    let default = SplitRule::default_for(drives.first().map_or(DatasetKind::Raw, |d| d.dataset));
    let rule = rule.unwrap_or(&default);
    let mut labelled = Vec::new();
    let mut out = SplitLists::default();
    for d in &drives {
        for f in drive_frames(d, selection)? {
            let id = d.frame_id(f);
            out.all.push(id.clone());
            if d.has_labels(f) {
                labelled.push(id);
            } else {
                out.test.push(id);
            }
        }
    }
    labelled.sort();
    if rule != &default {
        rule.check_against(&labelled)?;
    }
    let val = assign(rule, &labelled)?;
    for id in labelled {
        if val.contains(&id) {
            let name = id.drive_name();
            if id.dataset != DatasetKind::Object && !out.val_drives.contains(&name) {
                out.val_drives.push(name);
            }
            out.val.push(id);
        } else {
            out.train.push(id);
        }
    }
    out.all.sort();
    out.test.sort();
    Ok(out)
}
