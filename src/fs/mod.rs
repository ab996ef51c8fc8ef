//! File-system helpers shared by the readers and the writers.
//!
//! Every input file is read through [`read`] / [`read_text`]: only a regular file is opened (a
//! link that leads nowhere, a link loop, a folder, a FIFO, a device or a socket is an
//! [`Error::NotAFile`] naming it, never a hang or an endless read), and no read goes past its
//! [`Limit`]. Inside [`recording`] each read is also fingerprinted from the bytes read
//! ([`inputs`]), which is how a conversion knows what every frame was made from.
//! [`overlap`] keeps a command's outputs off its inputs.

pub mod inputs;
mod overlap;

use std::fs::{File, Metadata};
use std::io::Read as _;
use std::path::{Path, PathBuf};

pub use crate::error::NotFileKind;
use crate::error::{Error, Result};
pub use inputs::{fingerprint, note, recording, Fingerprint, InputRecord, Inputs};
pub use overlap::{overlap, refuse_linked, refuse_overlap, resolved, Overlap, Role};

/// The entries of a folder, sorted by path; errors name the folder.
pub fn sorted_dir(dir: &Path) -> Result<Vec<PathBuf>> {
    let mut out = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))? {
        out.push(entry.map_err(|e| Error::io(dir, e))?.path());
    }
    out.sort();
    Ok(out)
}

/// Removes the file at `path`: true when it was there, false when it was already gone (another
/// name of the same run removed it); other failures are errors naming it.
pub fn remove_if_there(path: &Path) -> Result<bool> {
    match std::fs::remove_file(path) {
        Ok(()) => Ok(true),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(false),
        Err(source) => Err(Error::Write {
            path: path.into(),
            source,
        }),
    }
}

/// Whether something is at `path`: a file, or a link even when it leads nowhere (a dangling
/// link to a label file is then read, and its error names it, instead of the frame passing as
/// unlabelled). Inside [`recording`], an absent path is recorded as such: a file that appears
/// there later changes what the frame is made from.
pub fn present(path: &Path) -> bool {
    let there = std::fs::symlink_metadata(path).is_ok();
    if !there {
        inputs::record_absent(path);
    }
    there
}

/// The most bytes a reader takes from one file: far above any real file of its kind, so that
/// only a mistake (a link to `/dev/zero` is refused anyway, a multi-gigabyte log named
/// `calib.txt`) reaches it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Limit {
    /// Text: calibration, timestamps, poses, tracklet XML, label_2, lists, YAML (64 MiB; the
    /// largest KITTI tracklet file is under 10 MiB).
    Text,
    /// Binary data: scans, per-point labels, images, maps (4 GiB).
    Data,
}

impl Limit {
    /// The limit in bytes.
    pub const fn bytes(self) -> u64 {
        match self {
            Limit::Text => 64 << 20,
            Limit::Data => 4 << 30,
        }
    }
}

/// The kind of a non-regular file from its metadata (links followed).
fn kind_of(meta: &Metadata) -> Option<NotFileKind> {
    if meta.is_file() {
        return None;
    }
    if meta.is_dir() {
        return Some(NotFileKind::Folder);
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt as _;
        let t = meta.file_type();
        if t.is_fifo() {
            return Some(NotFileKind::Fifo);
        }
        if t.is_char_device() || t.is_block_device() {
            return Some(NotFileKind::Device);
        }
        if t.is_socket() {
            return Some(NotFileKind::Socket);
        }
    }
    Some(NotFileKind::Other)
}

/// The metadata of the regular file at `path` (links followed); anything else is an error
/// naming the path and what is there.
pub fn regular(path: &Path) -> Result<Metadata> {
    let not_a_file = |found| Error::NotAFile {
        path: path.into(),
        found,
    };
    match std::fs::metadata(path) {
        Ok(meta) => match kind_of(&meta) {
            None => Ok(meta),
            Some(found) => Err(not_a_file(found)),
        },
        Err(e) => match std::fs::symlink_metadata(path) {
            Ok(link) if link.file_type().is_symlink() => {
                Err(not_a_file(if e.kind() == std::io::ErrorKind::NotFound {
                    NotFileKind::DanglingLink
                } else {
                    NotFileKind::BrokenLink
                }))
            }
            _ => Err(Error::io(path, e)),
        },
    }
}

/// Opens the regular file at `path` for reading without ever blocking on it: checked first,
/// opened non-blocking (a FIFO swapped in between would not wait for a writer), checked again
/// on the open handle.
pub fn open(path: &Path) -> Result<(File, Metadata)> {
    regular(path)?;
    let mut options = File::options();
    options.read(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt as _;
        options.custom_flags(libc::O_NONBLOCK);
    }
    let file = options.open(path).map_err(|e| Error::io(path, e))?;
    let meta = file.metadata().map_err(|e| Error::io(path, e))?;
    if let Some(found) = kind_of(&meta) {
        return Err(Error::NotAFile {
            path: path.into(),
            found,
        });
    }
    Ok((file, meta))
}

/// Reads the regular file at `path`, at most `limit` (a larger file is an
/// [`Error::TooLarge`]); inside [`recording`], fingerprints the bytes read.
pub fn read(path: &Path, limit: Limit) -> Result<Vec<u8>> {
    let (file, meta) = open(path)?;
    let too_large = |bytes| Error::TooLarge {
        path: path.into(),
        bytes,
        limit: limit.bytes(),
    };
    if meta.len() > limit.bytes() {
        return Err(too_large(meta.len()));
    }
    let mut bytes = Vec::with_capacity(meta.len() as usize);
    file.take(limit.bytes() + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| Error::io(path, e))?;
    if bytes.len() as u64 > limit.bytes() {
        return Err(too_large(bytes.len() as u64));
    }
    inputs::record_read(path, &meta, &bytes);
    Ok(bytes)
}

/// [`read`] as UTF-8 text; invalid UTF-8 is an I/O error of kind `InvalidData` naming the file.
pub fn read_text(path: &Path, limit: Limit) -> Result<String> {
    let bytes = read(path, limit)?;
    String::from_utf8(bytes).map_err(|e| {
        Error::io(
            path,
            std::io::Error::new(std::io::ErrorKind::InvalidData, e.utf8_error()),
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn special_files_are_named_and_never_opened() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        std::fs::create_dir(d.join("folder")).unwrap();
        #[cfg(unix)]
        {
            std::os::unix::fs::symlink(d.join("nowhere"), d.join("dangling")).unwrap();
            std::os::unix::fs::symlink(d.join("loop"), d.join("loop")).unwrap();
            std::os::unix::fs::symlink("/dev/zero", d.join("zero")).unwrap();
            let fifo = std::ffi::CString::new(d.join("fifo").to_str().unwrap()).unwrap();
            // SAFETY: a valid C string; mkfifo only creates the node.
            assert_eq!(unsafe { libc::mkfifo(fifo.as_ptr(), 0o644) }, 0);
        }
        let kind = |name: &str| match read(&d.join(name), Limit::Text) {
            Err(Error::NotAFile { found, path }) => {
                assert_eq!(path, d.join(name));
                found
            }
            other => panic!("{name}: {other:?}"),
        };
        assert_eq!(kind("folder"), NotFileKind::Folder);
        #[cfg(unix)]
        {
            assert_eq!(kind("dangling"), NotFileKind::DanglingLink);
            assert_eq!(kind("loop"), NotFileKind::BrokenLink);
            assert_eq!(kind("zero"), NotFileKind::Device);
            assert_eq!(kind("fifo"), NotFileKind::Fifo);
        }
        assert!(matches!(
            read(&d.join("absent"), Limit::Text),
            Err(Error::Io { .. })
        ));
    }

    #[test]
    fn a_file_over_its_limit_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("big.txt");
        let f = File::create(&p).unwrap();
        f.set_len(Limit::Text.bytes() + 1).unwrap();
        match read(&p, Limit::Text) {
            Err(Error::TooLarge { bytes, limit, .. }) => {
                assert_eq!(
                    (bytes, limit),
                    (Limit::Text.bytes() + 1, Limit::Text.bytes())
                )
            }
            other => panic!("{other:?}"),
        }
    }
}
