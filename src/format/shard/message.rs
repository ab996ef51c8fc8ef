//! The frame message of a shard: `kitti2pgm.Frame`, generated from `proto/kitti2pgm/frame.proto`
//! (`generated/`, written by `cargo run --manifest-path tools/protogen/Cargo.toml`; a test checks
//! that it was made from the `.proto` in the tree), and its conversions from and to converted
//! frames.

use std::path::Path;

use crate::error::{Error, Result};
use crate::project::{Channels, PgmFrame};

#[allow(missing_docs, clippy::all)]
mod generated {
    include!("generated/kitti2pgm.rs");
}

/// One converted frame, as stored (protobuf `kitti2pgm.Frame`; fields documented in the
/// `.proto` file).
pub use generated::Frame as FrameMsg;

/// One scan's points, as stored in point shards (protobuf `kitti2pgm.Points`; see
/// [`super::points`]).
pub use generated::Points as PointsMsg;

/// The compiled `FileDescriptorSet` of `kitti2pgm/frame.proto`, stored as the schema of the
/// frame topic.
pub fn descriptor_set() -> &'static [u8] {
    include_bytes!("generated/frame_descriptor_set.bin")
}

impl FrameMsg {
    /// Builds the message of a converted frame: its tensor without the label plane (the label
    /// travels as its own array).
    pub fn from_frame(
        pgm: &PgmFrame,
        id: &str,
        drive: &str,
        frame_index: u32,
        timestamp_ns: u64,
        split: &str,
    ) -> FrameMsg {
        let depth = pgm.depth();
        let inputs = pgm.channels.inputs();
        let planes: Vec<usize> = inputs
            .0
            .iter()
            .map(|c| pgm.channels.index(*c).expect("an input of the frame"))
            .collect();
        let mut tensor = Vec::with_capacity(pgm.rows * pgm.cols * planes.len() * 4);
        for cell in pgm.data.chunks_exact(depth) {
            for &c in &planes {
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
            channels: inputs.names().into_iter().map(String::from).collect(),
            tensor,
            label: pgm.label.clone(),
            instance: pgm.instance.iter().flat_map(|v| v.to_le_bytes()).collect(),
            mask: pgm.mask.clone(),
            rgb_valid: pgm.rgb_valid.clone().unwrap_or_default(),
            split: split.into(),
        }
    }

    /// Cells of the map.
    pub fn cells(&self) -> usize {
        self.height as usize * self.width as usize
    }

    /// The tensor's channels; an error naming the shard for an unknown name.
    pub fn tensor_channels(&self, path: &Path) -> Result<Channels> {
        Channels::from_names(&self.channels).map_err(|name| {
            Error::format(path, format!("frame {}: unknown channel {name:?}", self.id))
        })
    }

    /// Checks that every array has the size its header announces; `path` names the shard.
    /// Prediction messages carry the label map alone (no tensor, instance or mask).
    pub fn validate(&self, path: &Path) -> Result<()> {
        let cells = self.cells();
        let prediction = self.tensor.is_empty() && self.mask.is_empty();
        let checks = [
            ("tensor", self.tensor.len(), cells * self.channels.len() * 4),
            ("label", self.label.len(), cells),
            ("instance", self.instance.len(), cells * 2),
            ("mask", self.mask.len(), cells),
        ];
        for (what, got, want) in checks {
            if got != want && !(prediction && what != "label") {
                return Err(Error::Length {
                    path: path.into(),
                    what: format!("frame {}: {what}", self.id),
                    found: got,
                    expected: want,
                    unit: "bytes",
                });
            }
        }
        if !self.rgb_valid.is_empty() && self.rgb_valid.len() != cells {
            return Err(Error::Length {
                path: path.into(),
                what: format!("frame {}: rgb_valid", self.id),
                found: self.rgb_valid.len(),
                expected: cells,
                unit: "bytes",
            });
        }
        Ok(())
    }

    /// The converted frame this message holds (a map message, [`FrameMsg::validate`]d);
    /// `path` names the shard in errors.
    pub fn into_frame(self, path: &Path) -> Result<PgmFrame> {
        let le = |c: &[u8]| [c[0], c[1], c[2], c[3]];
        Ok(PgmFrame {
            rows: self.height as usize,
            cols: self.width as usize,
            channels: self.tensor_channels(path)?,
            data: self
                .tensor
                .chunks_exact(4)
                .map(|c| f32::from_le_bytes(le(c)))
                .collect(),
            instance: self
                .instance
                .chunks_exact(2)
                .map(|c| u16::from_le_bytes([c[0], c[1]]))
                .collect(),
            rgb_valid: (!self.rgb_valid.is_empty()).then_some(self.rgb_valid),
            label: self.label,
            mask: self.mask,
        })
    }
}
#[cfg(test)]
mod tests {
    use super::*;
    use crate::format::shard::FRAME_SCHEMA;
    use prost::Message as _;
    use prost_types::field_descriptor_proto::Type;

    /// The generated code and schema were made from the `.proto` in the tree: after changing it,
    /// `cargo run --manifest-path tools/protogen/Cargo.toml` regenerates them.
    #[test]
    fn generated_from_this_proto() {
        use sha2::Digest;
        let proto = include_bytes!("../../../proto/kitti2pgm/frame.proto");
        let hex: String = sha2::Sha256::digest(proto)
            .iter()
            .map(|b| format!("{b:02x}"))
            .collect();
        assert_eq!(
            include_str!("generated/frame.proto.sha256").trim(),
            hex,
            "src/format/shard/generated/ is not proto/kitti2pgm/frame.proto's: run \
             cargo run --manifest-path tools/protogen/Cargo.toml"
        );
    }

    /// The schema stored in every shard describes exactly the message the writer encodes.
    #[test]
    fn descriptor_matches_the_message() {
        let set = prost_types::FileDescriptorSet::decode(descriptor_set()).unwrap();
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
