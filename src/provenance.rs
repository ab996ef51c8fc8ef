//! Provenance: the parameters a conversion was made with, as one typed value.
//!
//! [`ConvertParams`] is what `convert` is asked to do, and it travels with what it writes: into
//! `convert_summary.json` ([`crate::format::summary`]) and into every shard's metadata
//! ([`crate::format::shard::metadata`]), and it is read back typed by the reports
//! ([`crate::report::truth::GroundTruth`]), so that `score` and `stats` never guess the map.

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::label::ClassMap;
use crate::plan::selection::FrameSelection;
use crate::plan::split::SplitRule;
use crate::project::camera::RgbOptions;
use crate::project::{Channels, PgmSpec};

/// What every converted frame's content depends on.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MapParams {
    /// Map shape, field of view and row rule.
    pub spec: PgmSpec,
    /// Colour channels, when sampled.
    pub rgb: Option<RgbOptions>,
    /// Which frames are converted.
    pub selection: FrameSelection,
    /// The classes and how they are labelled.
    pub class_map: ClassMap,
    /// The sensor model that decides the rows of another sensor's scans (`--sensor`,
    /// `--sensor-calibration`); `None`: KITTI's HDL-64E, rows from the scan order.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sensor: Option<crate::sensor::SensorParams>,
}

impl Default for MapParams {
    /// SqueezeSeg's: 64 x 512 over the front 90 degrees, rings, no colour, annotated frames,
    /// the paper's 4 classes.
    fn default() -> Self {
        MapParams {
            spec: PgmSpec::default(),
            rgb: None,
            selection: FrameSelection::Annotated,
            class_map: ClassMap::kitti_paper(),
            sensor: None,
        }
    }
}

impl MapParams {
    /// The channels of the `.npy` maps these parameters make.
    pub fn channels(&self) -> Channels {
        Channels::npy(self.rgb.is_some())
    }

    /// Checks the map and the class map.
    pub fn validate(&self) -> Result<()> {
        self.spec.validate()?;
        self.class_map.validate()?;
        if let Some(sensor) = &self.sensor {
            sensor.check_map(self.spec.cols, self.spec.fov)?;
        }
        if let Some(rgb) = &self.rgb {
            if !(rgb.camera == 2 || rgb.camera == 3) {
                return Err(Error::Config(format!(
                    "camera {} has no colour; use 2 or 3",
                    rgb.camera
                )));
            }
        }
        Ok(())
    }
}

/// Chunk compression of shards.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ShardCompression {
    /// lz4 (default): fast to read.
    #[default]
    Lz4,
    /// zstd: smaller, slower to write.
    Zstd,
    /// No compression.
    None,
}

crate::named_enum!(ShardCompression, "compression", [
    Lz4 => "lz4" [] "lz4: fast to read",
    Zstd => "zstd" [] "zstd: smaller",
    None => "none" [] "none",
]);

/// What a shard holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ShardKind {
    /// Projected maps, one `kitti2pgm.Frame` per frame (`--format mcap`, under `OUT/shards`).
    #[default]
    Maps,
    /// Unprojected points, one `kitti2pgm.Points` per frame (`--format points`, under `OUT/points`).
    Points,
}

crate::named_enum!(ShardKind, "shard content", [
    Maps => "maps" [] "projected maps, one kitti2pgm.Frame per frame (OUT/shards)",
    Points => "points" [] "unprojected points, one kitti2pgm.Points per frame (OUT/points)",
]);

/// MCAP shard output (`--format mcap`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ShardParams {
    /// Chunk compression.
    pub compression: ShardCompression,
    /// Frames per shard; `None` sizes shards to about [`SHARD_TARGET_BYTES`] of uncompressed data.
    pub frames_per_shard: Option<usize>,
    /// Add Foxglove visualisation topics.
    pub viz: bool,
    /// Which drives go to val (the same rule as `kitti2pgm split`).
    pub split: SplitRule,
}

/// Uncompressed bytes a shard is sized to when `--shard-frames` is not given.
pub const SHARD_TARGET_BYTES: usize = 256 << 20;

impl ShardParams {
    /// Frames per shard for a map of `spec`, with or without colour.
    pub fn frames_per_shard(&self, spec: &PgmSpec, rgb: bool) -> usize {
        self.frames_per_shard.unwrap_or_else(|| {
            // tensor (5 or 8 float32) + label + instance (2) + mask (+ rgb_valid), per cell.
            let per_cell = if rgb { 8 * 4 + 5 } else { 5 * 4 + 4 };
            (SHARD_TARGET_BYTES / (spec.cells() * per_cell)).max(1)
        })
    }
}

impl ShardParams {
    /// Frames per point shard, with or without colour (about 125,000 points a scan: x, y, z,
    /// intensity, ring, label, instance, file index, and r, g, b with its flag).
    pub fn frames_per_point_shard(&self, rgb: bool) -> usize {
        self.frames_per_shard.unwrap_or_else(|| {
            let per_point = if rgb { 24 + 13 } else { 24 };
            (SHARD_TARGET_BYTES / (125_000 * per_point)).max(1)
        })
    }
}

/// Everything a conversion is asked to make.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct ConvertParams {
    /// The maps.
    pub map: MapParams,
    /// `lidar_2d/<id>.npy` written.
    pub npy: bool,
    /// `labels/<drive>/<frame>.label` written.
    pub labels: bool,
    /// Map shards written (`OUT/shards`).
    pub shards: Option<ShardParams>,
    /// Point shards written (`OUT/points`).
    #[serde(default)]
    pub point_shards: Option<ShardParams>,
}

impl ConvertParams {
    /// Defaults: SqueezeSeg's maps, `.npy` and `.label` outputs, no shards.
    pub fn squeezeseg() -> ConvertParams {
        ConvertParams {
            map: MapParams::default(),
            npy: true,
            labels: true,
            shards: None,
            point_shards: None,
        }
    }

    /// The parameters of the shards of `kind`, if they are written.
    pub fn shards_of(&self, kind: ShardKind) -> Option<&ShardParams> {
        match kind {
            ShardKind::Maps => self.shards.as_ref(),
            ShardKind::Points => self.point_shards.as_ref(),
        }
    }

    /// Checks the parameters.
    pub fn validate(&self) -> Result<()> {
        self.map.validate()?;
        if !self.npy && !self.labels && self.shards.is_none() && self.point_shards.is_none() {
            return Err(Error::Config(
                "nothing to write: enable .npy, .label or shard output".into(),
            ));
        }
        let zero =
            |s: &Option<ShardParams>| s.as_ref().is_some_and(|s| s.frames_per_shard == Some(0));
        if zero(&self.shards) || zero(&self.point_shards) {
            return Err(Error::Config(
                "shards need at least 1 frame each (frames per shard: 0)".into(),
            ));
        }
        if self.point_shards.is_some() && self.map.sensor.as_ref().is_some_and(|s| s.ouster_columns)
        {
            return Err(Error::Config(
                "point shards carry each point's beam row, not Ouster's columns: the trainer \
                 projects them by azimuth; use --format npy or mcap with Ouster columns"
                    .into(),
            ));
        }
        Ok(())
    }
}
