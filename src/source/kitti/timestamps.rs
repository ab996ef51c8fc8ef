//! READ: `timestamps.txt` files (one `YYYY-MM-DD HH:MM:SS.fffffffff` a line, one line a frame).
//!
//! A blank line means the frame's timestamp is missing; it stays `None` so that line numbers keep
//! matching frame indices.

use std::path::Path;

use serde::Serialize;

use crate::error::{Error, Result};

/// A point in time, nanoseconds since the Unix epoch (KITTI's clock, taken as UTC).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
pub struct Timestamp(pub i64);

impl Timestamp {
    /// Parses `2011-09-26 13:02:25.951199337`.
    pub fn parse(s: &str) -> Option<Timestamp> {
        let t = chrono::NaiveDateTime::parse_from_str(s.trim(), "%Y-%m-%d %H:%M:%S%.f").ok()?;
        t.and_utc().timestamp_nanos_opt().map(Timestamp)
    }

    /// Seconds since the Unix epoch.
    pub fn as_secs_f64(self) -> f64 {
        self.0 as f64 * 1e-9
    }
}

/// Reads a timestamps file: entry `i` is frame `i`.
pub fn read(path: &Path) -> Result<Vec<Option<Timestamp>>> {
    let text = crate::fs::read_text(path, crate::fs::Limit::Text)?;
    parse(&text, path)
}

/// Parses timestamps text; `path` names the file in errors.
pub fn parse(text: &str, path: &Path) -> Result<Vec<Option<Timestamp>>> {
    text.lines()
        .enumerate()
        .map(|(i, line)| {
            if line.trim().is_empty() {
                return Ok(None);
            }
            Timestamp::parse(line)
                .map(Some)
                .ok_or_else(|| Error::Format {
                    path: path.into(),
                    line: Some(i + 1),
                    message: format!("not a timestamp: {line:?}"),
                })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blank_lines_are_missing_frames() {
        let t = parse(
            "2011-09-26 13:02:25.951199337\n\n2011-09-26 13:02:26.054281661\n",
            Path::new("t"),
        )
        .unwrap();
        assert_eq!(t.len(), 3);
        assert!(t[1].is_none());
        assert_eq!(t[2].unwrap().0 - t[0].unwrap().0, 103_082_324);
        assert!(parse("yesterday\n", Path::new("t.txt"))
            .unwrap_err()
            .to_string()
            .contains("t.txt:1"));
    }
}
