//! The `kitti2pgm` metadata record of a shard: version, typed conversion parameters, drives,
//! the frames planned, the frames that failed, the split, and the topic names.

use std::collections::BTreeMap;
use std::path::Path;

use serde::Serialize;

use crate::error::{Error, NotAFrameId, Result};
use crate::provenance::ConvertParams;
use crate::source::kitti::FrameId;

/// What the metadata record of a shard says.
#[derive(Debug, Clone, PartialEq, Default, Serialize)]
pub struct ShardMetadata {
    /// Tool version.
    pub version: String,
    /// The conversion parameters (stored as JSON under `params`).
    pub params: ConvertParams,
    /// Input drives, as `<date>_drive_<NNNN>_sync`.
    pub drives: Vec<String>,
    /// Frame ids planned for the shard, in order.
    pub frames: Vec<FrameId>,
    /// Frames of the plan that failed and are not in the shard.
    pub failed: Vec<FrameId>,
    /// The split of its frames.
    pub split: crate::plan::split::Split,
    /// What the shard holds.
    pub content: super::ShardKind,
    /// The digest of each written frame's inputs ([`crate::fs::Inputs::digest`], paths relative
    /// to the dataset root): a re-run keeps the shard only when its frames' inputs are unchanged.
    /// Empty in shards of earlier versions.
    pub inputs: BTreeMap<FrameId, u64>,
}

/// Frame ids one a line, as the record stores them.
fn ids_text(ids: &[FrameId]) -> String {
    ids.iter()
        .map(FrameId::to_string)
        .collect::<Vec<_>>()
        .join("\n")
}

impl ShardMetadata {
    /// The record's string map.
    pub fn to_map(&self) -> BTreeMap<String, String> {
        BTreeMap::from([
            ("version".into(), self.version.clone()),
            (
                "params".into(),
                serde_json::to_string(&self.params).expect("parameters serialise"),
            ),
            ("drives".into(), self.drives.join("\n")),
            ("frames".into(), ids_text(&self.frames)),
            ("failed".into(), ids_text(&self.failed)),
            ("split".into(), self.split.to_string()),
            ("content".into(), self.content.as_str().into()),
            (
                "inputs".into(),
                self.inputs
                    .iter()
                    .map(|(id, d)| format!("{id} {d:016x}"))
                    .collect::<Vec<_>>()
                    .join("\n"),
            ),
            // The topics, so that readers (the Python package) need no copy of them.
            ("frame_topic".into(), super::FRAME_TOPIC.into()),
            ("prediction_topic".into(), super::PREDICTION_TOPIC.into()),
            ("points_topic".into(), super::POINTS_TOPIC.into()),
        ])
    }

    /// Reads the record's string map; `path` names the shard in errors (a missing key, or
    /// parameters that are not this version's).
    pub fn from_map(m: &BTreeMap<String, String>, path: &Path) -> Result<ShardMetadata> {
        let get = |k: &str| {
            m.get(k).ok_or_else(|| Error::MissingKey {
                path: path.into(),
                key: format!("{k} (metadata entry)"),
            })
        };
        let list =
            |k: &str| -> Result<Vec<String>> { Ok(get(k)?.lines().map(String::from).collect()) };
        let ids = |v: &[String], key: &str| -> Result<Vec<FrameId>> {
            v.iter()
                .map(|s| {
                    s.parse().map_err(|e: NotAFrameId| Error::FrameId {
                        path: path.into(),
                        line: None,
                        source: NotAFrameId(format!("{} (metadata `{key}`)", e.0)),
                    })
                })
                .collect()
        };
        let version = get("version")?.clone();
        let params = serde_json::from_str(get("params")?).map_err(|e| Error::NotFormat {
            path: path.into(),
            format: concat!(
                "kitti2pgm ",
                env!("CARGO_PKG_VERSION"),
                "'s conversion parameters (metadata `params`)"
            ),
            detail: format!("{e} (shard written by kitti2pgm {version}?)"),
        })?;
        Ok(ShardMetadata {
            version,
            params,
            drives: list("drives")?,
            frames: ids(&list("frames")?, "frames")?,
            failed: ids(&list("failed")?, "failed")?,
            split: get("split")?
                .parse()
                .map_err(|e: Error| Error::format(path, format!("metadata `split`: {e}")))?,
            inputs: input_digests(m.get("inputs"), path)?,
            // Shards written before point shards existed hold maps.
            content: match m.get("content").map(String::as_str) {
                None | Some("maps") => super::ShardKind::Maps,
                Some("points") => super::ShardKind::Points,
                Some(other) => {
                    return Err(Error::format(
                        path,
                        format!("metadata `content` {other:?} is neither maps nor points"),
                    ))
                }
            },
        })
    }
}

/// The `inputs` entry: `FRAME_ID DIGEST` lines (absent in shards of earlier versions).
fn input_digests(entry: Option<&String>, path: &Path) -> Result<BTreeMap<FrameId, u64>> {
    let bad = |line: &str| {
        Error::format(
            path,
            format!("metadata `inputs`: line {line:?} is not `FRAME_ID DIGEST`"),
        )
    };
    let mut out = BTreeMap::new();
    for line in entry.map(String::as_str).unwrap_or("").lines() {
        let (id, digest) = line.split_once(' ').ok_or_else(|| bad(line))?;
        let id = id.parse().map_err(|e: NotAFrameId| e.in_file(path))?;
        out.insert(id, u64::from_str_radix(digest, 16).map_err(|_| bad(line))?);
    }
    Ok(out)
}
