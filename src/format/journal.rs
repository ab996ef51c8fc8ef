//! The provenance journal of a convert folder, `OUT/.kitti2pgm-frames`, both directions.
//!
//! ```text
//! kitti2pgm-frames/2 {"map":{...},...}              the parameters: ConvertParams as JSON
//! root "/data/kitti/raw"                             the dataset root, resolved, as a JSON string
//! 2011_09_26_0001_0000000000 [{"path":"2011_09_26/.../0000000000.bin","file":{"size":...,"mtime_ns":...,"xxh3":"..."}},...]
//! ```
//!
//! After the two header lines, one line per frame whose files were written whole: its id and
//! the inputs it was made from ([`Inputs`]: every file read, paths relative to the root, and
//! every path looked for and absent). Lines are appended as frames finish; a later line for a
//! frame replaces an earlier one; a last line without its newline (a run killed while appending
//! it) is not counted. Version 1 journals (parameters and frame ids, no root, no inputs) still
//! read, with no inputs: nothing they list can be kept.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::fs::Inputs;
use crate::provenance::ConvertParams;
use crate::source::kitti::FrameId;

/// Name of the journal in the output folder.
pub const JOURNAL_FILE: &str = ".kitti2pgm-frames";

/// First word of the header line, this version.
const MAGIC: &str = "kitti2pgm-frames/2";

/// First word of the header line of version 1 (no root, no inputs).
const MAGIC_V1: &str = "kitti2pgm-frames/1";

/// First word of the root line.
const ROOT: &str = "root";

/// A journal as read back.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct JournalRecord {
    /// The parameters' JSON, exactly as recorded.
    pub params: String,
    /// The dataset root, resolved (`None`: a version 1 journal).
    pub root: Option<PathBuf>,
    /// Frames whose files were written whole with these parameters, with their inputs (`None`:
    /// a version 1 journal, which recorded none).
    pub frames: BTreeMap<FrameId, Option<Inputs>>,
}

impl JournalRecord {
    /// Whether the journal was started with `params` from the dataset at `root` (resolved),
    /// recording inputs (this version).
    pub fn made_with(&self, params: &ConvertParams, root: &Path) -> bool {
        self.params == params_key(params) && self.root.as_deref() == Some(root)
    }

    /// Whether `id` is listed.
    pub fn lists(&self, id: &FrameId) -> bool {
        self.frames.contains_key(id)
    }
}

/// The parameters as the journal records them: one line of JSON.
pub fn params_key(params: &ConvertParams) -> String {
    serde_json::to_string(params).expect("the parameters serialise")
}

/// The two header lines for `params` and the resolved dataset `root`.
pub fn header(params: &ConvertParams, root: &Path) -> String {
    let root = serde_json::to_string(&root.to_string_lossy()).expect("a string serialises");
    format!("{MAGIC} {}\n{ROOT} {root}\n", params_key(params))
}

/// One frame's line.
pub fn frame_line(id: &FrameId, inputs: &Inputs) -> String {
    let json = serde_json::to_string(inputs).expect("inputs serialise");
    format!("{id} {json}\n")
}

/// Reads `path`; `Ok(None)` when nothing is there.
pub fn read(path: &Path) -> Result<Option<JournalRecord>> {
    if !crate::fs::present(path) {
        return Ok(None);
    }
    let bytes = crate::fs::read(path, crate::fs::Limit::Text)?;
    parse(&String::from_utf8_lossy(&bytes), path).map(Some)
}

/// Parses a journal's text; `path` names it in errors.
pub fn parse(text: &str, path: &Path) -> Result<JournalRecord> {
    let not_journal = |detail: String| Error::NotFormat {
        path: path.into(),
        format: "a kitti2pgm journal",
        detail,
    };
    // Only whole lines count.
    let mut lines = text
        .split_inclusive('\n')
        .filter_map(|l| l.strip_suffix('\n'));
    let first = lines.next().unwrap_or("");
    let (v1, params) = match first.split_once(' ') {
        Some((MAGIC, p)) => (false, p),
        Some((MAGIC_V1, p)) => (true, p),
        _ => {
            return Err(not_journal(format!(
                "its first line is not `{MAGIC} PARAMETERS`"
            )))
        }
    };
    let mut record = JournalRecord {
        params: params.to_string(),
        ..Default::default()
    };
    if !v1 {
        let root = lines
            .next()
            .and_then(|l| l.strip_prefix(ROOT))
            .and_then(|l| l.strip_prefix(' '))
            .and_then(|r| serde_json::from_str::<String>(r).ok())
            .ok_or_else(|| not_journal(format!("its second line is not `{ROOT} \"PATH\"`")))?;
        record.root = Some(root.into());
    }
    for (i, line) in lines.enumerate().filter(|(_, l)| !l.is_empty()) {
        let line_no = i + if v1 { 2 } else { 3 };
        let (id, inputs) = match (v1, line.split_once(' ')) {
            (true, _) => (line, None),
            (false, Some((id, json))) => {
                let inputs: Inputs = serde_json::from_str(json).map_err(|e| Error::Format {
                    path: path.into(),
                    line: Some(line_no),
                    message: format!("the inputs of frame {id} are not a list of inputs: {e}"),
                })?;
                (id, Some(inputs))
            }
            (false, None) => {
                return Err(Error::Format {
                    path: path.into(),
                    line: Some(line_no),
                    message: "a frame line is `FRAME_ID INPUTS`".into(),
                })
            }
        };
        let id: FrameId = id
            .parse()
            .map_err(|e: crate::error::NotAFrameId| Error::FrameId {
                path: path.into(),
                line: Some(line_no),
                source: e,
            })?;
        record.frames.insert(id, inputs);
    }
    Ok(record)
}

/// The whole journal's text: the header, then `frames` in frame order.
pub fn encode<'a>(
    header: &str,
    frames: impl IntoIterator<Item = (&'a FrameId, &'a Inputs)>,
) -> String {
    let mut text = header.to_string();
    for (id, inputs) in frames {
        text.push_str(&frame_line(id, inputs));
    }
    text
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_journal_round_trips_and_a_torn_last_line_is_not_counted() {
        let params = ConvertParams::squeezeseg();
        let root = Path::new("/data/kitti raw/\"odd\"");
        let id: FrameId = "2011_09_26_0001_0000000003".parse().unwrap();
        let ((), inputs) = crate::fs::recording(|| {
            crate::fs::present(Path::new("/nonexistent/label"));
        });
        let text = encode(&header(&params, root), [(&id, &inputs)]);
        let r = parse(&text, Path::new("j")).unwrap();
        assert!(r.made_with(&params, root));
        assert_eq!(r.frames.get(&id), Some(&Some(inputs.clone())));
        let torn = format!("{text}2011_09_26_0001_0000000004 [");
        assert_eq!(parse(&torn, Path::new("j")).unwrap(), r);
    }

    #[test]
    fn a_version_1_journal_reads_without_inputs_and_is_not_this_runs() {
        let params = ConvertParams::squeezeseg();
        let text = format!(
            "{MAGIC_V1} {}\n2011_09_26_0001_0000000003\n",
            params_key(&params)
        );
        let r = parse(&text, Path::new("j")).unwrap();
        assert_eq!(r.root, None);
        assert_eq!(r.frames.values().next(), Some(&None));
        assert!(!r.made_with(&params, Path::new("/")));
    }

    #[test]
    fn garbage_is_named() {
        assert!(matches!(
            parse("hello\n", Path::new("j")),
            Err(Error::NotFormat { .. })
        ));
        let bad = format!("{MAGIC} {{}}\nroot \"/\"\nnot-a-frame []\n");
        assert!(matches!(
            parse(&bad, Path::new("j")),
            Err(Error::FrameId { line: Some(3), .. })
        ));
    }
}
