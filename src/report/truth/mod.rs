//! REPORT input: the converted ground truth, wherever and however it was written.
//!
//! [`GroundTruth::open`] accepts a `convert` output folder, its `lidar_2d` folder, a bare folder
//! of `<frame id>.npy` maps (SqueezeSeg's published `lidar_2d` data), a folder of shards or one
//! shard. It returns the frames and the [`MapParams`] they were made with: read back typed from
//! `convert_summary.json` or the shards' metadata ([`Provenance::Recorded`]), or, for a folder
//! that carries none, SqueezeSeg's defaults with the files' own rows and columns, stated as such
//! ([`Provenance::Assumed`]). Frames are read into one shape, [`MapFrame`], whatever the source.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use rayon::prelude::*;

use crate::error::{Error, NotAFrameId, Result};
use crate::format::layout::{self, OutputDir};
use crate::format::pgm::{self, PgmFile};
use crate::format::shard::{Shard, ShardKind};
use crate::format::summary;
use crate::label::ClassMap;
use crate::project::camera::{RgbOptions, Sampling};
use crate::project::PgmFrame;
use crate::provenance::MapParams;
use crate::source::kitti::{discover_as, DatasetKind, Drive, FrameId};

pub mod completeness;

pub use completeness::Completeness;

/// Where the frames are.
#[derive(Debug, Clone, PartialEq)]
pub enum Source {
    /// `<frame id>.npy` maps in this folder (a convert folder's `lidar_2d`, or a bare one).
    Npy(PathBuf),
    /// These shards, sorted.
    Shards(Vec<PathBuf>),
    /// A SemanticKITTI root or sequence itself: per-point labels, no maps (what the benchmark
    /// scores against; `score` only).
    Dataset(Vec<Drive>),
}

/// Where the map parameters come from.
#[derive(Debug, Clone, PartialEq)]
pub enum Provenance {
    /// Read back from this file (`convert_summary.json` or the first shard).
    Recorded(PathBuf),
    /// Not recorded: SqueezeSeg's defaults with the files' rows and columns.
    Assumed,
}

/// Converted ground truth, opened.
#[derive(Debug, Clone)]
pub struct GroundTruth {
    /// The path given.
    pub path: PathBuf,
    /// Where the frames are.
    pub source: Source,
    /// The convert folder, when the frames are in one (its `.label` files, summary, ImageSet).
    pub dir: Option<OutputDir>,
    /// The map, classes, colour and selection the frames were made with.
    pub params: MapParams,
    /// Whether `params` were recorded or assumed.
    pub provenance: Provenance,
    /// The frames, sorted.
    pub frames: Vec<FrameId>,
    /// Set when the frames are an unfinished or inconsistent conversion's, read on purpose
    /// ([`Completeness::AllowPartial`]): what is missing or wrong. Reports print it.
    pub partial: Option<String>,
}

/// One ground-truth frame, from a `.npy` or a shard: the map and where it was read.
#[derive(Debug, Clone, PartialEq)]
pub struct MapFrame {
    /// The frame.
    pub id: FrameId,
    /// The file it was read from (its `.npy` or its shard).
    pub source: PathBuf,
    /// The map.
    pub map: PgmFrame,
}

impl MapFrame {
    /// The class of each cell, `u8::MAX` where the mask is 0.
    pub fn truth(&self) -> Vec<u8> {
        let m = &self.map;
        m.label
            .iter()
            .zip(&m.mask)
            .map(|(l, m)| if *m != 0 { *l } else { u8::MAX })
            .collect()
    }

    /// The frame of a map read from `path`, labels checked against `classes`
    /// ([`PgmFile::into_frame`]).
    pub fn from_pgm(id: FrameId, f: PgmFile, classes: &ClassMap, path: &Path) -> Result<MapFrame> {
        Ok(MapFrame {
            id,
            source: path.to_path_buf(),
            map: f.into_frame(classes, path)?,
        })
    }
}

fn is_npy_folder(dir: &Path) -> bool {
    layout::list_npy_frames(dir).is_ok()
}

impl GroundTruth {
    /// Opens the ground truth at `path` (see the module docs for what it may be); the output
    /// of an unfinished conversion is refused.
    pub fn open(path: &Path) -> Result<GroundTruth> {
        Self::open_with(path, Completeness::Require)
    }

    /// Opens the ground truth at `path`; `completeness` says whether an unfinished
    /// conversion's output is refused or read (and marked [`GroundTruth::partial`]).
    pub fn open_with(path: &Path, completeness: Completeness) -> Result<GroundTruth> {
        let mut gt = Self::open_any(path)?;
        if let Some(problem) = completeness::problem(&gt)? {
            match completeness {
                Completeness::Require => {
                    return Err(Error::Unfinished {
                        path: path.into(),
                        problem,
                    })
                }
                Completeness::AllowPartial => gt.partial = Some(problem),
            }
        }
        Ok(gt)
    }

    fn open_any(path: &Path) -> Result<GroundTruth> {
        let input = |message: &str| Error::Input {
            path: path.into(),
            message: message.into(),
        };
        if path.is_file() {
            if path.extension().is_some_and(|e| e == "mcap") {
                return Self::from_shards(path, vec![path.to_path_buf()], None);
            }
            return Err(input("not a ground-truth folder or shard (.mcap)"));
        }
        if !path.is_dir() {
            return Err(input("no such ground-truth folder or shard"));
        }
        let dir = OutputDir::new(path);
        // `OUT/lidar_2d` given: the convert folder is its parent.
        let parent = path
            .file_name()
            .is_some_and(|n| n == layout::LIDAR_2D)
            .then(|| path.parent().map(OutputDir::new))
            .flatten()
            .filter(|p| p.summary_path().is_file());
        if let Some(out) = parent {
            return Self::from_npy(path, path.to_path_buf(), Some(out));
        }
        if dir.has_maps() && is_npy_folder(&dir.lidar_dir()) {
            return Self::from_npy(path, dir.lidar_dir(), Some(dir));
        }
        let shards = dir.shards()?;
        if !shards.is_empty() {
            return Self::from_shards(path, shards, Some(dir));
        }
        if is_npy_folder(path) {
            return Self::from_npy(path, path.to_path_buf(), None);
        }
        if let Ok(found) = discover_as(path, Some(DatasetKind::Sequence)) {
            return Self::from_dataset(path, found.drives);
        }
        if dir.points_dir().is_dir() {
            return Err(input("holds point shards only (points/: unprojected points); the reports read maps: convert to .npy maps or map shards too"));
        }
        Err(input("neither a convert output folder (lidar_2d/ or shards/), a folder of <frame id>.npy maps, nor shards (*.mcap)"))
    }

    fn from_npy(path: &Path, npy_dir: PathBuf, dir: Option<OutputDir>) -> Result<GroundTruth> {
        let frames: Vec<FrameId> = layout::list_npy_frames(&npy_dir)?
            .into_iter()
            .map(|(id, _)| id)
            .collect();
        let recorded = match &dir {
            Some(d) => summary::read(&d.summary_path())?.map(|s| (s.params.map, d.summary_path())),
            None => None,
        };
        let (params, provenance) = match recorded {
            Some((p, file)) => (p, Provenance::Recorded(file)),
            None => {
                let first = pgm::read(&layout::npy_path_in(&npy_dir, &frames[0]))?;
                let mut p = MapParams::default();
                p.spec.rows = first.rows;
                p.spec.cols = first.cols;
                p.rgb = first.channels.has_rgb().then_some(RgbOptions {
                    camera: 2,
                    sampling: Sampling::Nearest,
                });
                (p, Provenance::Assumed)
            }
        };
        Ok(GroundTruth {
            path: path.into(),
            source: Source::Npy(npy_dir),
            dir,
            params,
            provenance,
            frames,
            partial: None,
        })
    }

    fn from_shards(
        path: &Path,
        shards: Vec<PathBuf>,
        dir: Option<OutputDir>,
    ) -> Result<GroundTruth> {
        let mut params: Option<MapParams> = None;
        let mut frames = Vec::new();
        for s in &shards {
            let md = Shard::open_verified(s)?.metadata()?;
            if md.content == ShardKind::Points {
                return Err(Error::Input {
                    path: s.clone(),
                    message: "a point shard holds unprojected points; \
                              the reports read maps: give the map shards (OUT/shards), the .npy \
                              maps or the convert folder"
                        .into(),
                });
            }
            match &params {
                None => params = Some(md.params.map.clone()),
                Some(p) if *p != md.params.map => {
                    return Err(Error::Input {
                        path: s.clone(),
                        message: format!(
                            "made with other map parameters than {}",
                            shards[0].display()
                        ),
                    })
                }
                Some(_) => {}
            }
            frames.extend(md.frames.iter().filter(|f| !md.failed.contains(f)).cloned());
        }
        frames.sort();
        Ok(GroundTruth {
            path: path.into(),
            source: Source::Shards(shards.clone()),
            dir: dir.filter(|d| d.has_maps() || d.has_labels()),
            params: params.expect("at least one shard"),
            provenance: Provenance::Recorded(shards[0].clone()),
            frames,
            partial: None,
        })
    }

    fn from_dataset(path: &Path, drives: Vec<Drive>) -> Result<GroundTruth> {
        let mut frames = Vec::new();
        for d in &drives {
            for f in d.scan_frames()? {
                if d.has_labels(f) {
                    frames.push(d.frame_id(f));
                }
            }
        }
        if frames.is_empty() {
            return Err(Error::Input {
                path: path.into(),
                message: "a SemanticKITTI root without labels (sequences/<NN>/labels/*.label)"
                    .into(),
            });
        }
        frames.sort();
        // Labels `kitti2pgm label` wrote from boxes are read with the class map it recorded.
        let recorded =
            crate::format::box_labels::recorded_class_map(drives.iter().map(|d| d.dir.as_path()))?;
        let provenance = match &recorded {
            Some(_) => drives[0]
                .dir
                .join(crate::format::box_labels::BOX_LABELS_MARKER),
            None => path.join("semantic-kitti.yaml (embedded)"),
        };
        let params = MapParams {
            class_map: recorded.unwrap_or_else(ClassMap::semantic_kitti),
            ..MapParams::default()
        };
        Ok(GroundTruth {
            path: path.into(),
            source: Source::Dataset(drives),
            dir: None,
            params,
            provenance: Provenance::Recorded(provenance),
            frames,
            partial: None,
        })
    }

    /// A sentence saying where the map parameters come from (for a report's header).
    pub fn provenance_note(&self) -> String {
        let s = &self.params.spec;
        let partial = match &self.partial {
            Some(p) => format!("; PARTIAL: {p}"),
            None => String::new(),
        };
        let note = match &self.provenance {
            Provenance::Recorded(p) => format!("map parameters from {}", p.display()),
            Provenance::Assumed => format!(
                "{} records no conversion parameters: assuming SqueezeSeg's map ({}x{} over {} deg, rows from rings, classes {})",
                self.path.display(),
                s.rows,
                s.cols,
                s.fov.0,
                self.params.class_map.names().join("/")
            ),
        };
        note + &partial
    }

    /// Reads one frame from a `.npy` source.
    fn read_npy(&self, dir: &Path, id: &FrameId) -> Result<MapFrame> {
        let path = layout::npy_path_in(dir, id);
        let f = pgm::read(&path)?;
        let (spec, map) = (&self.params.spec, &self.params.class_map);
        let want = self.params.channels();
        if f.channels != want {
            return Err(Error::Length {
                path,
                what: "the map (mixed 6- and 9-channel outputs?)".into(),
                found: f.channels.len(),
                expected: want.len(),
                unit: "channels",
            });
        }
        if (f.rows, f.cols) != (spec.rows, spec.cols) {
            return Err(Error::Shape {
                path,
                what: "the map".into(),
                found: vec![f.rows, f.cols],
                expected: format!("{}x{}, the ground truth's", spec.rows, spec.cols),
            });
        }
        MapFrame::from_pgm(id.clone(), f, map, &path)
    }

    /// Applies `f` to every frame of the ground truth (or those in `only`, which must all be
    /// present), in parallel, and returns the results sorted by frame id. Memory holds one
    /// chunk of `.npy` frames, or one frame per shard being streamed, at a time.
    pub fn map_frames<T: Send>(
        &self,
        only: Option<&BTreeSet<FrameId>>,
        f: &(dyn Fn(MapFrame) -> Result<T> + Sync),
        progress: &(dyn Fn(u64) + Sync),
    ) -> Result<Vec<(FrameId, T)>> {
        if let Some(o) = only {
            let have: BTreeSet<&FrameId> = self.frames.iter().collect();
            if let Some(missing) = o.iter().find(|id| !have.contains(id)) {
                let n = o.iter().filter(|id| !have.contains(id)).count();
                return Err(Error::Input {
                    path: self.path.clone(),
                    message: format!(
                        "{n} listed frame(s) are not in the ground truth, first {missing}"
                    ),
                });
            }
        }
        let wanted = |id: &FrameId| only.is_none_or(|o| o.contains(id));
        let mut out: Vec<(FrameId, T)> = Vec::new();
        match &self.source {
            Source::Npy(dir) => {
                let ids: Vec<&FrameId> = self.frames.iter().filter(|id| wanted(id)).collect();
                for chunk in ids.chunks(64) {
                    let part: Vec<Result<(FrameId, T)>> = chunk
                        .par_iter()
                        .map(|id| {
                            let r = self.read_npy(dir, id).and_then(f);
                            progress(1);
                            r.map(|t| ((*id).clone(), t))
                        })
                        .collect();
                    for p in part {
                        out.push(p?);
                    }
                }
            }
            Source::Dataset(_) => {
                return Err(Error::Input {
                    path: self.path.clone(),
                    message: "a SemanticKITTI root holds per-point labels, not maps: convert it first (score reads it as it is)".into(),
                })
            }
            Source::Shards(shards) => {
                let parts: Vec<Result<Vec<(FrameId, T)>>> = shards
                    .par_iter()
                    .map(|path| self.map_shard(path, &wanted, f, progress))
                    .collect();
                for p in parts {
                    out.extend(p?);
                }
                out.sort_by(|a, b| a.0.cmp(&b.0));
            }
        }
        Ok(out)
    }

    fn map_shard<T>(
        &self,
        path: &Path,
        wanted: &dyn Fn(&FrameId) -> bool,
        f: &(dyn Fn(MapFrame) -> Result<T> + Sync),
        progress: &(dyn Fn(u64) + Sync),
    ) -> Result<Vec<(FrameId, T)>> {
        let spec = &self.params.spec;
        let map = &self.params.class_map;
        let shard = Shard::open(path)?;
        let mut out = Vec::new();
        for msg in shard.frame_iter() {
            let msg = msg?;
            let id: FrameId = msg.id.parse().map_err(|e: NotAFrameId| e.in_file(path))?;
            if !wanted(&id) {
                continue;
            }
            if (msg.height as usize, msg.width as usize) != (spec.rows, spec.cols) {
                return Err(Error::Shape {
                    path: path.into(),
                    what: format!("frame {id}"),
                    found: vec![msg.height as usize, msg.width as usize],
                    expected: format!("{}x{}, the ground truth's", spec.rows, spec.cols),
                });
            }
            for (i, (l, m)) in msg.label.iter().zip(&msg.mask).enumerate() {
                if *m != 0 {
                    map.check(*l as u64, path, || format!("frame {id}, cell {i}"))?;
                }
            }
            let frame = MapFrame {
                id: id.clone(),
                source: path.to_path_buf(),
                map: msg.into_frame(path)?,
            };
            out.push((id, f(frame)?));
            progress(1);
        }
        Ok(out)
    }
}
