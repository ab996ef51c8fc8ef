//! What `infer` runs on: one scan file, a dataset root (every frame with a scan), or a ROS 2
//! bag's point cloud topic (streamed); each scan one [`Unit`], read where it runs.

use std::path::{Path, PathBuf};

use super::frame::{self, Projected};
use super::model::Model;
use crate::error::{Error, Result};
use crate::plan::{FrameSelection, Plan};
use crate::source::bag::{Bag, BagMessage, Lost, Next, Topic};
use crate::source::kitti::{DatasetKind, FrameId};
use crate::source::pointcloud2::{self, PointCloud2};

/// The sequence number a bag's frames are given (`OUT/sequences/00/...`), as `unpack`'s default.
pub const BAG_SEQUENCE: u32 = 0;

/// An input, opened.
pub enum Input {
    /// One scan file.
    File(PathBuf),
    /// A dataset root, planned.
    Root(Box<Plan>),
    /// A bag's `PointCloud2` topic.
    Bag(Bag, Topic),
}

impl Input {
    /// Opens `path`: a bag (a `.mcap` file or a bag folder; `topic` names its point cloud topic,
    /// and the error lists them when it is missing or wrong), a scan file or a dataset root
    /// (`dataset` forcing its layout).
    pub fn open(path: &Path, topic: Option<&str>, dataset: Option<DatasetKind>) -> Result<Input> {
        if crate::source::bag::is_bag(path) {
            let bag = Bag::open(path)?;
            // A usage error (exit 2) that lists the topics; not `unpack`'s hint: infer reads bags.
            let topic = (bag.topic(topic, pointcloud2::TYPE_NAME))
                .map_err(|e| Error::Config(e.to_string()))?;
            return Ok(Input::Bag(bag, topic));
        }
        if let Some(t) = topic {
            return Err(Error::Config(format!(
                "--topic {t}: {} is not a ROS 2 bag (a .mcap file, or a folder with metadata.yaml)",
                path.display()
            )));
        }
        if std::fs::metadata(path)
            .map_err(|e| Error::io(path, e))?
            .is_file()
        {
            return Ok(Input::File(path.into()));
        }
        Ok(Input::Root(Box::new(Plan::build_as(
            path,
            FrameSelection::All,
            dataset,
        )?)))
    }

    /// The number of scans, when known before reading (a bag's topic: its message count).
    pub fn len(&self) -> u64 {
        match self {
            Input::File(_) => 1,
            Input::Root(p) => p.jobs.len() as u64,
            Input::Bag(_, t) => t.messages,
        }
    }

    /// Whether it holds no scan.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// Where a scan's outputs go.
#[derive(Debug, Clone)]
pub enum Target {
    /// A frame of a root or a bag: the layouts `score` reads.
    Frame(FrameId),
    /// A lone scan file: `OUT/<stem>.label`.
    Stem(String),
}

/// How a unit's scan is read.
pub enum Read {
    /// A file; with the root's drive and frame (its camera).
    File(PathBuf, Option<(usize, u32)>),
    /// A bag's message.
    Message(BagMessage),
}

/// One scan to run.
pub struct Unit {
    /// Its name in the summary (the frame id, the file, the bag's message).
    pub name: String,
    /// Where its outputs go.
    pub target: Target,
    /// When it was taken, nanoseconds (a bag's header stamp; a raw drive's timestamp).
    pub stamp_ns: Option<i64>,
    /// How it is read.
    pub read: Read,
}

/// A frame of the input that cannot be run, found before running it.
pub struct Skipped {
    /// Its name.
    pub name: String,
    /// Why.
    pub error: String,
}

/// The units of `input`, in order; a bag's are read as they are taken (its damaged chunks are
/// [`Skipped`], and a bag that breaks off ends with one).
pub fn units(input: &Input) -> Box<dyn Iterator<Item = std::result::Result<Unit, Skipped>> + '_> {
    match input {
        Input::File(p) => Box::new(std::iter::once(Ok(Unit {
            name: p.display().to_string(),
            target: Target::Stem(
                p.file_stem()
                    .map(|s| s.to_string_lossy().into_owned())
                    .unwrap_or_else(|| "scan".into()),
            ),
            stamp_ns: None,
            read: Read::File(p.clone(), None),
        }))),
        Input::Root(plan) => {
            let failed = plan.failed.iter().map(|f| {
                Err(Skipped {
                    name: f.what.to_string(),
                    error: f.error.clone(),
                })
            });
            let jobs = plan.jobs.iter().map(move |&(d, f)| {
                let dp = &plan.drives[d];
                let id = dp.drive.frame_id(f);
                Ok(Unit {
                    name: id.to_string(),
                    target: Target::Frame(id),
                    stamp_ns: dp.timestamp(f).map(|t| t.0),
                    read: Read::File(dp.drive.scan_path(f), Some((d, f))),
                })
            });
            Box::new(failed.chain(jobs))
        }
        Input::Bag(bag, topic) => Box::new(bag_units(bag, topic)),
    }
}

fn bag_units<'a>(
    bag: &'a Bag,
    topic: &'a Topic,
) -> impl Iterator<Item = std::result::Result<Unit, Skipped>> + 'a {
    let mut broken = false;
    bag.messages(topic)
        .map_while(move |m| {
            if broken {
                return None;
            }
            Some(match m {
                Ok(Next::Message(m)) => vec![Ok(Unit {
                    name: format!("{} message {}", topic.name, m.index),
                    target: Target::Frame(bag_frame(m.index)),
                    stamp_ns: None,
                    read: Read::Message(m),
                })],
                Ok(Next::Lost(lost)) => lost_units(&lost),
                Err(e) => {
                    broken = true;
                    vec![Err(Skipped {
                        name: bag.path.display().to_string(),
                        error: format!("the bag breaks off here: {e}"),
                    })]
                }
            })
        })
        .flatten()
}

/// The frame id of a bag's message `index`: frame `index` of sequence [`BAG_SEQUENCE`], as
/// `unpack` names its scan.
fn bag_frame(index: u64) -> FrameId {
    FrameId {
        dataset: DatasetKind::Sequence,
        date: String::new(),
        drive: BAG_SEQUENCE,
        frame: index as u32,
    }
}

fn lost_units(lost: &Lost) -> Vec<std::result::Result<Unit, Skipped>> {
    let what = format!("{}: {}", lost.file.display(), lost.damage.error);
    if lost.messages.is_empty() {
        return vec![Err(Skipped {
            name: lost.file.display().to_string(),
            error: format!("{what} (the bag's index names none of the topic's messages in it)"),
        })];
    }
    (lost.messages.iter())
        .map(|m| {
            Err(Skipped {
                name: format!("message {}", m.index),
                error: format!("lost with a damaged chunk: {what}"),
            })
        })
        .collect()
}

/// Reads and projects a unit's scan with `model`'s map; returns the scan's header stamp when it
/// has one (a bag's message).
pub fn project(model: &Model, input: &Input, read: &Read) -> Result<(Projected, Option<i64>)> {
    match read {
        Read::File(path, drive_frame) => {
            let camera = match (input, drive_frame) {
                (Input::Root(plan), Some((d, f))) => Some((&plan.drives[*d], *f)),
                _ => None,
            };
            Ok((frame::project(model, path, camera)?, None))
        }
        Read::Message(m) => {
            let what = m.file.join(format!("message {}", m.index));
            let msg = PointCloud2::decode(&m.data, &what)?;
            // The bag reader's cloud: the points of the PCD `unpack` writes of it (tested).
            let scan = msg.cloud(&what)?;
            Ok((
                frame::project_points(model, scan, &what)?,
                Some(msg.stamp.nanos()),
            ))
        }
    }
}
