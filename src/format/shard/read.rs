//! Read back: a shard mapped into memory, its summary, metadata and frames.
//!
//! Frames are decoded in one place ([`decode`]), whether they are streamed through the whole
//! file ([`Shard::frame_iter`], constant memory, the frames before a corrupted point stay
//! readable) or read one chunk at a time ([`Shard::chunk_frames`], random access through the
//! chunk indexes).

use std::path::{Path, PathBuf};

use prost::Message as _;

use super::message::{FrameMsg, PointsMsg};
use super::metadata::ShardMetadata;
use super::{ShardKind, METADATA_NAME, POINTS_TOPIC, PREDICTION_TOPIC};
use crate::error::{Error, Result};
use crate::source::kitti::FrameId;

/// Whether a message's channel carries `schema` (messages are selected by schema, never by
/// topic alone: a visualisation topic may share a name's prefix or a user's tool may rename).
fn has_schema(message: &mcap::Message<'_>, schema: &str) -> bool {
    message
        .channel
        .schema
        .as_ref()
        .is_some_and(|s| s.name == schema)
}

/// The frame of a message on a frame or prediction topic, checked; `None` for other messages.
pub fn decode(message: &mcap::Message<'_>, path: &Path) -> Option<Result<FrameMsg>> {
    let topic = message.channel.topic.as_str();
    let frame_topic = topic == super::FRAME_TOPIC || topic == PREDICTION_TOPIC;
    if !frame_topic || !has_schema(message, super::FRAME_SCHEMA) {
        return None;
    }
    Some(
        FrameMsg::decode(&message.data[..])
            .map_err(|e| Error::NotFormat {
                path: path.into(),
                format: "a kitti2pgm frame message",
                detail: e.to_string(),
            })
            .and_then(|f| f.validate(path).map(|()| f)),
    )
}

/// A shard mapped into memory.
pub struct Shard {
    /// Its path.
    pub path: PathBuf,
    map: memmap2::Mmap,
}

impl Shard {
    /// Opens a shard (no check of its contents: see [`Shard::open_verified`]).
    pub fn open(path: &Path) -> Result<Shard> {
        let (file, _) = crate::fs::open(path)?;
        // SAFETY: the file is opened read-only and only read; a shard is never modified in
        // place (it is written under a temporary name and renamed), so the mapping is stable.
        let map = unsafe { memmap2::Mmap::map(&file) }.map_err(|e| Error::io(path, e))?;
        Ok(Shard {
            path: path.into(),
            map,
        })
    }

    /// Opens a shard and checks every byte of it ([`Shard::verify`]).
    pub fn open_verified(path: &Path) -> Result<Shard> {
        let shard = Shard::open(path)?;
        shard.verify()?;
        Ok(shard)
    }

    /// The raw bytes.
    pub fn bytes(&self) -> &[u8] {
        &self.map
    }

    /// Checks the whole file against the CRCs the writer stored: the data section's (every
    /// record from the start to the data end record: chunks, message indexes, metadata) and
    /// the summary section's (indexes, statistics, up to the footer), plus the magic at both
    /// ends. Any flipped bit fails; the error names the shard and, when a frame's chunk is the
    /// damaged part, the frame. A CRC stored as 0 (a writer that computed none) is not checked.
    pub fn verify(&self) -> Result<()> {
        use mcap::records::op;
        use mcap::MAGIC;
        // Record layout: opcode (1 byte), content length (u64), content.
        const RECORD_HEAD: usize = 1 + 8;
        // Footer content: summary start (u64), summary offset start (u64), summary CRC (u32).
        const FOOTER_CONTENT: u64 = 8 + 8 + 4;
        // Data end content: data section CRC (u32).
        const DATA_END_CONTENT: u64 = 4;
        const DATA_END_LEN: usize = RECORD_HEAD + DATA_END_CONTENT as usize;
        let b = self.bytes();
        let bad = |what: String| {
            Err(Error::Corrupt {
                path: self.path.clone(),
                what,
            })
        };
        // magic, ..., data end, summary, footer, magic.
        let footer_len = RECORD_HEAD + FOOTER_CONTENT as usize;
        if b.len() < 2 * MAGIC.len() + footer_len + DATA_END_LEN
            || !b.starts_with(MAGIC)
            || !b.ends_with(MAGIC)
        {
            return bad(format!(
                "{} bytes without MCAP magic at both ends (truncated or not finished?)",
                b.len()
            ));
        }
        let u64_at = |p: usize| u64::from_le_bytes(b[p..p + 8].try_into().expect("8 bytes"));
        let u32_at = |p: usize| u32::from_le_bytes(b[p..p + 4].try_into().expect("4 bytes"));
        let footer = b.len() - MAGIC.len() - footer_len;
        if b[footer] != op::FOOTER || u64_at(footer + 1) != FOOTER_CONTENT {
            return bad(format!("no footer record at byte {footer}"));
        }
        let summary_start = u64_at(footer + RECORD_HEAD) as usize;
        let summary_crc = u32_at(footer + RECORD_HEAD + 16);
        let summary_from = if summary_start == 0 {
            footer
        } else {
            summary_start
        };
        if summary_from > footer || summary_from < MAGIC.len() + DATA_END_LEN {
            return bad(format!("summary start {summary_start} out of the file"));
        }
        if summary_crc != 0 {
            // The summary CRC covers the summary section and the footer up to the CRC itself.
            let got = crc32fast::hash(&b[summary_from..footer + RECORD_HEAD + 16]);
            if got != summary_crc {
                return bad(format!(
                    "summary section CRC {got:#010x}, stored {summary_crc:#010x}"
                ));
            }
        }
        let data_end = summary_from - DATA_END_LEN;
        if b[data_end] != op::DATA_END || u64_at(data_end + 1) != DATA_END_CONTENT {
            return bad(format!("no data end record at byte {data_end}"));
        }
        let data_crc = u32_at(data_end + RECORD_HEAD);
        if data_crc != 0 {
            let got = crc32fast::hash(&b[..data_end]);
            if got != data_crc {
                // Name the frame when a chunk is the damaged part.
                let at = self.frame_iter().find_map(|f| f.err());
                return Err(at.unwrap_or_else(|| {
                    Error::Corrupt {
                        path: self.path.clone(),
                        what: format!("data section CRC {got:#010x}, stored {data_crc:#010x} (a record outside the frames' chunks is damaged)"),
                    }
                }));
            }
        }
        Ok(())
    }

    /// The summary section; an error when the shard was not finished (truncated, interrupted).
    pub fn summary(&self) -> Result<mcap::read::Summary> {
        match mcap::read::Summary::read(&self.map) {
            Ok(Some(s)) => Ok(s),
            Ok(None) => Err(Error::Corrupt {
                path: self.path.clone(),
                what: "no summary section: the shard was not finished".into(),
            }),
            Err(e) => Err(Error::mcap(
                &self.path,
                "unreadable summary (truncated or corrupted shard?)",
                e,
            )),
        }
    }

    /// The kitti2pgm metadata record.
    pub fn metadata(&self) -> Result<ShardMetadata> {
        let summary = self.summary()?;
        let index = summary
            .metadata_indexes
            .iter()
            .find(|m| m.name == METADATA_NAME)
            .ok_or_else(|| Error::MissingKey {
                path: self.path.clone(),
                key: format!("{METADATA_NAME} (metadata record)"),
            })?;
        let md = mcap::read::metadata(&self.map, index)
            .map_err(|e| Error::mcap(&self.path, "metadata record", e))?;
        ShardMetadata::from_map(&md.metadata, &self.path)
    }

    /// Every frame message in file order. The frames before a corrupted or truncated point are
    /// returned; the error names the shard and the frame after the last good one.
    pub fn frames(&self) -> (Vec<FrameMsg>, Option<Error>) {
        let mut out = Vec::new();
        for f in self.frame_iter() {
            match f {
                Ok(f) => out.push(f),
                Err(e) => return (out, Some(e)),
            }
        }
        (out, None)
    }

    /// The frame messages one at a time, in file order (constant memory), each chunk checked
    /// against its CRC. After an error (naming the shard and the frame after the last good one)
    /// the iterator ends. A shard whose end is lost still gives its first frames.
    pub fn frame_iter(&self) -> impl Iterator<Item = Result<FrameMsg>> + '_ {
        // The frame ids in shard order (from the metadata, when it is readable), to name the
        // frame a damaged chunk holds.
        let ids: Vec<String> = self
            .metadata()
            .map(|md| {
                md.frames
                    .iter()
                    .filter(|f| !md.failed.contains(f))
                    .map(FrameId::to_string)
                    .collect()
            })
            .unwrap_or_default();
        let mut state = FrameIter {
            stream: Some(self.messages()),
            count: 0,
            last: None,
            done: false,
            first_error: None,
        };
        let path = self.path.clone();
        std::iter::from_fn(move || {
            if state.done {
                return None;
            }
            if let Some(e) = state.first_error.take() {
                state.done = true;
                return Some(Err(e));
            }
            let fail = |st: &FrameIter, what: String| {
                let after = st
                    .last
                    .as_ref()
                    .map(|id| format!(" after frame {id}"))
                    .unwrap_or_default();
                let which = ids
                    .get(st.count)
                    .map(|id| format!(" ({id})"))
                    .unwrap_or_default();
                Error::Corrupt {
                    path: path.clone(),
                    what: format!("frame #{}{which}{after}: {what}", st.count),
                }
            };
            loop {
                let next = state.stream.as_mut().and_then(Iterator::next);
                let r = match next {
                    None => {
                        state.done = true;
                        return None;
                    }
                    Some(Ok(m)) => match decode(&m, &path) {
                        Some(Ok(f)) => Ok(f),
                        Some(Err(e)) => Err(fail(&state, e.to_string())),
                        None => continue,
                    },
                    Some(Err(e)) => Err(fail(&state, format!("corrupted or truncated: {e}"))),
                };
                match &r {
                    Ok(f) => {
                        state.count += 1;
                        state.last = Some(f.id.clone());
                    }
                    Err(_) => state.done = true,
                }
                return Some(r);
            }
        })
    }
}

impl Shard {
    /// The frame (or prediction) messages of chunk `chunk` of the summary's chunk indexes.
    pub fn chunk_frames<'a>(
        &'a self,
        summary: &'a mcap::read::Summary,
        chunk: usize,
    ) -> Result<impl Iterator<Item = Result<FrameMsg>> + 'a> {
        let index = &summary.chunk_indexes[chunk];
        let at = index.chunk_start_offset;
        let stream = summary
            .stream_chunk(self.bytes(), index)
            .map_err(|e| Error::mcap(&self.path, format!("chunk at byte {at}"), e))?;
        Ok(stream.filter_map(move |m| match m {
            Ok(m) => decode(&m, &self.path),
            Err(e) => Some(Err(Error::mcap(
                &self.path,
                format!("chunk at byte {at}: corrupted or truncated"),
                e,
            ))),
        }))
    }
}

/// The messages of a shard in file order, each chunk checked against its CRC *before* any of
/// its messages is handed out (so a damaged chunk is never half read, and an error names the
/// frame of the damaged chunk whatever the compression).
type Messages<'a> = mcap::io::MessageReader<std::io::Cursor<&'a [u8]>>;

impl Shard {
    fn messages(&self) -> Messages<'_> {
        // No record, compressed or not, can be longer than this (lz4 and zstd shrink a frame a
        // few times at most): a damaged length field is then an error, not a huge allocation.
        let limit = (self.bytes().len().saturating_mul(256)).max(256 << 20);
        let options = mcap::sans_io::linear_reader::LinearReaderOptions::default()
            .with_validate_chunk_crcs(true)
            .with_prevalidate_chunk_crcs(true)
            .with_record_length_limit(limit);
        mcap::io::MessageReader::new_with_options(std::io::Cursor::new(self.bytes()), options)
    }
}

struct FrameIter<'a> {
    stream: Option<Messages<'a>>,
    count: usize,
    last: Option<String>,
    done: bool,
    first_error: Option<Error>,
}

impl Shard {
    /// Every point message of a point shard, in file order, each chunk checked against its
    /// CRC and each message against its sizes; the error names the shard and the frame.
    pub fn points(&self) -> Result<Vec<PointsMsg>> {
        let mut out: Vec<PointsMsg> = Vec::new();
        for m in self.messages() {
            let fail = |what: String| {
                let after = out
                    .last()
                    .map(|p| format!(" after {}", p.id))
                    .unwrap_or_default();
                Error::Corrupt {
                    path: self.path.clone(),
                    what: format!("points #{}{after}: {what}", out.len()),
                }
            };
            let m = m.map_err(|e| fail(format!("corrupted or truncated: {e}")))?;
            if m.channel.topic != POINTS_TOPIC || !has_schema(&m, super::POINTS_SCHEMA) {
                continue;
            }
            let p = PointsMsg::decode(&m.data[..])
                .map_err(|e| fail(format!("undecodable point message: {e}")))?;
            p.validate(&self.path)?;
            out.push(p);
        }
        Ok(out)
    }
}

/// Whether the shard at `path` is finished, intact, holds `kind` and exactly `frames`, each made
/// from inputs of the given digest, with the same map and shard parameters as `params`.
pub fn shard_is_intact(
    path: &Path,
    frames: &[(FrameId, u64)],
    params: &crate::provenance::ConvertParams,
    kind: ShardKind,
) -> bool {
    let Ok(shard) = Shard::open_verified(path) else {
        return false;
    };
    let Ok(summary) = shard.summary() else {
        return false;
    };
    let Ok(md) = shard.metadata() else {
        return false;
    };
    let count = summary
        .channels
        .iter()
        .filter(|(_, c)| {
            c.topic == kind.topic() && c.schema.as_ref().is_some_and(|s| s.name == kind.schema())
        })
        .map(|(id, _)| {
            summary
                .stats
                .as_ref()
                .and_then(|s| s.channel_message_counts.get(id))
                .copied()
                .unwrap_or(0)
        })
        .sum::<u64>();
    md.failed.is_empty()
        && md.frames.len() == frames.len()
        && frames
            .iter()
            .zip(&md.frames)
            .all(|((id, digest), listed)| id == listed && md.inputs.get(id) == Some(digest))
        && md.params.map == params.map
        && md.content == kind
        && params.shards_of(kind) == md.params.shards_of(kind)
        && count == frames.len() as u64
}
