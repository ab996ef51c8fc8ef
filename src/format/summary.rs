//! WRITE and read back `convert_summary.json`: what a conversion made, and how.
//!
//! The summary carries the typed [`ConvertParams`] under `params` (map, class map, colour,
//! selection, outputs, shards), so that the reports read the map back exactly; the totals are
//! keyed by class name. Keys are documented in `docs/conventions.md`.

use std::collections::BTreeMap;
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::plan::{FrameFailure, Reconverted, Restart, SkipReason};
use crate::project::ProjectionStats;
use crate::provenance::ConvertParams;

/// Totals of a conversion.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct ConvertSummary {
    /// kitti2pgm version that wrote the files.
    pub version: String,
    /// What was asked for.
    pub params: ConvertParams,
    /// Whether the run finished: a summary with `false` was written when a run started and
    /// the run did not end (it was interrupted); the next run resumes it.
    pub complete: bool,
    /// Frames left as an earlier run with the same parameters wrote them (resumed run). The
    /// totals below (points, cells, collisions...) cover the frames converted by this run only.
    pub resumed_frames: u64,
    /// Temporary files of an interrupted run removed before converting.
    pub leftovers_removed: u64,
    /// Converted files of an earlier run with other parameters (or of any earlier run, with
    /// `--overwrite`) removed before converting, so that the folder holds one conversion.
    #[serde(default)]
    pub stale_removed: u64,
    /// Why every converted output of an earlier run was removed first (absent: the earlier
    /// run, if any, was continued).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub restarted: Option<Restart>,
    /// Frames an earlier run had finished that this run converted again, by why.
    #[serde(default)]
    pub reconverted: BTreeMap<Reconverted, u64>,
    /// The inputs found changed since the earlier run (paths relative to the dataset root, with
    /// what changed), sorted.
    #[serde(default)]
    pub changed_inputs: Vec<String>,
    /// The dataset the frames come from (its layout).
    #[serde(default)]
    pub source: crate::source::kitti::DatasetKind,
    /// How the map was chosen: the preset, why (asked for, or the source's default) and the
    /// values given on their own (`preset full (the default for SemanticKITTI)`).
    #[serde(default, deserialize_with = "origin_or_empty")]
    pub map_origin: Option<crate::project::MapOrigin>,
    /// Drives (sequences, object splits) found.
    pub drives: u64,
    /// Frames the run set out to convert (converted, kept, or failed at the end).
    #[serde(default)]
    pub frames_planned: u64,
    /// Frames converted and written.
    pub frames_converted: u64,
    /// Frames that failed (a failed drive counts all its scans).
    pub frames_failed: u64,
    /// Frames left out by the selection, by reason.
    pub frames_skipped: BTreeMap<SkipReason, u64>,
    /// Each failure, sorted by frame id.
    pub failures: Vec<FrameFailure>,
    /// Files in velodyne folders that are not scans (skipped).
    pub not_frames: Vec<String>,
    /// Label files that belong to no scan (SemanticKITTI `labels/`, object `label_2/`): not
    /// read; a scan may be missing.
    #[serde(default)]
    pub labels_without_scan: Vec<String>,
    /// Tracklets of an object type KITTI does not define, by type (labelled as the class map
    /// says: background unless it lists the type).
    pub unknown_object_types: BTreeMap<String, u64>,
    /// Frames converted without labels (SemanticKITTI test sequences, object `testing/`):
    /// every point has the class map's background class.
    pub frames_without_labels: u64,
    /// Finite points read.
    pub points: u64,
    /// Non-finite points dropped.
    pub dropped_nonfinite: u64,
    /// Points beyond `kitti::velodyne::MAX_RANGE_M` dropped.
    pub dropped_out_of_range: u64,
    /// Points per class, by class name.
    pub labelled_points: BTreeMap<String, u64>,
    /// Valid cells per class, by class name.
    pub labelled_cells: BTreeMap<String, u64>,
    /// Projection counts (points in the field of view, filled and total cells, collisions,
    /// frames binned by elevation).
    #[serde(flatten)]
    pub projection: ProjectionStats,
    /// Ids of the frames binned by elevation (sorted).
    pub fallback_frames: Vec<String>,
    /// Another sensor's conversion: the ids of the frames whose rows came from the sensor's beam
    /// table (sorted); the other frames' came from their ring field.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub beam_table_frame_ids: Vec<String>,
    /// Cells with a colour.
    pub rgb_cells: u64,
    /// Shards written.
    pub shards_written: u64,
    /// Shards left as they were (complete, intact, same frames and parameters).
    pub shards_skipped: u64,
}

impl ConvertSummary {
    /// Whether something was lost: a failed frame, drive or folder. The CLI then exits with 3,
    /// or 1 when nothing at all was converted.
    pub fn has_failures(&self) -> bool {
        self.frames_failed > 0 || !self.failures.is_empty()
    }

    /// Filled cells over all cells.
    pub fn fill_ratio(&self) -> f64 {
        self.projection.fill_ratio()
    }
}

/// A map origin, or `None` for an absent, null or empty one (a summary of a map given directly).
fn origin_or_empty<'de, D: serde::Deserializer<'de>>(
    d: D,
) -> std::result::Result<Option<crate::project::MapOrigin>, D::Error> {
    match Option::<String>::deserialize(d)? {
        Some(s) if !s.is_empty() => s.parse().map(Some).map_err(serde::de::Error::custom),
        _ => Ok(None),
    }
}

/// Writes the summary to `path`, atomically.
pub fn write(path: &Path, summary: &ConvertSummary, durability: super::Durability) -> Result<()> {
    let json = serde_json::to_vec_pretty(summary).expect("the summary serialises");
    super::atomic_write(path, &json, durability)
}

/// Reads the summary at `path`; `Ok(None)` when there is no such file.
pub fn read(path: &Path) -> Result<Option<ConvertSummary>> {
    if !crate::fs::present(path) {
        return Ok(None);
    }
    let text = crate::fs::read_text(path, crate::fs::Limit::Text)?;
    serde_json::from_str(&text)
        .map(Some)
        .map_err(|e| Error::NotFormat {
            path: path.into(),
            format: concat!(
                "a kitti2pgm ",
                env!("CARGO_PKG_VERSION"),
                " conversion summary"
            ),
            detail: e.to_string(),
        })
}
