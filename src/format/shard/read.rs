//! Read back: a shard mapped into memory, its summary, metadata and frames.
//!
//! Frames are decoded in one place ([`decode`]), whether they are streamed through the whole
//! file ([`Shard::frame_iter`], constant memory, the frames before a corrupted point stay
//! readable) or read one chunk at a time ([`Shard::chunk_frames`], random access through the
//! chunk indexes).

use std::path::{Path, PathBuf};

use prost::Message as _;

use super::message::FrameMsg;
use super::metadata::ShardMetadata;
use super::{FRAME_TOPIC, METADATA_NAME, PREDICTION_TOPIC};
use crate::error::{Error, Result};

/// The frame of a message on a frame or prediction topic, checked; `None` for other topics.
pub fn decode(message: &mcap::Message<'_>, path: &Path) -> Option<Result<FrameMsg>> {
    let topic = message.channel.topic.as_str();
    if topic != FRAME_TOPIC && topic != PREDICTION_TOPIC {
        return None;
    }
    Some(
        FrameMsg::decode(&message.data[..])
            .map_err(|e| Error::format(path, format!("undecodable frame message: {e}")))
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
    /// Opens a shard.
    pub fn open(path: &Path) -> Result<Shard> {
        let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
        // SAFETY: the file is opened read-only and only read; a shard is never modified in
        // place (it is written under a temporary name and renamed), so the mapping is stable.
        let map = unsafe { memmap2::Mmap::map(&file) }.map_err(|e| Error::io(path, e))?;
        Ok(Shard {
            path: path.into(),
            map,
        })
    }

    /// The raw bytes.
    pub fn bytes(&self) -> &[u8] {
        &self.map
    }

    /// The summary section; an error when the shard was not finished (truncated, interrupted).
    pub fn summary(&self) -> Result<mcap::read::Summary> {
        match mcap::read::Summary::read(&self.map) {
            Ok(Some(s)) => Ok(s),
            Ok(None) => Err(Error::format(
                &self.path,
                "no summary section: the shard was not finished",
            )),
            Err(e) => Err(Error::format(
                &self.path,
                format!("unreadable summary (truncated or corrupted shard?): {e}"),
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
            .ok_or_else(|| {
                Error::format(&self.path, format!("no `{METADATA_NAME}` metadata record"))
            })?;
        let md = mcap::read::metadata(&self.map, index)
            .map_err(|e| Error::format(&self.path, format!("metadata record: {e}")))?;
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

    /// The frame messages one at a time, in file order (constant memory). After an error
    /// (naming the shard and the frame after the last good one) the iterator ends.
    pub fn frame_iter(&self) -> impl Iterator<Item = Result<FrameMsg>> + '_ {
        let mut state = FrameIter {
            stream: None,
            count: 0,
            last: None,
            done: false,
            first_error: None,
        };
        match mcap::MessageStream::new(&self.map) {
            Ok(s) => state.stream = Some(s),
            Err(e) => {
                state.first_error =
                    Some(Error::format(&self.path, format!("not an MCAP file: {e}")))
            }
        }
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
                Error::format(&path, format!("frame #{}{after}: {what}", st.count))
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
            .map_err(|e| Error::format(&self.path, format!("chunk at byte {at}: {e}")))?;
        Ok(stream.filter_map(move |m| match m {
            Ok(m) => decode(&m, &self.path),
            Err(e) => Some(Err(Error::format(
                &self.path,
                format!("chunk at byte {at}: corrupted or truncated: {e}"),
            ))),
        }))
    }
}

struct FrameIter<'a> {
    stream: Option<mcap::MessageStream<'a>>,
    count: usize,
    last: Option<String>,
    done: bool,
    first_error: Option<Error>,
}

/// Whether the shard at `path` is finished, intact and holds exactly `frames`, made with the
/// same map and shard parameters as `params`.
pub fn shard_is_intact(
    path: &Path,
    frames: &[String],
    params: &crate::params::ConvertParams,
) -> bool {
    let Ok(shard) = Shard::open(path) else {
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
        .filter(|(_, c)| c.topic == FRAME_TOPIC)
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
        && md.frames == frames
        && md.params.map == params.map
        && md.params.shards == params.shards
        && count == frames.len() as u64
}
