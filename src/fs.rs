//! File-system helpers shared by the readers and the writers.

use std::path::{Path, PathBuf};

use crate::error::{Error, Result};

/// The entries of a folder, sorted by path; errors name the folder.
pub fn sorted_dir(dir: &Path) -> Result<Vec<PathBuf>> {
    let mut out = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))? {
        out.push(entry.map_err(|e| Error::io(dir, e))?.path());
    }
    out.sort();
    Ok(out)
}

/// Whether something is at `path`: a file, or a link even when it leads nowhere (a dangling
/// link to a label file is then read, and its error names it, instead of the frame passing as
/// unlabelled).
pub fn present(path: &Path) -> bool {
    std::fs::symlink_metadata(path).is_ok()
}
