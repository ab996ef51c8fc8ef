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
    /// An array of another element type than the reader takes.
    #[error("{}: dtype {found}, expected {expected}", path.display())]
    Dtype {
        /// The `.npy` file.
        path: PathBuf,
        /// The dtype the file holds, as NumPy describes it (`'<i8'`).
        found: String,
        /// The dtype wanted, in words and as NumPy writes it.
        expected: &'static str,
    },
    /// A label that is not a class id of the class map.
    #[error("{}: {what} has label {value}, not a class id of {map} (0-{max}){}", path.display(), hint.map(|h| format!("; {h}")).unwrap_or_default())]
    NotAClass {
        /// The file holding it.
        path: PathBuf,
        /// Which element (`point 17`, `cell (3, 4)`).
        what: String,
        /// The value found.
        value: u64,
        /// The class map's name.
        map: String,
        /// Its largest class id.
        max: usize,
        /// What the reader of the message may have meant, when known.
        hint: Option<&'static str>,
    },
    /// A ground-truth frame without a prediction.
    #[error("{}: no prediction for ground-truth frame {frame}{}", root.display(), expected.as_ref().map(|e| format!(": expected {e}")).unwrap_or_default())]
    MissingPrediction {
        /// The predictions searched.
        root: PathBuf,
        /// The frame id.
        frame: String,
        /// Where its prediction was looked for, when there is one place.
        expected: Option<String>,
    },
    /// Work that needs the raw scans, asked for without them.
    #[error("{frame}: {what} needs the raw scans")]
    NeedsScans {
        /// The frame id it was needed for.
        frame: String,
        /// What needs them.
        what: &'static str,
    },
    /// The output of an unfinished or inconsistent conversion, refused.
    #[error("{}: {problem}; finish the conversion (run it again), or read what is there on purpose", path.display())]
    Unfinished {
        /// The converted data.
        path: PathBuf,
        /// What is unfinished or inconsistent.
        problem: String,
    },
    /// A per-point label file whose count is not its scan's.
    #[error("{}: {labels} labels, but the scan {} has {points} points{}", path.display(), scan.display(), note.map(|n| format!(" ({n})")).unwrap_or_default())]
    LabelCount {
        /// The label file.
        path: PathBuf,
        /// Labels in it.
        labels: usize,
        /// Its scan.
        scan: PathBuf,
        /// Points in the scan.
        points: usize,
        /// The likely cause, when known.
        note: Option<&'static str>,
    },
    /// The MCAP library could not read or write a shard.
    #[error("{}: {context}: {source}", path.display())]
    Mcap {
        /// The shard.
        path: PathBuf,
        /// What was being read or written (`chunk at byte 1234`, `MCAP writer`).
        context: String,
        /// The library's error.
        source: mcap::McapError,
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
    /// An [`Error::Mcap`] for `path`.
    pub fn mcap(
        path: impl Into<PathBuf>,
        context: impl Into<String>,
        source: mcap::McapError,
    ) -> Self {
        Error::Mcap {
            path: path.into(),
            context: context.into(),
            source,
        }
    }

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
