//! The library's one error type.
//!
//! Every variant that touches a file carries its path, so that a message read in a log of
//! ten thousand frames says which file is wrong and how (ripgrep's `WithPath` habit). The
//! numbers that disagree travel in the variant ("1000003 bytes, not a multiple of 16").

use std::path::PathBuf;

/// What went wrong, with the file it went wrong in.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// A file could not be opened, read or listed.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file or folder.
        path: PathBuf,
        /// The operating system's error.
        source: std::io::Error,
    },
    /// A file could not be written (or renamed into place).
    #[error("{}: cannot write: {source}", path.display())]
    Write {
        /// The file or folder.
        path: PathBuf,
        /// The operating system's error.
        source: std::io::Error,
    },
    /// A file's contents do not follow its format.
    #[error("{}{}: {message}", path.display(), line.map(|l| format!(":{l}")).unwrap_or_default())]
    Format {
        /// The file.
        path: PathBuf,
        /// 1-based line number, when the format is line based.
        line: Option<usize>,
        /// What is wrong, with the values that disagree.
        message: String,
    },
    /// A required key is missing from a calibration file.
    #[error("{}: missing key `{key}`", path.display())]
    MissingKey {
        /// The calibration file.
        path: PathBuf,
        /// The key that is absent.
        key: String,
    },
    /// A path is not what the command needs (not a KITTI raw root, no drives, ...).
    #[error("{}: {message}", path.display())]
    Input {
        /// The path given.
        path: PathBuf,
        /// What is wrong with it.
        message: String,
    },
    /// An image could not be decoded.
    #[error("{}: cannot decode image: {source}", path.display())]
    Image {
        /// The image file.
        path: PathBuf,
        /// The decoder's error.
        source: image::ImageError,
    },
    /// Options that contradict each other or are out of range.
    #[error("invalid option: {0}")]
    Config(String),
}

impl Error {
    /// A [`Error::Format`] without a line number.
    pub fn format(path: impl Into<PathBuf>, message: impl Into<String>) -> Self {
        Error::Format {
            path: path.into(),
            line: None,
            message: message.into(),
        }
    }

    /// A [`Error::Io`] for `path`.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            source,
        }
    }
}

/// `Result` with the crate's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;
