//! REPORT input, checked: whether converted ground truth is one whole conversion.
//!
//! A reader refuses (by default) the frames of a conversion that did not finish (its
//! `convert_summary.json` says `complete: false`), maps that the conversion's journal does not
//! list (copied in, or left by another run), and a frame that two shards hold (shards of two
//! conversions); [`Completeness::AllowPartial`] reads them anyway and the report says so.

use std::path::{Path, PathBuf};

use super::{GroundTruth, Source};
use crate::error::Result;
use crate::format::journal::{self, JOURNAL_FILE};
use crate::format::layout::{self, OutputDir};
use crate::format::shard::Shard;
use crate::format::summary;
use crate::source::kitti::FrameId;

/// Whether a reader accepts the output of an unfinished (running, killed) conversion.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Completeness {
    /// Refuse it, naming what is missing (the default).
    #[default]
    Require,
    /// Read what is there, and say so ([`GroundTruth::partial`]).
    AllowPartial,
}

/// The convert folder the frames belong to: `dir` itself, or the folder above a given
/// `lidar_2d`, `shards` or `points` folder or shard.
fn convert_folder(gt: &GroundTruth) -> Option<OutputDir> {
    let mut candidates: Vec<PathBuf> = gt.dir.iter().map(|d| d.root.clone()).collect();
    let mut p = gt.path.clone();
    if p.is_file() {
        p.pop();
    }
    candidates.push(p.clone());
    if p.file_name()
        .is_some_and(|n| n == layout::LIDAR_2D || n == layout::SHARDS || n == layout::POINTS)
    {
        candidates.extend(p.parent().map(Path::to_path_buf));
    }
    candidates
        .into_iter()
        .map(OutputDir::new)
        .find(|d| d.summary_path().is_file())
}

/// What makes the frames an incomplete or inconsistent conversion, if anything: a summary
/// that says the run did not finish, maps the conversion's journal does not list, a frame
/// in two shards.
pub(crate) fn problem(gt: &GroundTruth) -> Result<Option<String>> {
    // The shards' frames are already listed (sorted) in `gt.frames`: a frame twice there is in
    // two shards; only then are the shards read again, to name both.
    if let (Source::Shards(shards), Some(twice)) = (
        &gt.source,
        gt.frames.windows(2).find(|w| w[0] == w[1]).map(|w| &w[0]),
    ) {
        let name = twice.to_string();
        let mut holders = Vec::new();
        for s in shards {
            let md = Shard::open(s)?.metadata()?;
            if md.frames.contains(twice) && !md.failed.contains(twice) {
                holders.push(s.display().to_string());
            }
        }
        return Ok(Some(format!(
            "frame {name} is in two shards, {} (shards of two conversions?)",
            holders.join(" and ")
        )));
    }
    let Some(dir) = convert_folder(gt) else {
        return Ok(None);
    };
    if let Some(s) = summary::read(&dir.summary_path())? {
        if !s.complete {
            return Ok(Some(format!(
                "the conversion into {} did not finish ({}: complete false): {} of its {} planned frames are here",
                dir.root.display(),
                layout::SUMMARY_FILE,
                gt.frames.len(),
                s.frames_planned
            )));
        }
    }
    if let (Source::Npy(_), Some(j)) = (&gt.source, journal::read(&dir.root.join(JOURNAL_FILE))?) {
        let stray: Vec<&FrameId> = gt.frames.iter().filter(|f| !j.lists(f)).collect();
        if let Some(first) = stray.first() {
            return Ok(Some(format!(
                "{} of the {} maps (first: {first}) were not made by the conversion recorded in {} (copied in, or left by another run)",
                stray.len(),
                gt.frames.len(),
                JOURNAL_FILE
            )));
        }
    }
    Ok(None)
}
