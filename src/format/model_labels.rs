//! `sequences/<NN>/model_labels.json`: the record `kitti2pgm infer --as-labels` leaves beside
//! the label files it writes from a model's predictions (pre-labels that a person corrects).
//! It names the model (its digest), the class map the files' raw ids are of, how the points got
//! their classes, and every file as written: a file whose content differs was edited since.
//!
//! Like `box_labels.json`, it is written with `complete: false` before the first label file and
//! with `complete: true` after the last, so an interrupted run says so.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::error::Result;
use crate::fs::Fingerprint;
use crate::label::ClassMap;
use crate::project::unproject::{KnnParams, Method, MethodKind};
use crate::source::kitti::sequence;

pub use crate::source::unpacked::MODEL_LABELS_MARKER;

/// The record's version.
pub const VERSION: u32 = 1;

/// How the points got their classes from the map, as recorded.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RecordedMethod {
    /// `cell` or `knn`.
    pub kind: MethodKind,
    /// The kNN's parameters (knn only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub knn: Option<KnnParams>,
}

impl From<&Method> for RecordedMethod {
    fn from(m: &Method) -> RecordedMethod {
        RecordedMethod {
            kind: m.kind(),
            knn: match m {
                Method::Cell => None,
                Method::Knn(p) => Some(*p),
            },
        }
    }
}

/// `model_labels.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ModelLabelRecord {
    /// [`VERSION`].
    pub version: u32,
    /// kitti2pgm's version.
    pub kitti2pgm: String,
    /// Whether the run finished (`false` while it writes).
    pub complete: bool,
    /// The model file, as given.
    pub model: PathBuf,
    /// Its content hash (`xxh3-128:...`).
    pub digest: String,
    /// What made the model (its record's `producer`).
    pub producer: String,
    /// The class map of the label files' raw ids (what `convert`, `check` and `score` read them
    /// with).
    pub class_map: ClassMap,
    /// How the points got their classes.
    pub method: RecordedMethod,
    /// What the model ran on (a dataset root or a bag), as given.
    pub input: PathBuf,
    /// Where the same predictions went in `score`'s layout (`infer --out`), when they did.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub predictions: Option<PathBuf>,
    /// The label files written, by frame name (`000042`), as written.
    pub frames: BTreeMap<String, Fingerprint>,
}

/// The record's path in sequence folder `seq`.
pub fn path(seq: &Path) -> PathBuf {
    seq.join(MODEL_LABELS_MARKER)
}

/// The record of sequence folder `seq`, if it has one.
pub fn read(seq: &Path) -> Result<Option<ModelLabelRecord>> {
    super::read_versioned(
        &path(seq),
        "a kitti2pgm model label record",
        VERSION,
        |r: &ModelLabelRecord| r.version,
    )
}

/// Writes `record` into sequence folder `seq`, atomically.
pub fn write(seq: &Path, record: &ModelLabelRecord, d: super::Durability) -> Result<()> {
    super::write_json(&path(seq), record, d)
}

/// The label file of frame `name` (`000042`) in sequence folder `seq`.
pub fn label_path(seq: &Path, name: &str) -> PathBuf {
    seq.join(sequence::LABELS).join(format!("{name}.label"))
}

/// What a sequence's model labels are now.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct LabelState {
    /// Frames whose file is as the model wrote it.
    pub unedited: Vec<String>,
    /// Frames whose file was changed since.
    pub edited: Vec<String>,
    /// Frames whose file is gone.
    pub missing: Vec<String>,
}

/// The first `shown` of `names` (frame names), and how many more, for a message.
pub fn frame_list(names: &[String], shown: usize) -> String {
    let mut s = names
        .iter()
        .take(shown)
        .cloned()
        .collect::<Vec<_>>()
        .join(", ");
    if names.len() > shown {
        s.push_str(&format!(" and {} more", names.len() - shown));
    }
    s
}

impl ModelLabelRecord {
    /// Compares every recorded file of sequence folder `seq` with what was written.
    pub fn state(&self, seq: &Path) -> Result<LabelState> {
        let mut s = LabelState::default();
        for (name, written) in &self.frames {
            match crate::fs::fingerprint(&label_path(seq, name))? {
                None => s.missing.push(name.clone()),
                Some(now) if now.same_content(written) => s.unedited.push(name.clone()),
                Some(_) => s.edited.push(name.clone()),
            }
        }
        Ok(s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record(frames: BTreeMap<String, Fingerprint>) -> ModelLabelRecord {
        ModelLabelRecord {
            version: VERSION,
            kitti2pgm: "test".into(),
            complete: true,
            model: "m.onnx".into(),
            digest: "xxh3-128:0".into(),
            producer: String::new(),
            class_map: ClassMap::semantic_kitti(),
            method: RecordedMethod::from(&Method::Knn(KnnParams::default())),
            input: "root".into(),
            predictions: None,
            frames,
        }
    }

    #[test]
    fn a_record_reads_back_and_tells_edited_missing_and_unedited_files() {
        let d = tempfile::tempdir().unwrap();
        let seq = d.path();
        std::fs::create_dir_all(seq.join(sequence::LABELS)).unwrap();
        let mut frames = BTreeMap::new();
        for name in ["000000", "000001", "000002"] {
            let p = label_path(seq, name);
            std::fs::write(&p, name.as_bytes()).unwrap();
            frames.insert(
                name.to_string(),
                crate::fs::fingerprint(&p).unwrap().unwrap(),
            );
        }
        let r = record(frames);
        write(seq, &r, super::super::Durability::Renamed).unwrap();
        assert_eq!(read(seq).unwrap(), Some(r.clone()));
        std::fs::write(label_path(seq, "000001"), b"corrected").unwrap();
        std::fs::remove_file(label_path(seq, "000002")).unwrap();
        let s = r.state(seq).unwrap();
        assert_eq!(s.unedited, ["000000"]);
        assert_eq!(s.edited, ["000001"]);
        assert_eq!(s.missing, ["000002"]);
        // Another version, or not a record: errors naming the file.
        std::fs::write(path(seq), b"{\"version\": 2}").unwrap();
        let e = read(seq).unwrap_err().to_string();
        assert!(e.contains(MODEL_LABELS_MARKER), "{e}");
        assert!(read(&seq.join("absent")).unwrap().is_none());
    }
}
