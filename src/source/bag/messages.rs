//! The messages of one topic of a bag, streamed file by file ([`Bag::messages`]): a damaged
//! chunk gives the topic's messages it held (named by the file's message index) as a loss, and
//! the stream goes on after it.

use std::collections::HashMap;
use std::path::PathBuf;

use mcap::records::Record;

use super::records::{Damage, Item, Records};
#[cfg(doc)]
use super::Bag;
use super::{read_summary, BagMessage, MessageRef};
use crate::error::Result;

/// What a bag's stream of one topic gives: a message, or the topic's messages lost in a damaged
/// chunk.
#[derive(Debug)]
pub enum Next<T> {
    /// A message (what the caller made of it).
    Message(T),
    /// A chunk (or record) that could not be read; the stream goes on after it.
    Lost(Lost),
}

impl<T> Next<T> {
    /// The message, `None` for a loss.
    pub fn message(self) -> Option<T> {
        match self {
            Next::Message(m) => Some(m),
            Next::Lost(_) => None,
        }
    }
}

/// Messages of the topic lost with a damaged chunk.
#[derive(Debug)]
pub struct Lost {
    /// The `.mcap` file.
    pub file: PathBuf,
    /// What is wrong, with its place in the file.
    pub damage: Damage,
    /// The topic's messages it held, by the file's message index (their places on the topic
    /// and log times, in order); empty when the file has no index for it, or it held none of
    /// the topic's (a damaged record outside a chunk: [`Damage::chunk`] false).
    pub messages: Vec<LostMessage>,
}

/// One message lost in a damaged chunk.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LostMessage {
    /// Its place among the topic's messages.
    pub index: u64,
    /// When the recorder received it (nanoseconds).
    pub log_time: u64,
}

/// The messages of one topic, streamed file by file (see [`Bag::messages`]). A damaged chunk
/// is a [`Next::Lost`] and the stream goes on; an error (a file that cannot be opened, a
/// framing that breaks off) ends it after the messages read before.
pub struct Messages {
    files: Vec<PathBuf>,
    topic: String,
    type_name: String,
    next_file: usize,
    open: Option<Records>,
    /// Schema names of the open file, by id.
    schemas: HashMap<u16, String>,
    /// Channel ids of the open file: whether each is the topic with its type.
    ours: HashMap<u16, bool>,
    index: u64,
    done: bool,
}

impl Messages {
    pub(super) fn new(files: Vec<PathBuf>, topic: &super::Topic) -> Messages {
        Messages {
            files,
            topic: topic.name.clone(),
            type_name: topic.type_name.clone(),
            next_file: 0,
            open: None,
            schemas: HashMap::new(),
            ours: HashMap::new(),
            index: 0,
            done: false,
        }
    }

    /// Calls `f` with the next message, borrowed from the reader's buffer (a message decoded
    /// in place is not copied out first), or gives the next loss: `None` at the end of the
    /// topic. An error ends the stream after the messages read before it.
    pub fn next_with<T>(&mut self, f: impl FnOnce(MessageRef<'_>) -> T) -> Option<Result<Next<T>>> {
        if self.done {
            return None;
        }
        let out = self.step(f);
        if out.is_err() {
            self.done = true;
        }
        out.transpose()
    }

    /// Opens the next file (its channels known from its summary, where it has one, so that a
    /// damaged chunk holding a channel's record still names its messages): false at the end.
    fn open_next(&mut self) -> Result<bool> {
        let Some(path) = self.files.get(self.next_file) else {
            return Ok(false);
        };
        self.next_file += 1;
        self.open = Some(Records::open(path)?);
        self.ours.clear();
        self.schemas.clear();
        if let Some(summary) = read_summary(path)? {
            for c in summary.channels.values() {
                let ty = c.schema.as_ref().map_or("", |s| s.name.as_str());
                self.ours
                    .insert(c.id, c.topic == self.topic && ty == self.type_name);
            }
        }
        Ok(true)
    }

    /// A loss of `damage`, with the topic's messages that the index records after its chunk
    /// name (read here: they come next in the file).
    fn lost(&mut self, damage: Damage) -> Result<Lost> {
        let mut entries = Vec::new();
        let records = self.open.as_mut().expect("a file open");
        while damage.chunk && records.next_is(mcap::records::op::MESSAGE_INDEX) {
            let context = || "reading the message index of a damaged chunk".to_string();
            match records.next(&context)? {
                Some(Item::Record(Record::MessageIndex(ix))) => {
                    if self.ours.get(&ix.channel_id) == Some(&true) {
                        entries.extend(ix.records.iter().map(|e| (e.offset, e.log_time)));
                    }
                }
                _ => break,
            }
        }
        entries.sort_unstable();
        let messages = (entries.into_iter())
            .map(|(_, log_time)| {
                self.index += 1;
                LostMessage {
                    index: self.index - 1,
                    log_time,
                }
            })
            .collect();
        Ok(Lost {
            file: self.files[self.next_file - 1].clone(),
            damage,
            messages,
        })
    }

    /// The next message of the topic (opening the next file as needed) given to `f`, or the
    /// next loss: `None` at the end.
    fn step<T>(&mut self, f: impl FnOnce(MessageRef<'_>) -> T) -> Result<Option<Next<T>>> {
        loop {
            let Some(records) = self.open.as_mut() else {
                if !self.open_next()? {
                    self.done = true;
                    return Ok(None);
                }
                continue;
            };
            let context = || format!("reading after message {} of {}", self.index, self.topic);
            let path = &self.files[self.next_file - 1];
            match records.next(&context)? {
                None => self.open = None,
                Some(Item::Damaged(damage)) => {
                    return self.lost(damage).map(|l| Some(Next::Lost(l)))
                }
                Some(Item::Record(Record::Schema { header, .. })) => {
                    self.schemas.insert(header.id, header.name);
                }
                Some(Item::Record(Record::Channel(c))) => {
                    let ty = self.schemas.get(&c.schema_id).map_or("", String::as_str);
                    let ours = c.topic == self.topic && ty == self.type_name;
                    self.ours.insert(c.id, ours);
                }
                Some(Item::Record(Record::Message { header, data })) => {
                    if self.ours.get(&header.channel_id) == Some(&true) {
                        let out = f(MessageRef {
                            index: self.index,
                            log_time: header.log_time,
                            data: &data,
                            file: path,
                        });
                        self.index += 1;
                        return Ok(Some(Next::Message(out)));
                    }
                }
                Some(_) => {}
            }
        }
    }
}

impl Iterator for Messages {
    type Item = Result<Next<BagMessage>>;

    fn next(&mut self) -> Option<Result<Next<BagMessage>>> {
        self.next_with(|m| m.to_owned())
    }
}
