//! `infer --as-labels ROOT`: the predictions as a sequence root's label files
//! (`ROOT/sequences/<NN>/labels/<frame6>.label`, SemanticKITTI's raw ids through the model's
//! class map, instance 0), pre-labels that a person corrects, with the record
//! `model_labels.json` ([`crate::format::model_labels`]) naming the model and every file as
//! written.
//!
//! Never over labels that are there: a sequence whose labels are the dataset's own (or
//! `kitti2pgm label`'s) is refused whatever the options; one whose labels an earlier `infer`
//! wrote is replaced only with `overwrite`, and then only when none of its files was edited.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::format::model_labels::{self as record, ModelLabelRecord, MODEL_LABELS_MARKER};
use crate::format::{label_file, Durability};
use crate::fs::Fingerprint;
use crate::label::{ClassId, ClassMap};
use crate::source::kitti::{sequence, DatasetKind, FrameId};

/// The label files of one run, being written.
pub struct AsLabels {
    root: PathBuf,
    durability: Durability,
    records: BTreeMap<u32, ModelLabelRecord>,
}

/// The sequence folder of number `n` under `root`.
fn seq_dir(root: &Path, n: u32) -> PathBuf {
    sequence::sequence_dir(root, n)
}

impl AsLabels {
    /// Checks that the sequences `numbers` of `root` can take the model's labels (see the
    /// module), removes an earlier run's files with `overwrite`, and starts each sequence's
    /// record (`complete: false`) from `template`.
    pub fn begin(
        root: &Path,
        numbers: &[u32],
        template: &ModelLabelRecord,
        overwrite: bool,
        durability: Durability,
    ) -> Result<AsLabels> {
        for &n in numbers {
            refuse_or_clear(&seq_dir(root, n), overwrite)?;
        }
        let mut records = BTreeMap::new();
        for &n in numbers {
            let seq = seq_dir(root, n);
            crate::format::create_dir(&seq.join(sequence::LABELS))?;
            record::write(&seq, template, durability)?;
            records.insert(n, template.clone());
        }
        Ok(AsLabels {
            root: root.into(),
            durability,
            records,
        })
    }

    /// Writes frame `id`'s label file (any thread); returns what to [`AsLabels::record`].
    pub fn write(
        &self,
        id: &FrameId,
        per_point: &[Option<ClassId>],
        map: &ClassMap,
    ) -> Result<(u32, String, Fingerprint)> {
        debug_assert_eq!(id.dataset, DatasetKind::Sequence);
        let (entries, _) = label_file::encode_predictions(id, per_point, map);
        let bytes = label_file::encode_raw(&entries);
        let name = id.frame_name();
        let path = record::label_path(&seq_dir(&self.root, id.drive), &name);
        crate::format::atomic_write(&path, &bytes, self.durability)?;
        let hash = xxhash_rust::xxh3::xxh3_64(&bytes);
        let fp = Fingerprint::of_written(&path, bytes.len() as u64, hash)?;
        Ok((id.drive, name, fp))
    }

    /// Records a file [`AsLabels::write`] wrote.
    pub fn record(&mut self, (seq, name, fp): (u32, String, Fingerprint)) {
        if let Some(r) = self.records.get_mut(&seq) {
            r.frames.insert(name, fp);
        }
    }

    /// Writes every sequence's record, complete.
    pub fn finish(self) -> Result<()> {
        for (n, mut r) in self.records {
            r.complete = true;
            record::write(&seq_dir(&self.root, n), &r, self.durability)?;
        }
        Ok(())
    }
}

/// With `--overwrite`: removes what interrupted `--as-labels` runs left in the sequences of
/// `root` (their label files and records: such a record is written before its first file, over a
/// folder that held no labels of another kind), so that the readers, which refuse an unfinished
/// run, read the root again. Returns the sequence folders cleared.
pub fn clear_unfinished(root: &Path) -> Result<Vec<PathBuf>> {
    let seqs = root.join(sequence::SEQUENCES);
    if !seqs.is_dir() {
        return Ok(Vec::new());
    }
    let mut cleared = Vec::new();
    for seq in crate::fs::sorted_dir(&seqs)? {
        let Some(rec) = (record::read(&seq).ok()).flatten() else {
            continue;
        };
        if rec.complete {
            continue;
        }
        clear_sequence(&seq)?;
        cleared.push(seq);
    }
    Ok(cleared)
}

/// Removes an interrupted run's label files (every one in the folder) and its record.
fn clear_sequence(seq: &Path) -> Result<()> {
    let labels = seq.join(sequence::LABELS);
    if labels.is_dir() {
        for f in crate::fs::sorted_dir(&labels)? {
            if f.extension().is_some_and(|e| e == "label") {
                std::fs::remove_file(&f).map_err(|e| Error::io(&f, e))?;
            }
        }
    }
    let marker = record::path(seq);
    std::fs::remove_file(&marker).map_err(|e| Error::io(&marker, e))
}

/// Refuses a sequence folder whose labels are not an earlier run's, or are and `overwrite` is
/// not given, or were edited; with `overwrite`, removes the earlier run's files.
fn refuse_or_clear(seq: &Path, overwrite: bool) -> Result<()> {
    let labels = seq.join(sequence::LABELS);
    let earlier = record::read(seq)?;
    let Some(earlier) = earlier else {
        if crate::fs::present(&crate::format::box_labels::path(seq))
            || crate::format::box_labels::has_label_files(seq)
        {
            return Err(Error::Config(format!(
                "{}: holds labels that are not a model's (the dataset's own, or `kitti2pgm \
                 label`'s): --as-labels never writes there; give it another root",
                labels.display()
            )));
        }
        return Ok(());
    };
    let marker = seq.join(MODEL_LABELS_MARKER);
    if !overwrite {
        return Err(Error::Config(format!(
            "{}: holds {} label files the model {} wrote ({}): replace them with --overwrite",
            labels.display(),
            earlier.frames.len(),
            earlier.model.display(),
            marker.display()
        )));
    }
    let state = earlier.state(seq)?;
    if !state.edited.is_empty() {
        return Err(Error::Config(format!(
            "{}: {} of the model's label files were edited since (frames {}): --overwrite \
             replaces no edited label; move them away first",
            labels.display(),
            state.edited.len(),
            record::frame_list(&state.edited, 5)
        )));
    }
    if !earlier.complete {
        return clear_sequence(seq);
    }
    for name in &state.unedited {
        let f = record::label_path(seq, name);
        std::fs::remove_file(&f).map_err(|e| Error::io(&f, e))?;
    }
    Ok(())
}
