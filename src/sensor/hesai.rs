//! Hesai angle-correction tables: a CSV with a header line (`Laser id,Elevation,Azimuth` or
//! `Channel,Elevation,Azimuth`) and one line per laser, angles in degrees, ids 1-based (the
//! drivers' ring / channel field counts from 0: beam id = laser id - 1).

use std::path::Path;

use super::{file_stem, Beam, BeamTable, SensorModel};
use crate::error::{Error, Result};
use crate::fs::{self, Limit};
use crate::geom::Degrees;

/// Reads a Hesai angle-correction CSV; the sensor is named after the file.
pub fn read(path: &Path) -> Result<SensorModel> {
    let text = fs::read_text(path, Limit::Text)?;
    parse(&text, path, file_stem(path))
}

/// Parses the CSV text of `path` into a model called `name`.
pub fn parse(text: &str, path: &Path, name: String) -> Result<SensorModel> {
    let mut lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty());
    let Some((_, header)) = lines.next() else {
        return Err(Error::format(
            path,
            "the table is empty: no header, no beam",
        ));
    };
    let header: Vec<String> = header
        .split(',')
        .map(|h| h.trim().to_ascii_lowercase())
        .collect();
    if header.len() < 3 || !header[1].starts_with("elevation") || !header[2].starts_with("azimuth")
    {
        return Err(Error::NotFormat {
            path: path.into(),
            format: "a Hesai angle-correction table",
            detail: format!(
                "the header is {:?}, expected `Laser id,Elevation,Azimuth`",
                header.join(",")
            ),
        });
    }
    let mut beams = Vec::new();
    for (i, line) in lines {
        let bad = |m: String| Error::Format {
            path: path.into(),
            line: Some(i + 1),
            message: m,
        };
        let cells: Vec<&str> = line.split(',').map(str::trim).collect();
        if cells.len() < 3 {
            return Err(bad(format!(
                "{} values, expected 3 (id, elevation, azimuth)",
                cells.len()
            )));
        }
        let id: u32 = cells[0]
            .parse()
            .map_err(|_| bad(format!("laser id {:?} is not a whole number", cells[0])))?;
        let angle = |s: &str, what: &str| {
            s.parse::<f64>()
                .map_err(|_| bad(format!("{what} {s:?} is not a number")))
        };
        if id == 0 || id > u16::MAX as u32 {
            return Err(bad(format!(
                "laser id {id} is not in 1-65535 (Hesai counts from 1)"
            )));
        }
        beams.push(Beam {
            id: (id - 1) as u16,
            elevation: Degrees(angle(cells[1], "elevation")?),
            azimuth: Degrees(angle(cells[2], "azimuth")?),
        });
    }
    Ok(SensorModel::plain(name, BeamTable::new(beams, path)?))
}
