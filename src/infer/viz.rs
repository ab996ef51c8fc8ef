//! `infer --viz OUT.mcap`: the labelled points of every scan, coloured by the class map, in a
//! Foxglove file (`/kitti2pgm/viz/points`, Foxglove's `PointCloud`), each at its scan's own
//! time (a bag's header stamp, a raw drive's timestamp; else 100 ms after the one before), so a
//! drive is replayed with its segmentation. Written as the frames finish, in their order, to a
//! temporary file renamed into place at the end.

use std::io::BufWriter;
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::format::shard::viz::{VizChannels, VizFrame};
use crate::geom::Point3;
use crate::label::{ClassId, ClassMap};

/// The time between scans without a stamp of their own (10 Hz).
const STEP_NS: u64 = 100_000_000;

/// A replay file being written.
pub struct VizWriter {
    path: PathBuf,
    tmp: tempfile::TempPath,
    w: mcap::Writer<BufWriter<std::fs::File>>,
    channels: VizChannels,
    colours: Vec<[u8; 3]>,
    messages: u32,
    last_ns: Option<u64>,
}

impl VizWriter {
    /// Starts the file `path` (its folder made), for points of `map`'s classes.
    pub fn create(path: &Path, map: &ClassMap) -> Result<VizWriter> {
        let dir = path
            .parent()
            .filter(|p| !p.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        crate::format::create_dir(dir)?;
        let werr = |source| Error::Write {
            path: path.into(),
            source,
        };
        let merr = |e: mcap::McapError| Error::mcap(path, "MCAP writer", e);
        let (file, tmp) = crate::format::temp_builder()
            .suffix(".mcap")
            .tempfile_in(dir)
            .map_err(werr)?
            .into_parts();
        let mut w = mcap::WriteOptions::new()
            .profile("kitti2pgm")
            .library(format!("kitti2pgm {}", env!("CARGO_PKG_VERSION")))
            .create(BufWriter::new(file))
            .map_err(merr)?;
        let channels = VizChannels::add(&mut w).map_err(merr)?;
        Ok(VizWriter {
            path: path.into(),
            tmp,
            w,
            channels,
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
        (self.channels)
            .write(&mut self.w, &v, self.messages, time)
            .map_err(|e| Error::mcap(&self.path, "MCAP writer", e))?;
        self.messages += 1;
        Ok(())
    }

    /// Finishes the file and renames it into place.
    pub fn finish(mut self) -> Result<()> {
        let path = self.path.clone();
        let werr = |source| Error::Write {
            path: path.clone(),
            source,
        };
        (self.w)
            .finish()
            .map_err(|e| Error::mcap(&path, "MCAP writer", e))?;
        let file = (self.w.into_inner().into_inner()).map_err(|e| werr(e.into_error()))?;
        file.sync_data().map_err(werr)?;
        self.tmp.persist(&path).map_err(|e| werr(e.error))?;
        Ok(())
    }
}
