//! WRITE and read back training shards: MCAP files of converted frames.
//!
//! One message per frame on topic [`FRAME_TOPIC`], protobuf-encoded ([`FrameMsg`], generated
//! from `proto/kitti2pgm/frame.proto`, whose compiled `FileDescriptorSet` is stored as the
//! schema, so any generic MCAP/protobuf tool decodes it), in frame-id order, one chunk per frame
//! (lz4 by default, zstd or none) so that a reader can seek to a frame through the chunk
//! indexes. A metadata record [`METADATA_NAME`] holds the tool version, the typed conversion
//! parameters (map, class map, colour, split), the input drives and the frame list. The layout
//! is documented in `docs/shard-format.md`.
//!
//! - [`message`]: the frame message and its schema;
//! - [`metadata`]: the metadata record;
//! - [`write`]: [`ShardWriter`], atomic (temporary name, renamed when finished);
//! - [`read`]: [`Shard`], streaming and per-chunk reads, [`shard_is_intact`] for re-runs;
//! - [`viz`]: Foxglove visualisation topics (`--viz`).

pub mod message;
pub mod metadata;
pub mod points;
pub mod read;
pub mod viz;
pub mod write;

pub use crate::provenance::{ShardCompression, ShardKind};
pub use message::{FrameMsg, PointsMsg};
pub use metadata::ShardMetadata;
pub use read::{shard_is_intact, Shard};
pub use write::ShardWriter;

/// Topic of the frame messages.
pub const FRAME_TOPIC: &str = "/kitti2pgm/frame";
/// Topic of prediction messages in prediction shards (the trainer's `evaluate --format mcap`).
pub const PREDICTION_TOPIC: &str = "/kitti2pgm/prediction";
/// Schema name of the frame messages.
pub const FRAME_SCHEMA: &str = "kitti2pgm.Frame";
/// Topic of the point messages in point shards (`convert --format points`).
pub const POINTS_TOPIC: &str = "/kitti2pgm/points";
/// Schema name of the point messages.
pub const POINTS_SCHEMA: &str = "kitti2pgm.Points";

impl ShardKind {
    /// The topic of its messages.
    pub fn topic(self) -> &'static str {
        match self {
            ShardKind::Maps => FRAME_TOPIC,
            ShardKind::Points => POINTS_TOPIC,
        }
    }

    /// The schema name of its messages.
    pub fn schema(self) -> &'static str {
        match self {
            ShardKind::Maps => FRAME_SCHEMA,
            ShardKind::Points => POINTS_SCHEMA,
        }
    }
}
/// Name of the metadata record.
pub const METADATA_NAME: &str = "kitti2pgm";
/// MCAP profile string.
pub const PROFILE: &str = "kitti2pgm";
