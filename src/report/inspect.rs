//! What a shard holds: frames, channels, sizes, compression ratio, class counts.

use std::collections::BTreeMap;
use std::path::Path;

use serde::Serialize;

use crate::error::Result;
use crate::format::shard::{Shard, ShardKind, ShardMetadata};
use crate::label::ClassCounts;

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
    /// Valid cells per class (names from the class map in the metadata); for a point shard,
    /// points per class.
    pub class_cells: BTreeMap<String, u64>,
    /// Points of all frames (point shards; 0 for map shards).
    pub points: u64,
    /// The kitti2pgm metadata record.
    pub metadata: ShardMetadata,
}

/// Inspects a shard, decoding every frame (streamed). Fails, naming the shard and the frame, on
/// a truncated or corrupted shard, or a label that is not a class of its map.
pub fn inspect(path: &Path) -> Result<ShardInfo> {
    let shard = Shard::open_verified(path)?;
    let summary = shard.summary()?;
    let metadata = shard.metadata()?;
    let map = &metadata.params.map.class_map;
    let mut cells = ClassCounts::zeros(map.len());
    if metadata.content == ShardKind::Points {
        let (mut count, mut first, mut last, mut points) = (0u64, None, None, 0u64);
        for p in shard.points()? {
            for (i, l) in p.label.iter().enumerate() {
                map.check(*l as u64, path, || format!("points {}, point {i}", p.id))?;
                cells.0[*l as usize] += 1;
            }
            points += p.count as u64;
            count += 1;
            if first.is_none() {
                first = Some(p.id);
            } else {
                last = Some(p.id);
            }
        }
        let counted = Counted {
            cells,
            count,
            first,
            last,
            shape: None,
            points,
        };
        return Ok(info(&shard, summary, metadata, counted));
    }
    let (mut count, mut first, mut last) = (0u64, None, None);
    for f in shard.frame_iter() {
        let f = f?;
        for (i, (l, m)) in f.label.iter().zip(&f.mask).enumerate() {
            if *m != 0 {
                map.check(*l as u64, path, || format!("frame {}, cell {i}", f.id))?;
                cells.0[*l as usize] += 1;
            }
        }
        count += 1;
        if first.is_none() {
            first = Some(f);
        } else {
            last = Some(f.id);
        }
    }
    let shape = first
        .as_ref()
        .map(|f| ([f.height, f.width], f.channels.clone()));
    let counted = Counted {
        cells,
        count,
        first: first.map(|f| f.id),
        last,
        shape,
        points: 0,
    };
    Ok(info(&shard, summary, metadata, counted))
}

/// What reading a shard's frames counted.
struct Counted {
    /// Labelled cells (points, for a point shard) per class.
    cells: ClassCounts,
    /// Frames read.
    count: u64,
    /// First frame id.
    first: Option<String>,
    /// Last frame id (when more than one).
    last: Option<String>,
    /// The first map's rows and columns, and its channels (map shards).
    shape: Option<([u32; 2], Vec<String>)>,
    /// Points (point shards).
    points: u64,
}

/// The counts of a shard, put together.
fn info(
    shard: &Shard,
    summary: mcap::read::Summary,
    metadata: ShardMetadata,
    counted: Counted,
) -> ShardInfo {
    let Counted {
        cells,
        count,
        first,
        last,
        shape,
        points,
    } = counted;
    let map = &metadata.params.map.class_map;
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
    ShardInfo {
        path: shard.path.display().to_string(),
        frames: topics
            .get(metadata.content.topic())
            .copied()
            .unwrap_or(count),
        last_frame: last.or_else(|| first.clone()),
        shape: shape.as_ref().map(|s| s.0),
        channels: shape.map(|s| s.1).unwrap_or_default(),
        first_frame: first,
        topics,
        file_bytes: shard.bytes().len() as u64,
        uncompressed_bytes: uncompressed,
        compression,
        compression_ratio: if compressed == 0 {
            1.0
        } else {
            uncompressed as f64 / compressed as f64
        },
        class_cells: map.keyed(&cells.0),
        points,
        metadata,
    }
}
