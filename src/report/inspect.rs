//! What a shard holds: frames, channels, sizes, compression ratio, class counts.

use std::collections::BTreeMap;
use std::path::Path;

use serde::Serialize;

use crate::error::Result;
use crate::label::Class;
use crate::write::shard::{Shard, ShardMetadata, FRAME_TOPIC};

/// The inspection of one shard.
#[derive(Debug, Clone, Serialize)]
pub struct ShardInfo {
    /// The shard file.
    pub path: String,
    /// Frames on the frame topic.
    pub frames: u64,
    /// First and last frame ids.
    pub first_frame: Option<String>,
    /// Last frame id.
    pub last_frame: Option<String>,
    /// Map rows and columns.
    pub shape: Option<[u32; 2]>,
    /// Tensor channels.
    pub channels: Vec<String>,
    /// Topics and their message counts.
    pub topics: BTreeMap<String, u64>,
    /// Bytes on disk.
    pub file_bytes: u64,
    /// Bytes of the chunks once decompressed.
    pub uncompressed_bytes: u64,
    /// Chunk compression(s) used.
    pub compression: Vec<String>,
    /// uncompressed / compressed chunk bytes.
    pub compression_ratio: f64,
    /// Valid cells per class.
    pub class_cells: BTreeMap<&'static str, u64>,
    /// The kitti2pgm metadata record.
    pub metadata: ShardMetadata,
}

/// Inspects a shard, decoding every frame. Fails, naming the shard and the frame, on a truncated
/// or corrupted shard.
pub fn inspect(path: &Path) -> Result<ShardInfo> {
    let shard = Shard::open(path)?;
    let summary = shard.summary()?;
    let metadata = shard.metadata()?;
    let (frames, err) = shard.frames();
    if let Some(e) = err {
        return Err(e);
    }
    let mut topics = BTreeMap::new();
    if let Some(stats) = &summary.stats {
        for (id, n) in &stats.channel_message_counts {
            if let Some(c) = summary.channels.get(id) {
                *topics.entry(c.topic.clone()).or_default() += n;
            }
        }
    }
    let (mut compressed, mut uncompressed) = (0u64, 0u64);
    let mut compression: Vec<String> = Vec::new();
    for c in &summary.chunk_indexes {
        compressed += c.compressed_size;
        uncompressed += c.uncompressed_size;
        let name = if c.compression.is_empty() {
            "none".to_string()
        } else {
            c.compression.clone()
        };
        if !compression.contains(&name) {
            compression.push(name);
        }
    }
    let mut cells = [0u64; Class::COUNT];
    for f in &frames {
        for (l, m) in f.label.iter().zip(&f.mask) {
            if *m != 0 {
                cells[(*l as usize).min(Class::COUNT - 1)] += 1;
            }
        }
    }
    Ok(ShardInfo {
        path: path.display().to_string(),
        frames: topics
            .get(FRAME_TOPIC)
            .copied()
            .unwrap_or(frames.len() as u64),
        first_frame: frames.first().map(|f| f.id.clone()),
        last_frame: frames.last().map(|f| f.id.clone()),
        shape: frames.first().map(|f| [f.height, f.width]),
        channels: frames
            .first()
            .map(|f| f.channels.clone())
            .unwrap_or_default(),
        topics,
        file_bytes: shard.bytes().len() as u64,
        uncompressed_bytes: uncompressed,
        compression,
        compression_ratio: if compressed == 0 {
            1.0
        } else {
            uncompressed as f64 / compressed as f64
        },
        class_cells: Class::ALL
            .iter()
            .map(|c| (c.name(), cells[*c as usize]))
            .collect(),
        metadata,
    })
}
