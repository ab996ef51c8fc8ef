//! What a piece of work was made from: every input file it read, fingerprinted from the bytes
//! read (size, modification time, XXH3-64 of the content), and every path it looked for and
//! found absent.
//!
//! [`recording`] runs a closure and returns, beside its result, the [`Inputs`] read inside it
//! through [`super::read`] (or probed by [`super::present`]); [`note`] adds inputs read earlier
//! (a drive's tracklets, read once for all its frames). Scopes nest per thread, so a rayon task
//! stolen while a frame waits records into its own scope. A re-run compares the recorded inputs
//! with the files as they are now ([`Inputs::first_change`]): the content decides (a file
//! touched but unchanged is the same input), size and time are kept to say what changed.

use std::cell::RefCell;
use std::collections::BTreeMap;
use std::fs::Metadata;
use std::io::Read as _;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};

/// One file's identity as read: its size, modification time and content hash.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Fingerprint {
    /// Bytes.
    pub size: u64,
    /// Modification time, nanoseconds since the Unix epoch (informative: the content decides).
    pub mtime_ns: i64,
    /// XXH3-64 of the content, 16 hex digits.
    #[serde(with = "hex64")]
    pub xxh3: u64,
}

impl Fingerprint {
    /// Whether two fingerprints are of the same content.
    pub fn same_content(&self, other: &Fingerprint) -> bool {
        self.size == other.size && self.xxh3 == other.xxh3
    }

    /// The fingerprint of a file just written at `path`, whose `size` bytes hash to `xxh3`
    /// (known to the writer): its modification time read back.
    pub fn of_written(path: &Path, size: u64, xxh3: u64) -> Result<Fingerprint> {
        let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
        Ok(Fingerprint {
            size,
            mtime_ns: mtime_ns(&meta),
            xxh3,
        })
    }

    fn of(meta: &Metadata, bytes: &[u8]) -> Fingerprint {
        Fingerprint {
            size: bytes.len() as u64,
            mtime_ns: mtime_ns(meta),
            xxh3: xxhash_rust::xxh3::xxh3_64(bytes),
        }
    }
}

fn mtime_ns(meta: &Metadata) -> i64 {
    match meta.modified() {
        Ok(t) => match t.duration_since(std::time::UNIX_EPOCH) {
            Ok(d) => d.as_nanos().min(i64::MAX as u128) as i64,
            Err(e) => -(e.duration().as_nanos().min(i64::MAX as u128) as i64),
        },
        Err(_) => 0,
    }
}

/// Serialises a `u64` as 16 hex digits (JSON numbers lose precision above 2^53 elsewhere).
mod hex64 {
    use serde::{Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(v: &u64, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(&format!("{v:016x}"))
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<u64, D::Error> {
        let s = String::deserialize(d)?;
        u64::from_str_radix(&s, 16).map_err(serde::de::Error::custom)
    }
}

/// One input: a path and what was there (`None`: looked for and absent).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct InputRecord {
    /// The path as read (relative to the dataset root in a journal).
    pub path: PathBuf,
    /// The file read, or `None` where nothing was.
    pub file: Option<Fingerprint>,
}

/// The inputs of one piece of work, one record per path, sorted by path.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(transparent)]
pub struct Inputs(Vec<InputRecord>);

impl Inputs {
    /// The records, sorted by path.
    pub fn records(&self) -> &[InputRecord] {
        &self.0
    }

    /// Adds records; a path seen twice keeps its first record (what the work read first).
    pub fn extend(&mut self, more: impl IntoIterator<Item = InputRecord>) {
        let mut by_path: BTreeMap<PathBuf, Option<Fingerprint>> =
            self.0.drain(..).map(|r| (r.path, r.file)).collect();
        for r in more {
            by_path.entry(r.path).or_insert(r.file);
        }
        self.0 = by_path
            .into_iter()
            .map(|(path, file)| InputRecord { path, file })
            .collect();
    }

    /// The same inputs with paths relative to the root (those under it, as written in any of
    /// `roots`: the root as given and resolved; others stay as they are).
    pub fn relative_to(&self, roots: &[&Path]) -> Inputs {
        let mut out = Inputs::default();
        out.extend(self.0.iter().map(|r| {
            InputRecord {
                path: roots
                    .iter()
                    .find_map(|root| r.path.strip_prefix(root).ok())
                    .unwrap_or(&r.path)
                    .to_path_buf(),
                file: r.file,
            }
        }));
        out
    }

    /// One hash of every path and content (not the times): equal inputs, equal digest.
    pub fn digest(&self) -> u64 {
        let mut h = xxhash_rust::xxh3::Xxh3::new();
        for r in &self.0 {
            h.update(r.path.to_string_lossy().as_bytes());
            h.update(&[0]);
            match &r.file {
                Some(f) => {
                    h.update(&f.size.to_le_bytes());
                    h.update(&f.xxh3.to_le_bytes());
                }
                None => h.update(b"absent"),
            }
            h.update(&[0xff]);
        }
        h.digest()
    }

    /// The first input (paths relative to `root`) whose content differs now from the record,
    /// with what changed; `None` when every input is as recorded. `now` fingerprints a path
    /// (a cache shared by the frames of a run).
    pub fn first_change(
        &self,
        root: &Path,
        now: &dyn Fn(&Path) -> Result<Option<Fingerprint>>,
    ) -> Option<Change> {
        self.0.iter().find_map(|r| {
            let change = match (now(&root.join(&r.path)), &r.file) {
                (Err(e), _) => InputChange::Unreadable(e.to_string()),
                (Ok(None), None) => return None,
                (Ok(None), Some(_)) => InputChange::Removed,
                (Ok(Some(_)), None) => InputChange::Appeared,
                (Ok(Some(a)), Some(b)) if a.same_content(b) => return None,
                (Ok(Some(a)), Some(b)) if a.size != b.size => InputChange::Size {
                    was: b.size,
                    now: a.size,
                },
                (Ok(Some(_)), Some(_)) => InputChange::Content,
            };
            Some(Change {
                path: r.path.clone(),
                change,
            })
        })
    }
}

/// How one input differs from its record.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum InputChange {
    /// Another size.
    Size {
        /// Recorded.
        was: u64,
        /// Now.
        now: u64,
    },
    /// Same size, other content.
    Content,
    /// Absent when recorded, there now.
    Appeared,
    /// There when recorded, absent now.
    Removed,
    /// There, but it cannot be read (the error).
    Unreadable(String),
}

/// An input that changed since it was recorded.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Change {
    /// The input (relative to the dataset root).
    pub path: PathBuf,
    /// What changed.
    pub change: InputChange,
}

impl std::fmt::Display for Change {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let p = self.path.display();
        match &self.change {
            InputChange::Size { was, now } => write!(f, "{p}: {was} bytes, now {now}"),
            InputChange::Content => write!(f, "{p}: content changed"),
            InputChange::Appeared => write!(f, "{p}: appeared"),
            InputChange::Removed => write!(f, "{p}: removed"),
            InputChange::Unreadable(e) => write!(f, "{p}: unreadable now ({e})"),
        }
    }
}

thread_local! {
    /// The open recording scopes of this thread, innermost last.
    static SCOPES: RefCell<Vec<Vec<InputRecord>>> = const { RefCell::new(Vec::new()) };
}

/// Pops the scope it pushed, also when the closure panics.
struct Scope;

impl Drop for Scope {
    fn drop(&mut self) {
        SCOPES.with(|s| s.borrow_mut().pop());
    }
}

/// Runs `f`, returning beside its result every input it read or probed (on this thread).
pub fn recording<T>(f: impl FnOnce() -> T) -> (T, Inputs) {
    SCOPES.with(|s| s.borrow_mut().push(Vec::new()));
    let scope = Scope;
    let out = f();
    let records = SCOPES.with(|s| s.borrow_mut().last_mut().map(std::mem::take));
    drop(scope);
    let mut inputs = Inputs::default();
    inputs.extend(records.unwrap_or_default());
    (out, inputs)
}

fn recording_now() -> bool {
    SCOPES.with(|s| !s.borrow().is_empty())
}

fn push(record: InputRecord) {
    SCOPES.with(|s| {
        if let Some(top) = s.borrow_mut().last_mut() {
            top.push(record);
        }
    });
}

/// Adds inputs read earlier (outside the scope) to the innermost scope, if any.
pub fn note(inputs: &Inputs) {
    if recording_now() {
        inputs.0.iter().cloned().for_each(push);
    }
}

/// Records a file read whole (its bytes), if a scope is open.
pub(super) fn record_read(path: &Path, meta: &Metadata, bytes: &[u8]) {
    if recording_now() {
        push(InputRecord {
            path: path.into(),
            file: Some(Fingerprint::of(meta, bytes)),
        });
    }
}

/// Records a path looked for and absent, if a scope is open.
pub(super) fn record_absent(path: &Path) {
    if recording_now() {
        push(InputRecord {
            path: path.into(),
            file: None,
        });
    }
}

/// The fingerprint of `path` now, streamed (`None` when nothing is there, not even a link);
/// anything there that is not a readable regular file is an error.
pub fn fingerprint(path: &Path) -> Result<Option<Fingerprint>> {
    if std::fs::symlink_metadata(path).is_err() {
        return Ok(None);
    }
    let (mut file, meta) = super::open(path)?;
    let mut h = xxhash_rust::xxh3::Xxh3::new();
    let mut buf = vec![0u8; 1 << 20];
    let mut size = 0u64;
    loop {
        let n = file.read(&mut buf).map_err(|e| Error::io(path, e))?;
        if n == 0 {
            break;
        }
        h.update(&buf[..n]);
        size += n as u64;
    }
    Ok(Some(Fingerprint {
        size,
        mtime_ns: mtime_ns(&meta),
        xxh3: h.digest(),
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_scope_records_reads_and_absences_and_nests() {
        let dir = tempfile::tempdir().unwrap();
        let a = dir.path().join("a.txt");
        std::fs::write(&a, b"alpha").unwrap();
        let b = dir.path().join("b.txt");
        let ((), outer) = recording(|| {
            super::super::read(&a, super::super::Limit::Text).unwrap();
            let ((), inner) = recording(|| assert!(!super::super::present(&b)));
            assert_eq!(inner.records().len(), 1);
            assert_eq!(inner.records()[0].file, None);
        });
        assert_eq!(outer.records().len(), 1, "{outer:?}");
        let f = outer.records()[0].file.unwrap();
        assert_eq!(f, fingerprint(&a).unwrap().unwrap());
        assert_eq!(f.xxh3, xxhash_rust::xxh3::xxh3_64(b"alpha"));
        // Outside any scope, nothing is recorded.
        assert!(!recording_now());
    }

    #[test]
    fn changes_are_found_by_content() {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path();
        std::fs::write(root.join("s.bin"), b"0123").unwrap();
        let now = |p: &Path| fingerprint(p);
        let ((), rec) = recording(|| {
            super::super::read(&root.join("s.bin"), super::super::Limit::Data).unwrap();
            super::super::present(&root.join("l.label"));
        });
        let rec = rec.relative_to(&[root]);
        assert_eq!(rec.records()[1].path, Path::new("s.bin"));
        assert_eq!(rec.first_change(root, &now), None);
        // Touched, same bytes: unchanged.
        std::fs::write(root.join("s.bin"), b"0123").unwrap();
        assert_eq!(rec.first_change(root, &now), None);
        std::fs::write(root.join("s.bin"), b"3210").unwrap();
        assert_eq!(
            rec.first_change(root, &now).unwrap().change,
            InputChange::Content
        );
        std::fs::write(root.join("s.bin"), b"0123").unwrap();
        std::fs::write(root.join("l.label"), b"").unwrap();
        let c = rec.first_change(root, &now).unwrap();
        assert_eq!(
            (c.path.as_path(), c.change),
            (Path::new("l.label"), InputChange::Appeared)
        );
        let json = serde_json::to_string(&rec).unwrap();
        assert_eq!(serde_json::from_str::<Inputs>(&json).unwrap(), rec);
        assert_ne!(rec.digest(), Inputs::default().digest());
    }
}
