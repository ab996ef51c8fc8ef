//! WRITE and read back training shards: MCAP files of converted frames.
//!
//! One message per frame on topic [`FRAME_TOPIC`], protobuf-encoded (`kitti2pgm.Frame`, its
//! `FileDescriptorSet` stored as the schema, so any generic MCAP/protobuf tool decodes it), in
//! frame-id order, one chunk per frame (lz4 by default, zstd or none as options) so that a reader
//! can seek to a frame through the chunk indexes. A metadata record [`METADATA_NAME`] holds the
//! tool version, the conversion parameters, the input drives and the frame list. The layout is
//! documented in `docs/shard-format.md`.
//!
//! A shard is written under a temporary name and renamed when finished, so a file named
//! `<split>-<NNNNN>.mcap` is always complete; [`shard_is_intact`] lets a re-run skip it.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use prost::Message as _;
use serde::Serialize;

use crate::error::{Error, Result};
use crate::project::frame::PgmFrame;

/// Topic of the frame messages.
pub const FRAME_TOPIC: &str = "/kitti2pgm/frame";
/// Schema name of the frame messages.
pub const FRAME_SCHEMA: &str = "kitti2pgm.Frame";
/// Name of the metadata record.
pub const METADATA_NAME: &str = "kitti2pgm";
/// MCAP profile string.
pub const PROFILE: &str = "kitti2pgm";

/// One converted frame, as stored (protobuf `kitti2pgm.Frame`).
#[derive(Clone, PartialEq, prost::Message)]
pub struct FrameMsg {
    /// Frame id, `<date>_<drive4>_<frame10>`.
    #[prost(string, tag = "1")]
    pub id: String,
    /// Drive folder name, `<date>_drive_<NNNN>_sync`.
    #[prost(string, tag = "2")]
    pub drive: String,
    /// Frame index in the drive.
    #[prost(uint32, tag = "3")]
    pub frame_index: u32,
    /// Velodyne timestamp, ns since the Unix epoch; 0 when unknown.
    #[prost(uint64, tag = "4")]
    pub timestamp_ns: u64,
    /// Rows.
    #[prost(uint32, tag = "5")]
    pub height: u32,
    /// Columns.
    #[prost(uint32, tag = "6")]
    pub width: u32,
    /// Names of the tensor's channels, in order (the `.npy` order without `label`).
    #[prost(string, repeated, tag = "7")]
    pub channels: Vec<String>,
    /// float32 little endian, height x width x channels (HWC).
    #[prost(bytes = "vec", tag = "8")]
    pub tensor: Vec<u8>,
    /// u8 class id per cell, height x width.
    #[prost(bytes = "vec", tag = "9")]
    pub label: Vec<u8>,
    /// u16 little endian instance id per cell (tracklet index + 1, 0 = none).
    #[prost(bytes = "vec", tag = "10")]
    pub instance: Vec<u8>,
    /// u8, 1 where the cell holds a point (range > 0).
    #[prost(bytes = "vec", tag = "11")]
    pub mask: Vec<u8>,
    /// u8, 1 where the cell has a colour; empty without colour channels.
    #[prost(bytes = "vec", tag = "12")]
    pub rgb_valid: Vec<u8>,
    /// Split the frame belongs to (`train`, `val`).
    #[prost(string, tag = "13")]
    pub split: String,
}

impl FrameMsg {
    /// Builds the message of a converted frame.
    pub fn from_frame(
        pgm: &PgmFrame,
        id: &str,
        drive: &str,
        frame_index: u32,
        timestamp_ns: u64,
        split: &str,
    ) -> FrameMsg {
        let depth = pgm.depth();
        let inputs: Vec<usize> = (0..depth).filter(|&c| pgm.channels[c] != "label").collect();
        let mut tensor = Vec::with_capacity(pgm.rows * pgm.cols * inputs.len() * 4);
        for cell in pgm.data.chunks_exact(depth) {
            for &c in &inputs {
                tensor.extend_from_slice(&cell[c].to_le_bytes());
            }
        }
        FrameMsg {
            id: id.into(),
            drive: drive.into(),
            frame_index,
            timestamp_ns,
            height: pgm.rows as u32,
            width: pgm.cols as u32,
            channels: inputs
                .iter()
                .map(|&c| pgm.channels[c].to_string())
                .collect(),
            tensor,
            label: pgm.label.clone(),
            instance: pgm.instance.iter().flat_map(|v| v.to_le_bytes()).collect(),
            mask: pgm.mask.clone(),
            rgb_valid: pgm.rgb_valid.clone().unwrap_or_default(),
            split: split.into(),
        }
    }

    /// Checks that every array has the size its header announces; `path` names the shard.
    pub fn validate(&self, path: &Path) -> Result<()> {
        let cells = self.height as usize * self.width as usize;
        let checks = [
            ("tensor", self.tensor.len(), cells * self.channels.len() * 4),
            ("label", self.label.len(), cells),
            ("instance", self.instance.len(), cells * 2),
            ("mask", self.mask.len(), cells),
        ];
        for (what, got, want) in checks {
            if got != want {
                return Err(Error::format(
                    path,
                    format!("frame {}: {what} has {got} bytes, expected {want}", self.id),
                ));
            }
        }
        if !self.rgb_valid.is_empty() && self.rgb_valid.len() != cells {
            return Err(Error::format(
                path,
                format!(
                    "frame {}: rgb_valid has {} bytes, expected {cells}",
                    self.id,
                    self.rgb_valid.len()
                ),
            ));
        }
        Ok(())
    }

    /// The tensor as float32 values.
    pub fn tensor_f32(&self) -> Vec<f32> {
        self.tensor
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect()
    }
}

/// The `FileDescriptorSet` of `kitti2pgm/frame.proto`, stored as the schema of the frame topic.
pub fn frame_descriptor_set() -> Vec<u8> {
    use prost_types::field_descriptor_proto::{Label, Type};
    use prost_types::{
        DescriptorProto, FieldDescriptorProto, FileDescriptorProto, FileDescriptorSet,
    };
    let field = |name: &str, number: i32, ty: Type, repeated: bool| FieldDescriptorProto {
        name: Some(name.into()),
        number: Some(number),
        label: Some(if repeated {
            Label::Repeated
        } else {
            Label::Optional
        } as i32),
        r#type: Some(ty as i32),
        json_name: Some(
            name.split('_')
                .enumerate()
                .map(|(i, p)| {
                    if i == 0 {
                        p.to_string()
                    } else {
                        p[..1].to_uppercase() + &p[1..]
                    }
                })
                .collect(),
        ),
        ..Default::default()
    };
    let fields = vec![
        field("id", 1, Type::String, false),
        field("drive", 2, Type::String, false),
        field("frame_index", 3, Type::Uint32, false),
        field("timestamp_ns", 4, Type::Uint64, false),
        field("height", 5, Type::Uint32, false),
        field("width", 6, Type::Uint32, false),
        field("channels", 7, Type::String, true),
        field("tensor", 8, Type::Bytes, false),
        field("label", 9, Type::Bytes, false),
        field("instance", 10, Type::Bytes, false),
        field("mask", 11, Type::Bytes, false),
        field("rgb_valid", 12, Type::Bytes, false),
        field("split", 13, Type::String, false),
    ];
    let file = FileDescriptorProto {
        name: Some("kitti2pgm/frame.proto".into()),
        package: Some("kitti2pgm".into()),
        message_type: vec![DescriptorProto {
            name: Some("Frame".into()),
            field: fields,
            ..Default::default()
        }],
        syntax: Some("proto3".into()),
        ..Default::default()
    };
    FileDescriptorSet { file: vec![file] }.encode_to_vec()
}

/// Chunk compression.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, serde::Deserialize, Default)]
pub enum ShardCompression {
    /// lz4 (default): fast to read.
    #[default]
    Lz4,
    /// zstd: smaller, slower to write.
    Zstd,
    /// No compression.
    None,
}

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
    viz: Option<crate::write::viz::VizChannels>,
}

impl ShardWriter {
    /// Starts a shard that will be named `path`.
    pub fn create(path: &Path, compression: ShardCompression, viz: bool) -> Result<ShardWriter> {
        let dir = path.parent().unwrap_or(Path::new("."));
        let werr = |source| Error::Write {
            path: path.into(),
            source,
        };
        let tmp = crate::write::temp_builder()
            .suffix(".mcap")
            .tempfile_in(dir)
            .map_err(werr)?;
        let (file, tmp) = tmp.into_parts();
        let merr = |e: mcap::McapError| Error::format(path, format!("MCAP writer: {e}"));
        let mut writer = mcap::WriteOptions::new()
            .profile(PROFILE)
            .library(format!("kitti2pgm {}", env!("CARGO_PKG_VERSION")))
            .compression(compression.mcap())
            .chunk_size(Some(CHUNK_BYTES))
            .create(std::io::BufWriter::with_capacity(1 << 20, file))
            .map_err(merr)?;
        let schema = writer
            .add_schema(FRAME_SCHEMA, "protobuf", &frame_descriptor_set())
            .map_err(merr)?;
        let frame_channel = writer
            .add_channel(schema, FRAME_TOPIC, "protobuf", &BTreeMap::new())
            .map_err(merr)?;
        let viz = if viz {
            Some(crate::write::viz::VizChannels::add(&mut writer).map_err(merr)?)
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
        Error::format(&self.path, format!("MCAP writer: {e}"))
    }

    /// Appends a frame (and its visualisation messages when `viz` is given and enabled).
    pub fn write(
        &mut self,
        msg: &FrameMsg,
        log_time: u64,
        viz: Option<&crate::write::viz::VizFrame>,
    ) -> Result<()> {
        let header = mcap::records::MessageHeader {
            channel_id: self.frame_channel,
            sequence: self.sequence,
            log_time,
            publish_time: log_time,
        };
        self.writer
            .write_to_known_channel(&header, &msg.encode_to_vec())
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

/// What the metadata record of a shard says.
#[derive(Debug, Clone, PartialEq, Default, Serialize)]
pub struct ShardMetadata {
    /// Tool version.
    pub version: String,
    /// Conversion parameters as JSON (map, colour, selection, split rule, compression).
    pub params: String,
    /// Input drives, as `<date>_drive_<NNNN>_sync`.
    pub drives: Vec<String>,
    /// Frame ids planned for the shard, in order.
    pub frames: Vec<String>,
    /// Frames of the plan that failed and are not in the shard.
    pub failed: Vec<String>,
    /// Split name.
    pub split: String,
}

impl ShardMetadata {
    fn to_map(&self) -> BTreeMap<String, String> {
        BTreeMap::from([
            ("version".into(), self.version.clone()),
            ("params".into(), self.params.clone()),
            ("drives".into(), self.drives.join("\n")),
            ("frames".into(), self.frames.join("\n")),
            ("failed".into(), self.failed.join("\n")),
            ("split".into(), self.split.clone()),
        ])
    }

    fn from_map(m: &BTreeMap<String, String>) -> ShardMetadata {
        let list = |k: &str| {
            m.get(k)
                .map(|s| s.lines().map(String::from).collect())
                .unwrap_or_default()
        };
        ShardMetadata {
            version: m.get("version").cloned().unwrap_or_default(),
            params: m.get("params").cloned().unwrap_or_default(),
            drives: list("drives"),
            frames: list("frames"),
            failed: list("failed"),
            split: m.get("split").cloned().unwrap_or_default(),
        }
    }
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
        Ok(ShardMetadata::from_map(&md.metadata))
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
                    Some(Ok(m)) if m.channel.topic == FRAME_TOPIC => {
                        match FrameMsg::decode(&m.data[..]) {
                            Ok(f) => f.validate(&path).map(|()| f),
                            Err(e) => Err(fail(&state, format!("undecodable message: {e}"))),
                        }
                    }
                    Some(Ok(_)) => continue,
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

struct FrameIter<'a> {
    stream: Option<mcap::MessageStream<'a>>,
    count: usize,
    last: Option<String>,
    done: bool,
    first_error: Option<Error>,
}

/// Whether the shard at `path` is finished, intact and holds exactly `frames` under `params`.
pub fn shard_is_intact(path: &Path, frames: &[String], params: &str) -> bool {
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
        && md.params == params
        && count == frames.len() as u64
}

/// The name of shard `index` of a split: `<split>-<NNNNN>.mcap`.
pub fn shard_name(split: &str, index: usize) -> String {
    format!("{split}-{index:05}.mcap")
}

#[cfg(test)]
mod tests {
    use super::*;
    use prost_types::field_descriptor_proto::Type;

    /// The schema stored in every shard describes exactly the message the writer encodes.
    #[test]
    fn descriptor_matches_the_message() {
        let set = prost_types::FileDescriptorSet::decode(&frame_descriptor_set()[..]).unwrap();
        let file = &set.file[0];
        assert_eq!(file.package(), "kitti2pgm");
        let msg = &file.message_type[0];
        assert_eq!(format!("{}.{}", file.package(), msg.name()), FRAME_SCHEMA);
        let fields: Vec<(String, i32, Type)> = msg
            .field
            .iter()
            .map(|f| (f.name().to_string(), f.number(), f.r#type()))
            .collect();
        let m = FrameMsg {
            id: "a".into(),
            drive: "b".into(),
            frame_index: 1,
            timestamp_ns: 2,
            height: 3,
            width: 4,
            channels: vec!["c".into()],
            tensor: vec![5],
            label: vec![6],
            instance: vec![7],
            mask: vec![8],
            rgb_valid: vec![9],
            split: "d".into(),
        };
        // Every field present once: walk the encoded message's keys and compare with the schema.
        let bytes = m.encode_to_vec();
        let mut seen = Vec::new();
        let mut buf = &bytes[..];
        while !buf.is_empty() {
            let key = prost::encoding::decode_varint(&mut buf).unwrap();
            let (number, wire) = ((key >> 3) as i32, key & 7);
            let f = fields
                .iter()
                .find(|f| f.1 == number)
                .unwrap_or_else(|| panic!("field {number} not in the schema"));
            let expected_wire = match f.2 {
                Type::String | Type::Bytes => 2,
                Type::Uint32 | Type::Uint64 => 0,
                other => panic!("unexpected type {other:?}"),
            };
            assert_eq!(wire, expected_wire, "{}", f.0);
            if wire == 0 {
                prost::encoding::decode_varint(&mut buf).unwrap();
            } else {
                let n = prost::encoding::decode_varint(&mut buf).unwrap() as usize;
                buf = &buf[n..];
            }
            seen.push(number);
        }
        seen.sort();
        assert_eq!(seen, (1..=13).collect::<Vec<_>>());
        assert_eq!(fields.len(), 13);
    }
}
