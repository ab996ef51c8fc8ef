//! A ROS 2 bag's point clouds -> a sequence folder that every command reads: one bag is one
//! sequence, one `PointCloud2` message one frame (`sequences/NN/velodyne/<frame6>.pcd`, every
//! field kept, repacked little-endian as PCD stores it), its header stamp kept in `times.txt`
//! (seconds after the first frame, exact) and the first stamp in `unpack.json`.
//!
//! The bag is streamed: messages are read, converted and written a small batch at a time, so
//! memory stays flat however large the bag. A message that does not decode fails its frame only
//! (no file; named in the summary) and the rest goes on.

use std::path::{Path, PathBuf};

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::{UnpackFailure, UnpackReport};
use crate::error::{Error, Result};
use crate::format::{atomic_write, create_dir, Durability};
use crate::source::bag::{Bag, BagMessage, Lost, Next, Topic};
use crate::source::kitti::sequence;
use crate::source::pcd;
use crate::source::pointcloud2::{PointCloud2, Stamp};
use crate::source::unpacked::BAG_MARKER;

/// What to unpack and where to.
#[derive(Debug, Clone)]
pub struct UnpackOptions {
    /// The root the sequence folder goes under (`ROOT/sequences/NN/`).
    pub out: PathBuf,
    /// The sequence number (`NN`).
    pub sequence: u32,
    /// Replace the scans of an earlier unpack (else a non-empty sequence is refused).
    pub overwrite: bool,
    /// Whether each file is flushed to the device before its rename.
    pub durability: Durability,
    /// The sensor's frame (`velodyne`), to find its pose in the clouds' frame through the bag's
    /// `/tf_static` ([`UnpackSummary::sensor_pose`]).
    pub sensor_frame: Option<String>,
}

/// Where the sensor sits in the frame its clouds are written in, from the bag's static
/// transforms: what `convert --sensor-pose` takes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FoundPose {
    /// The sensor's frame.
    pub sensor_frame: String,
    /// The clouds' frame (`header.frame_id`).
    pub points_frame: String,
    /// The pose: `--sensor-pose` of its text.
    pub pose: crate::sensor::SensorPose,
}

/// What an unpack did, written to `sequences/NN/unpack.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct UnpackSummary {
    /// kitti2pgm's version.
    pub version: String,
    /// The bag, as given.
    pub bag: PathBuf,
    /// The topic.
    pub topic: String,
    /// The sequence folder written.
    pub sequence_dir: PathBuf,
    /// Messages read on the topic.
    pub messages: u64,
    /// Frames written.
    pub frames_written: u64,
    /// Points in the frames written.
    pub points: u64,
    /// The first frame's header stamp (`sec.nanosec`), the zero of `times.txt`.
    pub first_stamp: Option<String>,
    /// The `header.frame_id`s seen (the frames the points are in).
    pub frame_ids: Vec<String>,
    /// The point fields of the first frame written.
    pub fields: Vec<String>,
    /// Frames whose `times.txt` line is the recorder's log time (their header did not decode).
    pub log_time_frames: Vec<u64>,
    /// Frames that failed.
    pub failures: Vec<UnpackFailure>,
    /// Scans of an earlier unpack past the last frame, removed (`--overwrite`).
    pub removed_stale: u64,
    /// The sensor's pose in the clouds' frame, when its frame was named.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sensor_pose: Option<FoundPose>,
    /// Messages on the topic of other types than `sensor_msgs/msg/PointCloud2`, passed over.
    #[serde(default)]
    pub skipped_other_types: u64,
    /// Damaged chunks or records passed over that the bag's index says held none of the
    /// topic's frames (or for which it has no index): each named with its place in its file.
    #[serde(default)]
    pub damaged: Vec<String>,
    /// False from the unpack's first write until its last: a sequence whose `unpack.json` says
    /// false is an interrupted unpack, which the readers refuse
    /// ([`crate::source::unpacked::refuse_unfinished`]). Summaries of earlier versions, written
    /// at the end only, are complete.
    #[serde(default = "crate::source::unpacked::complete_by_default")]
    pub complete: bool,
}

impl UnpackReport for UnpackSummary {
    fn frames_written(&self) -> u64 {
        self.frames_written
    }
    fn failures(&self) -> &[UnpackFailure] {
        &self.failures
    }
    fn damaged(&self) -> &[String] {
        &self.damaged
    }
}

/// One decoded frame, ready to write.
struct Unpacked {
    stamp: Stamp,
    frame_id: String,
    fields: Vec<String>,
    points: u64,
}

/// The sequence folder and its scan folder for `opts`.
fn sequence_dirs(opts: &UnpackOptions) -> (PathBuf, PathBuf) {
    let seq = sequence::sequence_dir(&opts.out, opts.sequence);
    let scans = seq.join(sequence::SCANS);
    (seq, scans)
}

/// The `.pcd` scans already in `dir`.
fn existing_scans(dir: &Path) -> Result<Vec<PathBuf>> {
    if !dir.exists() {
        return Ok(Vec::new());
    }
    Ok(crate::fs::sorted_dir(dir)?
        .into_iter()
        .filter(|p| p.extension().is_some_and(|e| e == "pcd" || e == "bin"))
        .collect())
}

fn scan_path(scans: &Path, frame: u64) -> PathBuf {
    scans.join(sequence::frame_file(frame, "pcd"))
}

/// Decodes one message and writes its scan.
fn unpack_one(m: &BagMessage, scans: &Path, d: Durability) -> Result<Unpacked> {
    let what = m.file.join(format!("message {}", m.index));
    let msg = PointCloud2::decode(&m.data, &what)?;
    let (layout, records) = msg.packed();
    let path = scan_path(scans, m.index);
    atomic_write(
        &path,
        &pcd::encode(&layout, msg.width, msg.height, &records),
        d,
    )?;
    Ok(Unpacked {
        points: msg.points() as u64,
        stamp: msg.stamp,
        frame_id: msg.frame_id,
        fields: layout.fields.iter().map(|f| f.name.clone()).collect(),
    })
}

/// Messages converted at a time (memory holds this many messages).
const BATCH: usize = 8;

/// Unpacks the bag's `PointCloud2` topic (as [`Bag::topic`] found it, `TYPE_NAME`) into a
/// sequence folder. `progress` hears of every frame done (its index). Errors: an unreadable bag,
/// a root another run writes into (its lock), or a non-empty sequence without `overwrite`; a
/// frame that fails, or is lost with a damaged chunk, is in the summary's `failures`, and a bag
/// that breaks off partway keeps the frames read before (its error is the last failure). The
/// sequence's `unpack.json` says `complete: false` until the end.
pub fn unpack(
    bag: &Bag,
    topic: &Topic,
    opts: &UnpackOptions,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<UnpackSummary> {
    let (seq, scans) = sequence_dirs(opts);
    let _lock = super::begin(&opts.out)?;
    let before = existing_scans(&scans)?;
    super::refuse_earlier(
        &scans,
        before.len(),
        opts.overwrite,
        "scans; unpack into another sequence (--sequence) or replace them (--overwrite)",
    )?;
    // The mark first, then the scans: no moment when scans stand without it.
    create_dir(&seq)?;
    let mut s = started(bag, topic, &seq)?;
    write_summary(&s, &seq, opts.durability)?;
    create_dir(&scans)?;
    let mut stamps: Vec<i64> = Vec::new();
    let mut stream = bag.messages(topic);
    loop {
        let mut batch = Vec::with_capacity(BATCH);
        let mut broke = None;
        for m in stream.by_ref().take(BATCH) {
            match m {
                Ok(m) => batch.push(m),
                Err(e) => broke = Some(e),
            }
        }
        if batch.is_empty() && broke.is_none() {
            break;
        }
        let done: Vec<Option<Result<Unpacked>>> = batch
            .par_iter()
            .map(|m| {
                let Next::Message(m) = m else { return None };
                let r = unpack_one(m, &scans, opts.durability);
                progress(m.index);
                Some(r)
            })
            .collect();
        for (m, r) in batch.into_iter().zip(done) {
            match (m, r) {
                (Next::Message(m), Some(r)) => record(&mut s, &mut stamps, &m, r),
                (Next::Lost(lost), _) => record_lost(&mut s, &mut stamps, lost, progress),
                (Next::Message(_), None) => unreachable!("every message is unpacked"),
            }
        }
        if let Some(e) = broke {
            s.failures.push(UnpackFailure {
                scene: None,
                frame: s.messages,
                error: format!("the bag breaks off here: {e}"),
            });
            break;
        }
    }
    // The frames, times.txt and unpack.json are kept when the pose cannot be found.
    let located = match (&opts.sensor_frame, s.frame_ids.first()) {
        (Some(sensor), Some(points)) => locate_sensor(bag, sensor, points, &s.frame_ids).map(Some),
        _ => Ok(None),
    };
    s.sensor_pose = located.as_ref().ok().cloned().flatten();
    finish(&mut s, &stamps, (&seq, &scans), &before, opts.durability)?;
    located.map(|_| s)
}

/// The summary of an unpack that begins (`complete: false`).
fn started(bag: &Bag, topic: &Topic, seq: &Path) -> Result<UnpackSummary> {
    Ok(UnpackSummary {
        version: env!("CARGO_PKG_VERSION").into(),
        bag: bag.path.clone(),
        topic: topic.name.clone(),
        sequence_dir: seq.into(),
        messages: 0,
        frames_written: 0,
        points: 0,
        first_stamp: None,
        frame_ids: Vec::new(),
        fields: Vec::new(),
        log_time_frames: Vec::new(),
        failures: Vec::new(),
        removed_stale: 0,
        sensor_pose: None,
        skipped_other_types: bag.other_types_on(&topic.name, &topic.type_name)?,
        damaged: Vec::new(),
        complete: false,
    })
}

/// Writes the sequence's `unpack.json`.
fn write_summary(s: &UnpackSummary, seq: &Path, durability: Durability) -> Result<()> {
    super::write_mark(s, seq, BAG_MARKER, durability)
}

/// Adds the frames lost with a damaged chunk to the summary (failures, their log times in
/// `times.txt`), or the damage alone when the bag's index names none of the topic's messages in
/// it.
fn record_lost(
    s: &mut UnpackSummary,
    stamps: &mut Vec<i64>,
    lost: Lost,
    progress: &(dyn Fn(u64) + Sync),
) {
    let what = format!("{}: {}", lost.file.display(), lost.damage.error);
    if lost.messages.is_empty() {
        s.damaged.push(format!(
            "{what} (the bag's message index names none of {}'s messages in it)",
            s.topic
        ));
        return;
    }
    for m in lost.messages {
        s.messages += 1;
        s.failures.push(UnpackFailure {
            scene: None,
            frame: m.index,
            error: format!("lost with a damaged chunk: {what}"),
        });
        s.log_time_frames.push(m.index);
        stamps.push(i64::try_from(m.log_time).unwrap_or(i64::MAX));
        progress(m.index);
    }
}

/// The pose of frame `sensor` in the clouds' frame `points` through the bag's `/tf_static`; an
/// error (naming the frames the transforms know) without a chain, or when the clouds come in
/// several frames.
fn locate_sensor(bag: &Bag, sensor: &str, points: &str, frame_ids: &[String]) -> Result<FoundPose> {
    let input = |message: String| Error::Input {
        path: bag.path.clone(),
        message,
    };
    if frame_ids.len() > 1 {
        return Err(input(format!(
            "its clouds come in several frames ({}): one sensor pose cannot serve them",
            frame_ids.join(", ")
        )));
    }
    let transforms = crate::source::tf::read_static(bag)?;
    let pose = crate::source::tf::sensor_pose_in(&transforms, sensor, points).ok_or_else(|| {
        let mut frames: Vec<&str> = (transforms.iter())
            .flat_map(|t| [t.parent.as_str(), t.child.as_str()])
            .collect();
        frames.sort_unstable();
        frames.dedup();
        input(format!(
            "no static transform joins {sensor} to the clouds' frame {points} (/tf_static \
             knows: {})",
            if frames.is_empty() {
                "nothing".to_string()
            } else {
                frames.join(", ")
            }
        ))
    })?;
    Ok(FoundPose {
        sensor_frame: sensor.into(),
        points_frame: points.into(),
        pose: crate::sensor::SensorPose::from_isometry(&pose),
    })
}

/// Adds one frame's outcome to the summary and its stamp (nanoseconds) to `stamps`.
fn record(s: &mut UnpackSummary, stamps: &mut Vec<i64>, m: &BagMessage, r: Result<Unpacked>) {
    s.messages += 1;
    match r {
        Ok(u) => {
            s.frames_written += 1;
            s.points += u.points;
            if s.first_stamp.is_none() {
                s.first_stamp = Some(u.stamp.to_string());
            }
            if s.fields.is_empty() {
                s.fields = u.fields;
            }
            if !s.frame_ids.contains(&u.frame_id) {
                s.frame_ids.push(u.frame_id);
            }
            stamps.push(u.stamp.nanos());
        }
        Err(e) => {
            s.failures.push(UnpackFailure {
                scene: None,
                frame: m.index,
                error: e.to_string(),
            });
            s.log_time_frames.push(m.index);
            stamps.push(i64::try_from(m.log_time).unwrap_or(i64::MAX));
        }
    }
}

/// Writes `times.txt` and `unpack.json`; removes the scans of an earlier unpack past the last
/// frame.
fn finish(
    s: &mut UnpackSummary,
    stamps: &[i64],
    (seq, scans): (&Path, &Path),
    before: &[PathBuf],
    durability: Durability,
) -> Result<()> {
    let failed: std::collections::BTreeSet<u64> = s.failures.iter().map(|f| f.frame).collect();
    // A scan this unpack wrote: a frame it read and did not fail, at that frame's name.
    let written = |old: &Path| {
        let frame = old
            .file_stem()
            .and_then(|n| n.to_str())
            .and_then(|n| n.parse().ok());
        frame.is_some_and(|i: u64| {
            i < s.messages && !failed.contains(&i) && scan_path(scans, i) == old
        })
    };
    s.removed_stale += super::remove_stale(before, written)?;
    super::write_times(seq, stamps, durability)?;
    s.complete = true;
    write_summary(s, seq, durability)
}
