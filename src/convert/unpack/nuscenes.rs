//! A nuScenes root -> sequence folders that every command reads: one scene is one sequence
//! (`scene-0061` -> `sequences/61`), one LIDAR_TOP keyframe one frame, in time order:
//! `velodyne/<frame6>.pcd.bin` (the scan itself, hard-linked where the file system allows, else
//! copied), `labels/<frame6>.label` (its nuScenes-lidarseg general classes as raw ids, u32 per
//! point; convert with `--class-map nuscenes` for the benchmark's 16 classes), `times.txt`
//! (seconds after the scene's first keyframe) and `nuscenes.json` (the scene and the
//! `sample_data` token of every frame, to carry predictions back to the benchmark's files).

use std::path::{Path, PathBuf};

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::{UnpackFailure, UnpackReport};
use crate::error::{Error, Result};
use crate::format::{atomic_write, create_dir, Durability};
use crate::source::kitti::sequence;
use crate::source::nuscenes::{Keyframe, NuScenes, Scene};
use crate::source::unpacked::NUSCENES_MARKER;

/// What to unpack and where to.
#[derive(Debug, Clone)]
pub struct NuScenesOptions {
    /// The root the sequence folders go under (`ROOT/sequences/<scene number>/`).
    pub out: PathBuf,
    /// Only these scenes (by name); all when empty.
    pub scenes: Vec<String>,
    /// Replace the frames of an earlier unpack (else a non-empty sequence is refused).
    pub overwrite: bool,
    /// Whether each file is flushed to the device before its rename.
    pub durability: Durability,
}

/// One scene as unpacked, written to its `sequences/NN/nuscenes.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SceneIndex {
    /// The scene's name.
    pub scene: String,
    /// The nuScenes version read.
    pub version: String,
    /// The sequence folder.
    pub sequence_dir: PathBuf,
    /// The `sample_data` token of every frame, in frame order.
    pub tokens: Vec<String>,
    /// Its first keyframe's timestamp (microseconds), the zero of `times.txt`.
    pub first_timestamp_us: Option<i64>,
    /// False from the scene's first write until its last (an interrupted unpack: the readers
    /// refuse the sequence, [`crate::source::unpacked::refuse_unfinished`]); indexes of earlier
    /// versions, written at the end only, are complete.
    #[serde(default = "crate::source::unpacked::complete_by_default")]
    pub complete: bool,
}

/// What an unpack of a nuScenes root did.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NuScenesSummary {
    /// kitti2pgm's version.
    pub version: String,
    /// The nuScenes root.
    pub root: PathBuf,
    /// Its version read.
    pub nuscenes_version: String,
    /// The scenes unpacked.
    pub scenes: Vec<SceneIndex>,
    /// Frames written.
    pub frames_written: u64,
    /// Frames written with their lidarseg labels.
    pub labelled_frames: u64,
    /// Points in the frames written.
    pub points: u64,
    /// Frames that failed (each naming its scene).
    pub failures: Vec<UnpackFailure>,
    /// Files of an earlier unpack no frame wrote again, removed (`overwrite`).
    pub removed_stale: u64,
}

impl UnpackReport for NuScenesSummary {
    fn frames_written(&self) -> u64 {
        self.frames_written
    }
    fn failures(&self) -> &[UnpackFailure] {
        &self.failures
    }
}

/// The sequence folder of scene `s` under `out`.
pub fn sequence_dir(out: &Path, s: &Scene) -> PathBuf {
    sequence::sequence_dir(out, s.number)
}

/// The scenes `opts` asks for (an unknown name is an error listing how many there are).
fn chosen<'a>(ds: &'a NuScenes, opts: &NuScenesOptions) -> Result<Vec<&'a Scene>> {
    if opts.scenes.is_empty() {
        return Ok(ds.scenes.iter().collect());
    }
    opts.scenes
        .iter()
        .map(|name| {
            ds.scenes
                .iter()
                .find(|s| &s.name == name)
                .ok_or_else(|| Error::Input {
                    path: ds.root.join(&ds.version),
                    message: format!(
                        "has no scene {name:?} ({} scenes, {} to {})",
                        ds.scenes.len(),
                        ds.scenes.first().map_or("", |s| &s.name),
                        ds.scenes.last().map_or("", |s| &s.name)
                    ),
                })
        })
        .collect()
}

/// The files of an earlier unpack in a sequence folder (scans and labels).
fn existing(seq: &Path) -> Result<Vec<PathBuf>> {
    let mut out = Vec::new();
    for sub in [sequence::SCANS, sequence::LABELS] {
        let dir = seq.join(sub);
        if dir.exists() {
            out.extend(crate::fs::sorted_dir(&dir)?);
        }
    }
    Ok(out)
}

/// Unpacks the scenes of `ds` that `opts` asks for. `progress` hears of every frame done.
/// Errors: an unknown scene, a root another run writes into (its lock), or a non-empty sequence
/// without `overwrite` (before anything is written); a frame that fails (its scan missing, its
/// labels not one per point) is in the summary's `failures` and the rest goes on. Each scene's
/// `nuscenes.json` says `complete: false` from its first write until its old files are gone and
/// its new ones written: an overwrite leaves what a fresh unpack leaves.
pub fn unpack_nuscenes(
    ds: &NuScenes,
    opts: &NuScenesOptions,
    progress: &(dyn Fn() + Sync),
) -> Result<NuScenesSummary> {
    let scenes = chosen(ds, opts)?;
    let _lock = super::begin(&opts.out)?;
    let mut before = Vec::new();
    for s in &scenes {
        let old = existing(&sequence_dir(&opts.out, s))?;
        super::refuse_earlier(
            &sequence_dir(&opts.out, s),
            old.len(),
            opts.overwrite,
            "files of an earlier unpack; replace them (--overwrite)",
        )?;
        before.push(old);
    }
    let mut summary = NuScenesSummary {
        version: env!("CARGO_PKG_VERSION").into(),
        root: ds.root.clone(),
        nuscenes_version: ds.version.clone(),
        scenes: Vec::new(),
        frames_written: 0,
        labelled_frames: 0,
        points: 0,
        failures: Vec::new(),
        removed_stale: 0,
    };
    for (s, old) in scenes.into_iter().zip(before) {
        let index = unpack_scene(ds, s, &old, opts, &mut summary, progress)?;
        summary.scenes.push(index);
    }
    Ok(summary)
}

/// One scene: marked unfinished, its frames written, the files of an earlier unpack that no
/// frame wrote again (`old`) removed, then `times.txt` and its finished index.
fn unpack_scene(
    ds: &NuScenes,
    s: &Scene,
    old: &[PathBuf],
    opts: &NuScenesOptions,
    summary: &mut NuScenesSummary,
    progress: &(dyn Fn() + Sync),
) -> Result<SceneIndex> {
    let seq = sequence_dir(&opts.out, s);
    create_dir(&seq)?;
    let mut index = scene_index(ds, s, &seq);
    write_index(&index, &seq, opts.durability)?;
    create_dir(&seq.join(sequence::SCANS))?;
    if s.keyframes.iter().any(|k| k.labels.is_some()) {
        create_dir(&seq.join(sequence::LABELS))?;
    }
    let done: Vec<Result<Written>> = s
        .keyframes
        .par_iter()
        .enumerate()
        .map(|(i, k)| {
            let r = unpack_frame(k, &seq, i, opts.durability);
            progress();
            r
        })
        .collect();
    let mut written = std::collections::HashSet::new();
    for (i, r) in done.into_iter().enumerate() {
        match r {
            Ok(w) => {
                summary.frames_written += 1;
                summary.points += w.points;
                summary.labelled_frames += w.label.is_some() as u64;
                written.insert(w.scan);
                written.extend(w.label);
            }
            Err(e) => summary.failures.push(UnpackFailure {
                scene: Some(s.name.clone()),
                frame: i as u64,
                error: e.to_string(),
            }),
        }
    }
    summary.removed_stale += super::remove_stale(old, |p| written.contains(p))?;
    let stamps: Vec<i64> = (s.keyframes.iter())
        .map(|k| k.timestamp_us * 1000)
        .collect();
    super::write_times(&seq, &stamps, opts.durability)?;
    index.complete = true;
    write_index(&index, &seq, opts.durability)?;
    Ok(index)
}

/// The files one frame wrote.
struct Written {
    scan: PathBuf,
    label: Option<PathBuf>,
    points: u64,
}

/// One keyframe: its scan linked (or copied) in, its labels checked against it and written.
fn unpack_frame(k: &Keyframe, seq: &Path, i: usize, d: Durability) -> Result<Written> {
    let meta = crate::fs::regular(&k.scan)?;
    let step = crate::source::nuscenes::point_layout().step as u64;
    if meta.len() % step != 0 {
        return Err(Error::format(
            &k.scan,
            format!(
                "{} bytes: not whole nuScenes points of {step} bytes",
                meta.len()
            ),
        ));
    }
    let points = meta.len() / step;
    // The labels are checked before anything is written: a scan never lands without the
    // labels it has.
    let classes = match &k.labels {
        Some(path) => {
            let classes = crate::fs::read(path, crate::fs::Limit::Data)?;
            if classes.len() as u64 != points {
                return Err(Error::LabelCount {
                    path: path.clone(),
                    labels: classes.len(),
                    scan: k.scan.clone(),
                    points: points as usize,
                    note: Some("a nuScenes-lidarseg file holds one uint8 per point"),
                });
            }
            Some(classes)
        }
        None => None,
    };
    let scan = (seq.join(sequence::SCANS)).join(sequence::frame_file(i as u64, "pcd.bin"));
    link_or_copy(&k.scan, &scan, d)?;
    let label = match classes {
        Some(classes) => {
            let raw: Vec<u8> = classes
                .iter()
                .flat_map(|&c| u32::from(c).to_le_bytes())
                .collect();
            let out = (seq.join(sequence::LABELS)).join(sequence::frame_file(i as u64, "label"));
            atomic_write(&out, &raw, d)?;
            Some(out)
        }
        None => None,
    };
    Ok(Written {
        scan,
        label,
        points,
    })
}

/// `to` becomes `from`'s content: a hard link where the file system allows, else a copy
/// (written atomically). A `to` that already is `from` (a link of an earlier unpack) stays: the
/// rename of a link onto another link of the same file does nothing, and would leave the
/// temporary name behind.
fn link_or_copy(from: &Path, to: &Path, d: Durability) -> Result<()> {
    if crate::fs::overlap(to, from) == Some(crate::fs::Overlap::Is) {
        return Ok(());
    }
    let tmp = to.with_extension("bin.link-tmp");
    crate::fs::remove_if_there(&tmp)?;
    if std::fs::hard_link(from, &tmp).is_ok() {
        return std::fs::rename(&tmp, to).map_err(|e| {
            let _ = std::fs::remove_file(&tmp);
            Error::io(to, e)
        });
    }
    atomic_write(to, &crate::fs::read(from, crate::fs::Limit::Data)?, d)
}

/// The index of scene `s` unpacked into `seq`, not yet complete.
fn scene_index(ds: &NuScenes, s: &Scene, seq: &Path) -> SceneIndex {
    SceneIndex {
        scene: s.name.clone(),
        version: ds.version.clone(),
        sequence_dir: seq.to_path_buf(),
        tokens: s.keyframes.iter().map(|k| k.token.clone()).collect(),
        first_timestamp_us: s.keyframes.first().map(|k| k.timestamp_us),
        complete: false,
    }
}

/// Writes a scene's `nuscenes.json`.
fn write_index(index: &SceneIndex, seq: &Path, d: Durability) -> Result<()> {
    super::write_mark(index, seq, NUSCENES_MARKER, d)
}
