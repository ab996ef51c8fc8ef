//! READ: an odometry sequence's `poses.txt` (camera-0 pose of each scan in the first scan's
//! camera frame, 12 numbers a line: a 3x4 matrix row by row) and `times.txt` (seconds a line).

use std::path::Path;

use crate::error::{Error, Result};
use crate::geom::Matrix3x4;

/// The poses of a sequence, one per scan.
pub fn read(path: &Path) -> Result<Vec<Matrix3x4>> {
    let text = crate::fs::read_text(path, crate::fs::Limit::Text)?;
    parse(&text, path)
}

/// Parses `poses.txt` text; `path` names it in errors (with the line).
pub fn parse(text: &str, path: &Path) -> Result<Vec<Matrix3x4>> {
    text.lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty())
        .map(|(i, l)| {
            let v: Vec<f64> = l
                .split_whitespace()
                .map(|s| s.parse::<f64>().ok().filter(|x| x.is_finite()))
                .collect::<Option<_>>()
                .ok_or_else(|| Error::Format {
                    path: path.into(),
                    line: Some(i + 1),
                    message: "not a list of finite numbers".into(),
                })?;
            if v.len() != 12 {
                return Err(Error::Format {
                    path: path.into(),
                    line: Some(i + 1),
                    message: format!("{} numbers, expected 12 (a 3x4 pose)", v.len()),
                });
            }
            Ok(Matrix3x4::from_row_slice(&v))
        })
        .collect()
}

/// The number of non-empty lines of a text file (`times.txt`).
pub fn count_lines(path: &Path) -> Result<usize> {
    let text = crate::fs::read_text(path, crate::fs::Limit::Text)?;
    Ok(text.lines().filter(|l| !l.trim().is_empty()).count())
}

/// A sequence's `times.txt`: seconds a scan, one a line; a line that is not a number is an
/// error naming it.
pub fn read_times(path: &Path) -> Result<Vec<f64>> {
    let text = crate::fs::read_text(path, crate::fs::Limit::Text)?;
    (text.lines().enumerate())
        .filter(|(_, l)| !l.trim().is_empty())
        .map(|(i, l)| {
            l.trim()
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| {
                    crate::error::Error::format(
                        path,
                        format!("line {}: {l:?} is not a time in seconds", i + 1),
                    )
                })
        })
        .collect()
}

/// `times.txt` text for scans taken `nanos` nanoseconds after the first: seconds a line,
/// written exactly (nine decimals, no float rounding).
pub fn times_text(nanos: impl IntoIterator<Item = i64>) -> String {
    let mut out = String::new();
    for n in nanos {
        let sign = if n < 0 { "-" } else { "" };
        let a = n.unsigned_abs();
        out += &format!("{sign}{}.{:09}\n", a / 1_000_000_000, a % 1_000_000_000);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_and_names_bad_lines() {
        let p = Path::new("poses.txt");
        let m = parse("1 0 0 1 0 1 0 2 0 0 1 3\n", p).unwrap();
        assert_eq!(m[0][(1, 3)], 2.0);
        let e = parse("1 0 0 1\n", p).unwrap_err().to_string();
        assert!(
            e.contains("poses.txt:1") && e.contains("expected 12"),
            "{e}"
        );
        assert!(parse("1 0 0 1 0 1 0 2 0 0 1 nan\n", p).is_err());
    }

    #[test]
    fn times_are_exact_seconds() {
        assert_eq!(
            times_text([0, 100_000_001, -5, 3_600_000_000_123]),
            "0.000000000\n0.100000001\n-0.000000005\n3600.000000123\n"
        );
    }
}
