//! REPORT: a SemanticKITTI benchmark submission checked before it is uploaded, and packed.
//!
//! What semantic-kitti-api's `validate_submission.py` requires: every scan of the requested
//! sequences has `PRED/sequences/<NN>/predictions/<frame6>.label`, with exactly one entry per
//! point of the scan, each a raw id of the dataset's `learning_map` (low 16 bits; the high 16
//! bits, an instance, are allowed); nothing missing, nothing extra. Every problem is named.
//! [`write_zip`] packs a valid folder in the benchmark's layout (`sequences/<NN>/predictions/`
//! and `description.txt` at the root of the archive).

use std::io::Write;
use std::path::{Path, PathBuf};

use serde::Serialize;

use crate::error::{Error, Result};
use crate::format::label_file;
use crate::label::ClassMap;
use crate::source::kitti::{discover_as, DatasetKind, Drive};

/// One thing wrong with a submission.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Problem {
    /// The file or folder.
    pub path: PathBuf,
    /// What is wrong, with the numbers.
    pub problem: String,
}

/// The result of a check.
#[derive(Debug, Clone, Serialize)]
pub struct SubmissionCheck {
    /// The sequences checked.
    pub sequences: Vec<String>,
    /// Prediction files expected (one per scan).
    pub expected: u64,
    /// Of those, present and valid.
    pub valid: u64,
    /// Every problem, sorted by path.
    pub problems: Vec<Problem>,
    /// The valid prediction files as checked: (sequence, file, its size); what the archive
    /// packs, and nothing else.
    #[serde(skip)]
    pub checked: Vec<(String, PathBuf, u64)>,
}

impl SubmissionCheck {
    /// Whether the folder can be submitted as it is.
    pub fn is_valid(&self) -> bool {
        self.problems.is_empty()
    }
}

/// Checks the prediction folder `pred` against the SemanticKITTI root `root`, for `sequences`
/// (default: every sequence of the root), with the raw ids of `map`'s `learning_map`.
pub fn check_submission(
    pred: &Path,
    root: &Path,
    sequences: Option<&[u32]>,
    map: &ClassMap,
) -> Result<SubmissionCheck> {
    if map.learning_map.is_empty() {
        return Err(Error::Config(format!(
            "class map {:?} has no learning_map: a submission holds SemanticKITTI's raw ids",
            map.name
        )));
    }
    if !pred.is_dir() {
        return Err(Error::Input {
            path: pred.into(),
            message: "no such prediction folder (expected PRED/sequences/<NN>/predictions/)".into(),
        });
    }
    let drives = select_sequences(root, sequences)?;
    let mut problems = Vec::new();
    let mut checked = Vec::new();
    let (mut expected, mut valid) = (0u64, 0u64);
    let names: Vec<String> = drives.iter().map(|d| format!("{:02}", d.number)).collect();
    for (d, seq) in drives.iter().zip(&names) {
        let dir = crate::format::layout::sequence_predictions_dir(pred, seq);
        let scans = d.scan_frames()?;
        for &f in &scans {
            expected += 1;
            let file = dir.join(format!("{f:06}.label"));
            match check_file(&file, &d.scan_path(f), map) {
                Ok(size) => {
                    valid += 1;
                    checked.push((seq.clone(), file, size));
                }
                Err(problem) => problems.push(Problem {
                    path: file,
                    problem,
                }),
            }
        }
        if dir.is_dir() {
            problems.extend(extra_files(&dir, &scans)?);
        }
    }
    let seq_root = pred.join("sequences");
    if seq_root.is_dir() {
        for p in crate::fs::sorted_dir(&seq_root)? {
            let name = p.file_name().and_then(|n| n.to_str()).unwrap_or("");
            if !names.iter().any(|s| s == name) {
                problems.push(Problem {
                    path: p,
                    problem: format!(
                        "extra: not one of the sequences checked ({})",
                        names.join(", ")
                    ),
                });
            }
        }
    }
    problems.sort_by(|a, b| a.path.cmp(&b.path));
    Ok(SubmissionCheck {
        sequences: names,
        expected,
        valid,
        problems,
        checked,
    })
}

/// The sequences of `root` to check: `sequences`, each of which must be there, or all.
fn select_sequences(root: &Path, sequences: Option<&[u32]>) -> Result<Vec<Drive>> {
    let all = discover_as(root, Some(DatasetKind::Sequence))?.drives;
    let Some(want) = sequences else {
        return Ok(all);
    };
    let mut seen = std::collections::BTreeSet::new();
    if let Some(twice) = want.iter().find(|n| !seen.insert(**n)) {
        return Err(Error::Config(format!(
            "sequence {twice:02} is asked for twice"
        )));
    }
    want.iter()
        .map(|&n| {
            all.iter()
                .find(|d| d.number == n)
                .cloned()
                .ok_or_else(|| Error::Input {
                    path: root.into(),
                    message: format!("no sequence {n:02} here"),
                })
        })
        .collect()
}

/// The files of a prediction folder that are not the prediction of one of its sequence's
/// `scans` (sorted frame numbers).
fn extra_files(dir: &Path, scans: &[u32]) -> Result<Vec<Problem>> {
    let mut extra = Vec::new();
    for p in crate::fs::sorted_dir(dir)? {
        let frame = p
            .file_name()
            .and_then(|n| n.to_str())
            .and_then(|n| n.strip_suffix(".label"))
            .filter(|s| s.len() == 6)
            .and_then(|s| s.parse::<u32>().ok());
        if frame.is_none_or(|f| scans.binary_search(&f).is_err()) {
            extra.push(Problem {
                path: p,
                problem: "extra: not the prediction of a scan of this sequence".into(),
            });
        }
    }
    Ok(extra)
}

/// What is wrong with one prediction file, if anything; its size when nothing is.
fn check_file(file: &Path, scan: &Path, map: &ClassMap) -> std::result::Result<u64, String> {
    let meta = match std::fs::metadata(file) {
        Ok(m) => m,
        Err(_) => {
            return Err(format!(
                "missing (the scan {} has no prediction)",
                scan.display()
            ))
        }
    };
    // A KITTI .bin by its size, a PCD by its header.
    let points = crate::source::points_in_file(scan)
        .ok_or_else(|| format!("its scan {} cannot be read as a scan", scan.display()))?;
    if meta.len() % 4 != 0 || meta.len() / 4 != points {
        return Err(format!(
            "{} bytes: {} labels for the {points} points of {}",
            meta.len(),
            meta.len() as f64 / 4.0,
            scan.display()
        ));
    }
    let raw = label_file::read_raw(file).map_err(|e| e.to_string())?;
    let bad: Vec<(usize, u32)> = raw
        .iter()
        .enumerate()
        .filter(|(_, v)| map.class_of_raw(**v & 0xFFFF).is_none())
        .map(|(i, v)| (i, *v & 0xFFFF))
        .collect();
    if let Some(&(i, v)) = bad.first() {
        return Err(format!(
            "{} labels are not raw ids of the dataset's learning_map (first: point {i}, id {v})",
            bad.len()
        ));
    }
    Ok(meta.len())
}

/// Packs the checked, valid submission `pred` into a zip archive at `zip_path` (written
/// atomically): `sequences/<NN>/predictions/<frame6>.label` of the checked sequences and
/// `description.txt` with `description`.
pub fn write_zip(
    pred: &Path,
    check: &SubmissionCheck,
    zip_path: &Path,
    description: &str,
) -> Result<()> {
    if !check.is_valid() {
        return Err(Error::Input {
            path: pred.into(),
            message: format!("{} problems: not packed", check.problems.len()),
        });
    }
    crate::fs::refuse_overlap(zip_path, &[(crate::fs::Role::Predictions, pred)])?;
    let dir = zip_path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let werr = |source: std::io::Error| Error::Write {
        path: zip_path.into(),
        source,
    };
    let zerr = |e: zip::result::ZipError| werr(std::io::Error::other(e));
    let tmp = crate::format::temp_builder()
        .tempfile_in(dir)
        .map_err(|source| Error::Write {
            path: dir.into(),
            source,
        })?;
    let mut z = zip::ZipWriter::new(tmp.as_file());
    let options = zip::write::SimpleFileOptions::default()
        .compression_method(zip::CompressionMethod::Deflated);
    z.start_file("description.txt", options).map_err(zerr)?;
    z.write_all(description.as_bytes()).map_err(werr)?;
    // Exactly the files checked, as checked: a file that changed since is not packed.
    for (seq, p, size) in &check.checked {
        let name = p.file_name().and_then(|n| n.to_str()).unwrap_or_default();
        z.start_file(format!("sequences/{seq}/predictions/{name}"), options)
            .map_err(zerr)?;
        let bytes = crate::fs::read(p, crate::fs::Limit::Data)?;
        if bytes.len() as u64 != *size {
            return Err(Error::Length {
                path: p.clone(),
                what: "the prediction (changed since it was checked)".into(),
                found: bytes.len(),
                expected: *size as usize,
                unit: "bytes",
            });
        }
        z.write_all(&bytes).map_err(werr)?;
    }
    z.finish().map_err(zerr)?;
    tmp.persist(zip_path).map_err(|e| werr(e.error))?;
    Ok(())
}
