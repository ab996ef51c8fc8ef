//! WRITE, and the one owner of every file kind the tool writes or reads back.
//!
//! Each module owns one kind of file, both directions; nothing else builds a path, an encoding or
//! a decoder for it:
//!
//! | module | file |
//! |---|---|
//! | [`npy`] | `.npy` arrays (NumPy format 1.0), any numeric dtype in, float32 out |
//! | [`pgm`] | a converted frame as `.npy` (SqueezeSeg's H x W x 6/9 layout, named channels) |
//! | [`box_labels`] | `sequences/<NN>/box_labels.json`: what `label` made its label files from |
//! | [`model_labels`] | `sequences/<NN>/model_labels.json`: the model `infer --as-labels` made its label files with |
//! | [`label_file`] | per-point `.label` files (u32: class, instance << 16) |
//! | [`layout`] | the output folder: paths, discovery of converted frames and shards |
//! | [`summary`] | `convert_summary.json`, with the typed [`ConvertParams`](crate::provenance::ConvertParams) |
//! | [`imageset`] | `ImageSet/*.txt` frame lists |
//! | [`journal`] | `OUT/.kitti2pgm-frames`, the provenance journal: parameters, dataset root, each frame's inputs |
//! | [`shard`] | MCAP training and prediction shards (records, write, read, viz topics) |
//! | [`png`] | PNG pictures |
//!
//! Every output is first written to a temporary file in the destination folder and renamed into
//! place, so a crash or a full disk never leaves a half-written file under a final name.

pub mod box_labels;
pub mod imageset;
pub mod journal;
pub mod label_file;
pub mod layout;
pub mod model_labels;
pub mod npy;
pub mod pgm;
pub mod png;
pub mod shard;
pub mod summary;

use std::io::Write;
use std::path::Path;

use crate::error::{Error, Result};

/// How far an output is taken before its writer returns.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum Durability {
    /// Written to a temporary file and renamed into place: whole or absent whatever happens to
    /// the process.
    #[default]
    Renamed,
    /// Also flushed to the device before the rename, so that it survives a power cut as well (a
    /// disk round trip per file).
    Synced,
}

impl Durability {
    /// Flushes `file` to the device when that is asked for.
    pub fn flush(self, file: &std::fs::File) -> std::io::Result<()> {
        match self {
            Durability::Renamed => Ok(()),
            Durability::Synced => file.sync_data(),
        }
    }
}

/// Writes `bytes` to `path` atomically (temporary file in the same folder, then rename), flushed
/// to the device first when `durability` says so.
///
/// The rename makes the file appear whole or not at all, whatever happens to the process.
pub fn atomic_write(path: &Path, bytes: &[u8], durability: Durability) -> Result<()> {
    atomic_write_parts(path, &[bytes], durability)
}

/// [`atomic_write`] of the concatenation of `parts` (a header and a large body, without copying
/// them into one buffer first).
pub fn atomic_write_parts(path: &Path, parts: &[&[u8]], durability: Durability) -> Result<()> {
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let werr = |source| Error::Write {
        path: path.into(),
        source,
    };
    let mut tmp = temp_builder()
        .tempfile_in(dir)
        .map_err(|source| Error::Write {
            path: dir.into(),
            source,
        })?;
    for part in parts {
        tmp.write_all(part).map_err(werr)?;
    }
    durability.flush(tmp.as_file()).map_err(werr)?;
    tmp.persist(path).map_err(|e| werr(e.error))?;
    Ok(())
}

/// A temporary-file builder for outputs: hidden `.tmp-` name, and on Unix the mode of an
/// ordinary new file (0666 less the umask) instead of tempfile's private 0600, so that the file
/// keeps normal permissions once renamed into place.
pub fn temp_builder() -> tempfile::Builder<'static, 'static> {
    let mut b = tempfile::Builder::new();
    b.prefix(".tmp-");
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        b.permissions(std::fs::Permissions::from_mode(0o666));
    }
    b
}

/// Creates a folder and its parents, naming it in the error.
pub fn create_dir(path: &Path) -> Result<()> {
    std::fs::create_dir_all(path).map_err(|source| Error::Write {
        path: path.into(),
        source,
    })
}

/// The JSON record at `path` (`None` when there is none), parsed as `format` and of `version`
/// (`version_of` reads it): the one reader of the records kept beside a sequence's labels.
pub(crate) fn read_versioned<T: serde::de::DeserializeOwned>(
    path: &Path,
    format: &'static str,
    version: u32,
    version_of: impl Fn(&T) -> u32,
) -> Result<Option<T>> {
    if !crate::fs::present(path) {
        return Ok(None);
    }
    let text = crate::fs::read_text(path, crate::fs::Limit::Text)?;
    let record: T = serde_json::from_str(&text).map_err(|e| Error::NotFormat {
        path: path.into(),
        format,
        detail: e.to_string(),
    })?;
    let found = version_of(&record);
    if found != version {
        return Err(Error::format(
            path,
            format!("record version {found} (this kitti2pgm writes {version})"),
        ));
    }
    Ok(Some(record))
}

/// Writes a JSON record to `path`, pretty-printed, atomically.
pub(crate) fn write_json<T: serde::Serialize>(
    path: &Path,
    record: &T,
    d: Durability,
) -> Result<()> {
    let json = serde_json::to_vec_pretty(record).expect("a record serialises");
    atomic_write(path, &json, d)
}
