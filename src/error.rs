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
    /// An input path that holds something other than a regular file: a link that leads
    /// nowhere or loops, a folder, a FIFO (reading would wait forever), a device.
    #[error("{}: {found}, not a regular file", path.display())]
    NotAFile {
        /// The path.
        path: PathBuf,
        /// What is there.
        found: NotFileKind,
    },
    /// An input file larger than any real file of its kind.
    #[error("{}: {bytes} bytes, more than the {limit} a file of this kind may have", path.display())]
    TooLarge {
        /// The file.
        path: PathBuf,
        /// Its size (or the bytes read before stopping).
        bytes: u64,
        /// The limit.
        limit: u64,
    },
    /// An output path that is, lies inside or holds one of the command's inputs.
    #[error("{}: the output {how} {role} {}; write somewhere else", output.display(), input.display())]
    OutputOverInput {
        /// The output path.
        output: PathBuf,
        /// How it meets the input.
        how: Overlap,
        /// What the input is.
        role: Role,
        /// The input path.
        input: PathBuf,
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
    /// A file that is not of its format at all (not NumPy, not XML, not a kitti2pgm journal).
    #[error("{}: not {format}: {detail}", path.display())]
    NotFormat {
        /// The file.
        path: PathBuf,
        /// The format it should be in, with its article (`a .npy file`).
        format: &'static str,
        /// The parser's account.
        detail: String,
    },
    /// A binary file whose length is not a whole number of records.
    #[error("{}: {bytes} bytes, not a multiple of {record} ({} whole {what}s and {} stray bytes; truncated?)", path.display(), bytes / record, bytes % record)]
    Truncated {
        /// The file.
        path: PathBuf,
        /// Its length.
        bytes: usize,
        /// The length of one record.
        record: usize,
        /// What a record is (`point`, `label`).
        what: &'static str,
    },
    /// A field or record of another length than its header or its shape says.
    #[error("{}: {what} has {found} {unit}, expected {expected}", path.display())]
    Length {
        /// The file.
        path: PathBuf,
        /// Which field, of which frame (`frame 0052/0000000003: channel x`).
        what: String,
        /// The length found.
        found: usize,
        /// The length wanted.
        expected: usize,
        /// What is counted (`bytes`, `labels`).
        unit: &'static str,
    },
    /// An array or map of another shape than the reader or the ground truth needs.
    #[error("{}: {what} is {}, expected {expected}", path.display(), dims(found))]
    Shape {
        /// The file.
        path: PathBuf,
        /// What has the shape (`map`, `prediction for 0052/0000000003`).
        what: String,
        /// Its dimensions.
        found: Vec<usize>,
        /// What was wanted, in words with the dimensions.
        expected: String,
    },
    /// A value that must be finite and is not (NaN or infinite).
    #[error("{}: {what} is {value}, not a finite number", path.display())]
    NotFinite {
        /// The file.
        path: PathBuf,
        /// Which value (`oxts value 7`, `frame 3: channel range at cell (2, 5)`).
        what: String,
        /// The value.
        value: f64,
    },
    /// A shard whose bytes do not check: a CRC, a record or a message is damaged or missing.
    #[error("{}: corrupted shard: {what}", path.display())]
    Corrupt {
        /// The shard.
        path: PathBuf,
        /// What does not check, where (`frame #3 (0052/0000000003): ...`).
        what: String,
    },
    /// A file or record naming a frame by a string that is not a frame id.
    #[error("{}{}: {source}", path.display(), line.map(|l| format!(":{l}")).unwrap_or_default())]
    FrameId {
        /// The file.
        path: PathBuf,
        /// 1-based line number, in a list.
        line: Option<usize>,
        /// The string.
        source: NotAFrameId,
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
        /// The value found (a float where the file holds floats: `2.5`, `-1`).
        value: f64,
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
    /// A frame asked for (in a list) that the data does not hold.
    #[error("{}: frame {frame} is listed but not there", path.display())]
    FrameNotFound {
        /// The data searched (the ground truth).
        path: PathBuf,
        /// The frame id.
        frame: String,
    },
    /// Two predictions of one frame.
    #[error("{}: a second prediction for frame {frame} (the first: {})", path.display(), first.display())]
    DuplicatePrediction {
        /// The second file or shard.
        path: PathBuf,
        /// The frame id.
        frame: String,
        /// The first file or shard.
        first: PathBuf,
    },
    /// An output folder another process is converting into (its lock is held).
    #[error("{}: another kitti2pgm run (convert or unpack) is writing into this folder", path.display())]
    Locked {
        /// The output folder.
        path: PathBuf,
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
    /// A sequence folder an unpack began and never finished (killed, or failed before its end),
    /// refused: its scans are a part of the recording that looks whole.
    #[error("{}: an unfinished {what} ({} says complete: false: it was interrupted); {again}", path.display(), marker.display())]
    UnfinishedUnpack {
        /// The sequence folder.
        path: PathBuf,
        /// The file that says so (`unpack.json`, `nuscenes.json`, `box_labels.json`).
        marker: PathBuf,
        /// What did not finish (`unpack`, `label run`).
        what: &'static str,
        /// What to do.
        again: &'static str,
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
    /// A required key is missing from a calibration file or a shard's metadata.
    #[error("{}: missing key `{key}`", path.display())]
    MissingKey {
        /// The calibration file or shard.
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
        source: png::DecodingError,
    },
    /// Options that contradict each other or are out of range.
    #[error("invalid option: {0}")]
    Config(String),
}

impl Error {
    /// The kind of problem as one word, for programs reading `--json` output (the variant's
    /// name in snake case: `not_a_file`, `output_over_input`, `config`...).
    pub fn kind(&self) -> &'static str {
        match self {
            Error::Io { .. } => "io",
            Error::NotAFile { .. } => "not_a_file",
            Error::TooLarge { .. } => "too_large",
            Error::OutputOverInput { .. } => "output_over_input",
            Error::Write { .. } => "write",
            Error::Format { .. } => "format",
            Error::NotFormat { .. } => "not_format",
            Error::Truncated { .. } => "truncated",
            Error::Length { .. } => "length",
            Error::Shape { .. } => "shape",
            Error::NotFinite { .. } => "not_finite",
            Error::Corrupt { .. } => "corrupt",
            Error::FrameId { .. } => "frame_id",
            Error::Dtype { .. } => "dtype",
            Error::NotAClass { .. } => "not_a_class",
            Error::MissingPrediction { .. } => "missing_prediction",
            Error::FrameNotFound { .. } => "frame_not_found",
            Error::DuplicatePrediction { .. } => "duplicate_prediction",
            Error::Locked { .. } => "locked",
            Error::NeedsScans { .. } => "needs_scans",
            Error::Unfinished { .. } | Error::UnfinishedUnpack { .. } => "unfinished",
            Error::LabelCount { .. } => "label_count",
            Error::Mcap { .. } => "mcap",
            Error::MissingKey { .. } => "missing_key",
            Error::Input { .. } => "input",
            Error::Image { .. } => "image",
            Error::Config(_) => "config",
        }
    }

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

/// A string that is not a frame id (`FrameId`'s parse error).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{0:?} is not a frame id like 2011_09_26_0001_0000000010, 00_000000 or 000000")]
pub struct NotAFrameId(pub String);

impl NotAFrameId {
    /// The [`Error::FrameId`] for this string found in `path`.
    pub fn in_file(self, path: impl Into<PathBuf>) -> Error {
        Error::FrameId {
            path: path.into(),
            line: None,
            source: self,
        }
    }
}

/// What is at a path that is not a regular file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NotFileKind {
    /// A symbolic link whose target does not exist.
    DanglingLink,
    /// A symbolic link that cannot be followed (a loop, a target that cannot be reached).
    BrokenLink,
    /// A folder.
    Folder,
    /// A named pipe: reading it would wait for a writer.
    Fifo,
    /// A character or block device (`/dev/zero` never ends).
    Device,
    /// A socket.
    Socket,
    /// Anything else that is not a regular file.
    Other,
}

impl std::fmt::Display for NotFileKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            NotFileKind::DanglingLink => "a link that leads nowhere",
            NotFileKind::BrokenLink => "a link that cannot be followed (a loop?)",
            NotFileKind::Folder => "a folder",
            NotFileKind::Fifo => "a named pipe (FIFO)",
            NotFileKind::Device => "a device",
            NotFileKind::Socket => "a socket",
            NotFileKind::Other => "something other than a file",
        })
    }
}

/// What an input is to the command, for the error.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Role {
    /// The dataset root (scans, labels, calibration, box annotations).
    Dataset,
    /// The converted ground truth.
    GroundTruth,
    /// The predictions.
    Predictions,
    /// Converted data read by a report (maps, shards).
    Converted,
    /// A list file.
    List,
    /// A class map file.
    ClassMap,
    /// A sensor's calibration table.
    Calibration,
    /// A model file (`infer`).
    Model,
}

impl std::fmt::Display for Role {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Role::Dataset => "the dataset",
            Role::GroundTruth => "the ground truth",
            Role::Predictions => "the predictions",
            Role::Converted => "the converted data",
            Role::List => "an input list",
            Role::ClassMap => "the class map",
            Role::Calibration => "the sensor calibration",
            Role::Model => "the model",
        })
    }
}

/// How an output path meets an input.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Overlap {
    /// The same path.
    Is,
    /// Inside the input folder.
    Inside,
    /// A folder holding the input.
    Holds,
    /// Inside a folder that holds a hard link of one of the input's files (the path named).
    BesideLink,
}

impl std::fmt::Display for Overlap {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Overlap::Is => "is",
            Overlap::Inside => "is inside",
            Overlap::Holds => "holds",
            Overlap::BesideLink => "is inside a folder that holds (hard-linked) a file of",
        })
    }
}

/// A number as a message shows it: `1e38`, not 39 digits; `35.2` as written.
pub fn shown<T>(x: T) -> String
where
    T: Copy + Into<f64> + std::fmt::Display + std::fmt::LowerExp,
{
    let v: f64 = x.into();
    if v.is_finite() && v != 0.0 && !(1e-4..1e6).contains(&v.abs()) {
        format!("{x:e}")
    } else {
        format!("{x}")
    }
}

/// `4x512x6`: dimensions as people write them.
fn dims(d: &[usize]) -> String {
    let parts: Vec<String> = d.iter().map(ToString::to_string).collect();
    parts.join("x")
}

/// `Result` with the crate's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kinds_are_snake_case_words() {
        let e = Error::Config("x".into());
        assert_eq!(e.kind(), "config");
        let (path, found) = ("p".into(), NotFileKind::Fifo);
        let k = Error::NotAFile { path, found }.kind();
        assert_eq!(k, "not_a_file");
        assert!(k.bytes().all(|c| c.is_ascii_lowercase() || c == b'_'));
    }
}
