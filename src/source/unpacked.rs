//! The marks an unpack leaves in a sequence folder it writes: `unpack.json` (a bag's) or
//! `nuscenes.json` (a nuScenes scene's), and the one `kitti2pgm label` leaves beside the labels
//! it writes from boxes (`box_labels.json`). Each is written with `complete: false` before the first
//! scan and again with `complete: true` after the last file, so a folder whose unpack was killed
//! or failed partway says so, and the readers refuse it ([`refuse_unfinished`]) instead of
//! taking a part of a recording for the whole.

use std::path::Path;

use serde::Deserialize;

use crate::error::{Error, Result};

/// A bag's unpack summary in its sequence folder.
pub const BAG_MARKER: &str = "unpack.json";
/// A nuScenes scene's index in its sequence folder.
pub const NUSCENES_MARKER: &str = "nuscenes.json";
/// The record `kitti2pgm label` leaves beside the labels it writes from boxes (its owner:
/// `format::box_labels`).
pub const BOX_LABELS_MARKER: &str = "box_labels.json";
/// The record `kitti2pgm infer --as-labels` leaves beside the label files it writes from a
/// model's predictions (its owner: `format::model_labels`).
pub const MODEL_LABELS_MARKER: &str = "model_labels.json";

/// The part of a mark the readers need.
#[derive(Deserialize)]
struct Mark {
    #[serde(default = "complete_by_default")]
    complete: bool,
}

/// The `complete` of a mark without one: an earlier version's, written only at the end (the
/// marks' serde default, here and in their writers' types).
pub fn complete_by_default() -> bool {
    true
}

/// An error when the sequence folder `seq` holds the mark of an unpack that did not finish
/// (or a mark that is not one: it names the file).
pub fn refuse_unfinished(seq: &Path) -> Result<()> {
    let unpack = "unpack the recording again with --overwrite";
    for (name, what, again) in [
        (BAG_MARKER, "unpack", unpack),
        (NUSCENES_MARKER, "unpack", unpack),
        (
            BOX_LABELS_MARKER,
            "label run",
            "run `kitti2pgm label` again",
        ),
        (
            MODEL_LABELS_MARKER,
            "infer --as-labels run",
            "run `kitti2pgm infer --as-labels` again with --overwrite",
        ),
    ] {
        let marker = seq.join(name);
        if !marker.is_file() {
            continue;
        }
        let text = crate::fs::read_text(&marker, crate::fs::Limit::Text)?;
        let mark: Mark = serde_json::from_str(&text)
            .map_err(|e| Error::format(&marker, format!("not an unpack's summary: {e}")))?;
        if !mark.complete {
            return Err(Error::UnfinishedUnpack {
                path: seq.into(),
                marker,
                what,
                again,
            });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_unfinished_mark_is_refused_and_an_old_one_is_complete() {
        let d = tempfile::tempdir().unwrap();
        assert!(refuse_unfinished(d.path()).is_ok());
        std::fs::write(d.path().join(BAG_MARKER), r#"{"topic": "/points"}"#).unwrap();
        assert!(refuse_unfinished(d.path()).is_ok());
        std::fs::write(d.path().join(NUSCENES_MARKER), r#"{"complete": false}"#).unwrap();
        let e = refuse_unfinished(d.path()).unwrap_err().to_string();
        assert!(
            e.contains("nuscenes.json") && e.contains("--overwrite"),
            "{e}"
        );
        std::fs::write(d.path().join(NUSCENES_MARKER), "{").unwrap();
        let e = refuse_unfinished(d.path()).unwrap_err().to_string();
        assert!(e.contains("nuscenes.json"), "{e}");
    }
}
