//! ImageSet lists: one frame id a line (`<date>_<drive4>_<frame10>`), sorted, as SqueezeSeg's
//! `ImageSet/{all,train,val}.txt`.

use std::path::Path;

use crate::error::{Error, Result};
use crate::source::kitti::FrameId;

/// Reads an ImageSet list; blank lines are ignored, anything else must be a frame id.
pub fn read(path: &Path) -> Result<Vec<FrameId>> {
    let text = crate::fs::read_text(path, crate::fs::Limit::Text)?;
    text.lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty())
        .map(|(i, l)| {
            l.trim()
                .parse::<FrameId>()
                .map_err(|source| Error::FrameId {
                    path: path.into(),
                    line: Some(i + 1),
                    source,
                })
        })
        .collect()
}

/// The text of a list: one id a line, in the given order, newline-terminated.
pub fn to_text(ids: &[FrameId]) -> String {
    let mut s = String::with_capacity(ids.len() * 27);
    for id in ids {
        s.push_str(&id.to_string());
        s.push('\n');
    }
    s
}

/// Writes an ImageSet list to `path`, atomically.
pub fn write(path: &Path, ids: &[FrameId]) -> Result<()> {
    super::atomic_write(path, to_text(ids).as_bytes(), super::Durability::Renamed)
}
