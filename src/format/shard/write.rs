//! WRITE: one shard, under a temporary name until it is finished.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use super::message::descriptor_set;
use super::metadata::ShardMetadata;
use super::viz::{VizChannels, VizFrame};
use super::{ShardCompression, ShardKind, METADATA_NAME, PROFILE};
use crate::error::{Error, Result};

impl ShardCompression {
    fn mcap(self) -> Option<mcap::Compression> {
        match self {
            ShardCompression::Lz4 => Some(mcap::Compression::Lz4),
            ShardCompression::Zstd => Some(mcap::Compression::Zstd),
            ShardCompression::None => None,
        }
    }
}

/// Target chunk size: smaller than one frame, so that every frame gets a chunk of its own and a
/// reader decompresses only the frame it wants.
const CHUNK_BYTES: u64 = 64 * 1024;

/// Writes one shard under a temporary name; [`ShardWriter::finish`] renames it into place.
pub struct ShardWriter {
    writer: mcap::Writer<std::io::BufWriter<std::fs::File>>,
    tmp: tempfile::TempPath,
    path: PathBuf,
    frame_channel: u16,
    sequence: u32,
    viz: Option<VizChannels>,
}

impl ShardWriter {
    /// Starts a shard of `kind` that will be named `path`.
    pub fn create(
        path: &Path,
        compression: ShardCompression,
        viz: bool,
        kind: ShardKind,
    ) -> Result<ShardWriter> {
        let dir = path.parent().unwrap_or(Path::new("."));
        let werr = |source| Error::Write {
            path: path.into(),
            source,
        };
        let tmp = crate::format::temp_builder()
            .suffix(".mcap")
            .tempfile_in(dir)
            .map_err(werr)?;
        let (file, tmp) = tmp.into_parts();
        let merr = |e: mcap::McapError| Error::mcap(path, "MCAP writer", e);
        let mut writer = mcap::WriteOptions::new()
            .profile(PROFILE)
            .library(format!("kitti2pgm {}", env!("CARGO_PKG_VERSION")))
            .compression(compression.mcap())
            .chunk_size(Some(CHUNK_BYTES))
            .create(std::io::BufWriter::with_capacity(1 << 20, file))
            .map_err(merr)?;
        let schema = writer
            .add_schema(kind.schema(), "protobuf", descriptor_set())
            .map_err(merr)?;
        let frame_channel = writer
            .add_channel(schema, kind.topic(), "protobuf", &BTreeMap::new())
            .map_err(merr)?;
        let viz = if viz {
            Some(VizChannels::add(&mut writer).map_err(merr)?)
        } else {
            None
        };
        Ok(ShardWriter {
            writer,
            tmp,
            path: path.into(),
            frame_channel,
            sequence: 0,
            viz,
        })
    }

    fn merr(&self, e: mcap::McapError) -> Error {
        Error::mcap(&self.path, "MCAP writer", e)
    }

    /// Appends a frame's encoded message (and its visualisation messages when `viz` is given
    /// and enabled).
    pub fn write(&mut self, msg: &[u8], log_time: u64, viz: Option<&VizFrame>) -> Result<()> {
        let header = mcap::records::MessageHeader {
            channel_id: self.frame_channel,
            sequence: self.sequence,
            log_time,
            publish_time: log_time,
        };
        self.writer
            .write_to_known_channel(&header, msg)
            .map_err(|e| self.merr(e))?;
        if let (Some(ch), Some(v)) = (&self.viz, viz) {
            let r = ch.write(&mut self.writer, v, self.sequence, log_time);
            r.map_err(|e| self.merr(e))?;
        }
        self.sequence += 1;
        Ok(())
    }

    /// Writes the metadata record, finishes the file (summary, indexes) and renames it into place.
    pub fn finish(mut self, metadata: &ShardMetadata) -> Result<()> {
        let md = mcap::records::Metadata {
            name: METADATA_NAME.into(),
            metadata: metadata.to_map(),
        };
        self.writer.write_metadata(&md).map_err(|e| self.merr(e))?;
        self.writer.finish().map_err(|e| self.merr(e))?;
        let buf = self.writer.into_inner();
        let file = buf.into_inner().map_err(|e| Error::Write {
            path: self.path.clone(),
            source: e.into_error(),
        })?;
        file.sync_data().map_err(|source| Error::Write {
            path: self.path.clone(),
            source,
        })?;
        self.tmp.persist(&self.path).map_err(|e| Error::Write {
            path: self.path.clone(),
            source: e.error,
        })?;
        Ok(())
    }
}
