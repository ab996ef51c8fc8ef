//! `infer --viz OUT.mcap`: the labelled points of every scan, coloured by the class map, in a
//! Foxglove file (`/kitti2pgm/viz/points`, Foxglove's `PointCloud`), each at its scan's own
//! time (a bag's header stamp, a raw drive's timestamp; else 100 ms after the one before), so a
//! drive is replayed with its segmentation. Written as the frames finish, in their order, to a
//! temporary file renamed into place at the end.

use std::path::Path;

use crate::error::Result;
use crate::format::shard::viz::{VizFile, VizFrame};
use crate::geom::Point3;
use crate::label::{ClassId, ClassMap};

/// The time between scans without a stamp of their own (10 Hz).
const STEP_NS: u64 = 100_000_000;

/// A replay file being written.
pub struct VizWriter {
    file: VizFile,
    colours: Vec<[u8; 3]>,
    messages: u32,
    last_ns: Option<u64>,
}

impl VizWriter {
    /// Starts the file `path` (its folder made), for points of `map`'s classes.
    pub fn create(path: &Path, map: &ClassMap) -> Result<VizWriter> {
        Ok(VizWriter {
            file: VizFile::create(path)?,
            colours: (0..map.len()).map(|c| map.colour(c as ClassId)).collect(),
            messages: 0,
            last_ns: None,
        })
    }

    /// Adds a scan's labelled points, at `stamp_ns` (its own time) when known.
    pub fn add(
        &mut self,
        points: Vec<(Point3, f32, ClassId)>,
        stamp_ns: Option<i64>,
    ) -> Result<()> {
        let time = match (stamp_ns, self.last_ns) {
            (Some(t), _) if t >= 0 => t as u64,
            (_, Some(last)) => last + STEP_NS,
            (_, None) => 0,
        };
        self.last_ns = Some(time);
        let v = VizFrame {
            points,
            colours: self.colours.clone(),
            ..Default::default()
        };
        self.file.write(&v, self.messages, time)?;
        self.messages += 1;
        Ok(())
    }

    /// Finishes the file and renames it into place.
    pub fn finish(self) -> Result<()> {
        self.file.finish()
    }
}
