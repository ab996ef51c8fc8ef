//! ROS 2 bags stored as MCAP: a bag directory (rosbag2's `metadata.yaml` naming its `.mcap`
//! files, read in that order) or a bare `.mcap` file. Messages are read where they lie in the
//! mapped file ([`records`]: an uncompressed chunk's messages are not copied, a compressed chunk
//! is decompressed whole, the pages passed are given back), so memory holds one chunk and one
//! message whatever the bag's size; the topic list comes from the summary section, or from one
//! pass over the file when it has none (an unfinished recording).

use std::collections::{BTreeMap, HashMap};
use std::fs::File;
use std::io::{Read, Seek};
use std::path::{Path, PathBuf};

use mcap::records::Record;
use mcap::sans_io::summary_reader::{SummaryReadEvent, SummaryReader};

pub use records::Damage;
use records::{Item, Records};

use crate::error::{Error, Result};
use crate::fs::{self, Limit};

mod messages;
mod records;

pub use messages::{Lost, LostMessage, Messages, Next};

/// A topic of a bag.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Topic {
    /// Its name (`/points`).
    pub name: String,
    /// Its message type (`sensor_msgs/msg/PointCloud2`).
    pub type_name: String,
    /// Its serialisation (`cdr`).
    pub encoding: String,
    /// Messages on it, over all the bag's files.
    pub messages: u64,
}

/// One message as read, borrowed from the reader's buffer (see [`Messages::next_with`]).
#[derive(Debug, Clone, Copy)]
pub struct MessageRef<'a> {
    /// Its place among the topic's messages, from 0.
    pub index: u64,
    /// When the recorder received it (nanoseconds).
    pub log_time: u64,
    /// The serialised message.
    pub data: &'a [u8],
    /// The `.mcap` file it came from.
    pub file: &'a Path,
}

impl MessageRef<'_> {
    /// The message copied out of the reader.
    pub fn to_owned(&self) -> BagMessage {
        BagMessage {
            index: self.index,
            log_time: self.log_time,
            data: self.data.to_vec(),
            file: self.file.into(),
        }
    }
}

/// One message as read.
#[derive(Debug, Clone)]
pub struct BagMessage {
    /// Its place among the topic's messages, from 0.
    pub index: u64,
    /// When the recorder received it (nanoseconds).
    pub log_time: u64,
    /// The serialised message.
    pub data: Vec<u8>,
    /// The `.mcap` file it came from.
    pub file: PathBuf,
}

/// A ROS 2 bag: its `.mcap` files in order.
#[derive(Debug, Clone)]
pub struct Bag {
    /// The path given (a directory or a `.mcap` file).
    pub path: PathBuf,
    /// Its MCAP files, in order.
    pub files: Vec<PathBuf>,
    /// Its topics, once read ([`Bag::topics`]).
    topics: std::sync::OnceLock<Vec<Topic>>,
}

#[derive(serde::Deserialize)]
struct Metadata {
    rosbag2_bagfile_information: Info,
}

#[derive(serde::Deserialize)]
struct Info {
    storage_identifier: String,
    relative_file_paths: Vec<String>,
    /// `""`, `FILE` (each file compressed whole) or `MESSAGE` (each message compressed).
    #[serde(default)]
    compression_mode: String,
    #[serde(default)]
    compression_format: String,
}

/// Whether `path` is a ROS 2 bag kitti2pgm reads: a `.mcap` file, or a bag directory (with
/// `metadata.yaml`).
pub fn is_bag(path: &Path) -> bool {
    (path.is_file() && path.extension().is_some_and(|e| e == "mcap"))
        || path.join("metadata.yaml").is_file()
}

/// A bag in a storage kitti2pgm does not read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Foreign {
    /// ROS 1 (`.bag`).
    Ros1,
    /// rosbag2's sqlite3 storage (`.db3`).
    Sqlite3,
}

/// Which foreign bag `path` is, by its extension (a file).
pub fn foreign_storage(path: &Path) -> Option<Foreign> {
    match path.extension()?.to_str()? {
        "bag" if path.is_file() => Some(Foreign::Ros1),
        "db3" if path.is_file() => Some(Foreign::Sqlite3),
        _ => None,
    }
}

impl Bag {
    /// Opens a bag directory (with `metadata.yaml`) or a `.mcap` file.
    pub fn open(path: &Path) -> Result<Bag> {
        if !path.is_dir() {
            if path.extension().is_some_and(|e| e == "db3") {
                return Err(Error::format(
                    path,
                    "a rosbag2 sqlite3 file: kitti2pgm reads MCAP bags; convert it first \
                     (`ros2 bag convert`, or `rosbags-convert --src BAG --dst OUT --dst-storage \
                     mcap`)",
                ));
            }
            fs::open(path)?;
            return Ok(Bag {
                path: path.into(),
                files: vec![path.into()],
                topics: Default::default(),
            });
        }
        let meta = path.join("metadata.yaml");
        if !meta.exists() {
            return Err(Error::Input {
                path: path.into(),
                message: "a directory without metadata.yaml: not a ROS 2 bag (give the bag \
                          directory or one of its .mcap files)"
                    .into(),
            });
        }
        let text = fs::read_text(&meta, Limit::Text)?;
        let info = serde_norway::from_str::<Metadata>(&text)
            .map_err(|e| Error::format(&meta, format!("not rosbag2 metadata: {e}")))?
            .rosbag2_bagfile_information;
        if info.storage_identifier != "mcap" {
            return Err(Error::format(
                &meta,
                format!(
                    "storage {:?}: kitti2pgm reads MCAP bags; convert this one first \
                     (`ros2 bag convert`, or `rosbags-convert --dst-storage mcap`)",
                    info.storage_identifier
                ),
            ));
        }
        if !info.compression_mode.is_empty() && !info.compression_mode.eq_ignore_ascii_case("none")
        {
            return Err(Error::format(
                &meta,
                format!(
                    "compressed by rosbag2 ({} mode, {}): decompress it first (`ros2 bag \
                     decompress`, or `rosbags-convert --src BAG --dst OUT --dst-storage mcap`); \
                     MCAP's own chunk compression (zstd, lz4) is read as it is",
                    info.compression_mode, info.compression_format
                ),
            ));
        }
        if info.relative_file_paths.is_empty() {
            return Err(Error::format(&meta, "relative_file_paths lists no file"));
        }
        let mut seen = std::collections::HashSet::new();
        if let Some(twice) = (info.relative_file_paths.iter()).find(|f| !seen.insert(*f)) {
            return Err(Error::format(
                &meta,
                format!(
                    "relative_file_paths lists {twice} twice: its messages would be read twice"
                ),
            ));
        }
        Ok(Bag {
            path: path.into(),
            files: info
                .relative_file_paths
                .iter()
                .map(|f| path.join(f))
                .collect(),
            topics: Default::default(),
        })
    }

    /// The bag's topics with their message counts over all its files: one entry a topic and
    /// message type (MCAP's channels: one topic can carry messages of several types), sorted by
    /// name and type. Read once (from the summaries, or by a pass over a file without one) and
    /// kept: finding a topic, its other types and the static transforms ask again.
    pub fn topics(&self) -> Result<Vec<Topic>> {
        if let Some(known) = self.topics.get() {
            return Ok(known.clone());
        }
        let mut all: BTreeMap<(String, String), Topic> = BTreeMap::new();
        for file in &self.files {
            for t in file_topics(file)? {
                let key = (t.name.clone(), t.type_name.clone());
                match all.get_mut(&key) {
                    Some(seen) => seen.messages += t.messages,
                    None => {
                        all.insert(key, t);
                    }
                }
            }
        }
        Ok(self
            .topics
            .get_or_init(|| all.into_values().collect())
            .clone())
    }

    /// Messages on the topic `name` of other types than `type_name` (left out when reading it).
    pub fn other_types_on(&self, name: &str, type_name: &str) -> Result<u64> {
        Ok((self.topics()?.iter())
            .filter(|t| t.name == name && t.type_name != type_name)
            .map(|t| t.messages)
            .sum())
    }

    /// The topic named `topic`, checked to be of `type_name`; the error lists the topics of that
    /// type (and their message counts) when it is missing or of another type.
    pub fn topic(&self, topic: Option<&str>, type_name: &str) -> Result<Topic> {
        let topics = self.topics()?;
        let of_type: Vec<String> = topics
            .iter()
            .filter(|t| t.type_name == type_name)
            .map(|t| format!("{} ({} message{})", t.name, t.messages, plural(t.messages)))
            .collect();
        let listed = if of_type.is_empty() {
            format!("the bag has no {type_name} topic")
        } else {
            format!("{type_name} topics: {}", of_type.join(", "))
        };
        let fail = |m: String| Error::Input {
            path: self.path.clone(),
            message: m,
        };
        let Some(name) = topic else {
            return Err(fail(format!("no topic given (--topic); {listed}")));
        };
        let on_topic: Vec<&Topic> = topics.iter().filter(|t| t.name == name).collect();
        if on_topic.is_empty() {
            return Err(fail(format!("no topic {name}; {listed}")));
        }
        let Some(t) = on_topic.iter().find(|t| t.type_name == type_name) else {
            let types: Vec<&str> = on_topic.iter().map(|t| t.type_name.as_str()).collect();
            return Err(fail(format!(
                "{name} is {}, not {type_name}; {listed}",
                types.join(" and ")
            )));
        };
        if t.encoding != "cdr" {
            return Err(fail(format!(
                "{name} is serialised as {:?}, not cdr",
                t.encoding
            )));
        }
        Ok((*t).clone())
    }

    /// The messages of `topic` (its name and type: the messages of other types on the same
    /// topic are passed over), streamed in file order.
    pub fn messages(&self, topic: &Topic) -> Messages {
        Messages::new(self.files.clone(), topic)
    }
}

fn plural(n: u64) -> &'static str {
    if n == 1 {
        ""
    } else {
        "s"
    }
}

/// Reads `n` bytes of `file` into `buf` as the sans-io readers ask.
fn fill(file: &mut File, buf: &mut [u8], path: &Path) -> Result<usize> {
    file.read(buf).map_err(|e| Error::io(path, e))
}

/// A file's topics from its summary, or from one pass over its records when it has none.
fn file_topics(path: &Path) -> Result<Vec<Topic>> {
    let summary = match read_summary(path)? {
        Some(s) => s,
        // No footer or summary: an unfinished recording (or not MCAP: the scan says).
        None => return scanned_topics(path),
    };
    let Some(stats) = summary.stats.clone() else {
        return scanned_topics(path);
    };
    Ok(summary
        .channels
        .values()
        .map(|c| Topic {
            name: c.topic.clone(),
            type_name: c.schema.as_ref().map_or(String::new(), |s| s.name.clone()),
            encoding: c.message_encoding.clone(),
            messages: stats
                .channel_message_counts
                .get(&c.id)
                .copied()
                .unwrap_or(0),
        })
        .collect())
}

/// The summary section of a file: `None` when it has none or its end cannot be read.
fn read_summary(path: &Path) -> Result<Option<mcap::Summary>> {
    let (mut file, meta) = fs::open(path)?;
    // The two magics and a footer record: a file shorter has no summary to seek to.
    if meta.len() < 2 * mcap::MAGIC.len() as u64 + 29 {
        return Ok(None);
    }
    let mut reader = SummaryReader::new();
    while let Some(event) = reader.next_event() {
        let Ok(event) = event else {
            return Ok(None);
        };
        match event {
            SummaryReadEvent::ReadRequest(n) => {
                let got = fill(&mut file, reader.insert(n), path)?;
                reader.notify_read(got);
            }
            SummaryReadEvent::SeekRequest(to) => {
                let at = file.seek(to).map_err(|e| Error::io(path, e))?;
                reader.notify_seeked(at);
            }
        }
    }
    Ok(reader.finish())
}

/// A file's topics counted in one linear pass (a file without a summary). A file that breaks
/// off (an unfinished recording) gives the topics and messages before the break; one in which
/// no channel can be read is an error.
fn scanned_topics(path: &Path) -> Result<Vec<Topic>> {
    let mut schemas: HashMap<u16, String> = HashMap::new();
    let mut topics: HashMap<u16, Topic> = HashMap::new();
    let read = Records::open(path).and_then(|mut records| {
        while let Some(item) = records.next(&|| "counting the topics".into())? {
            let Item::Record(record) = item else {
                continue;
            };
            match record {
                Record::Schema { header, .. } => {
                    schemas.insert(header.id, header.name);
                }
                Record::Channel(c) => {
                    let type_name = schemas.get(&c.schema_id).cloned().unwrap_or_default();
                    topics.insert(
                        c.id,
                        Topic {
                            name: c.topic,
                            type_name,
                            encoding: c.message_encoding,
                            messages: 0,
                        },
                    );
                }
                Record::Message { header, .. } => {
                    if let Some(t) = topics.get_mut(&header.channel_id) {
                        t.messages += 1;
                    }
                }
                _ => {}
            }
        }
        Ok(())
    });
    match read {
        Err(e) if topics.is_empty() => Err(e),
        _ => Ok(topics.into_values().collect()),
    }
}
