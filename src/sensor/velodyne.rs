//! Velodyne calibration tables in velodyne_pointcloud's YAML layout (`lasers:` with `laser_id`,
//! `vert_correction` and `rot_correction` in radians; `num_lasers`), as the ROS drivers and
//! Autoware's nebula ship them for every model.

use std::path::Path;

use serde::Deserialize;

use super::{file_stem, Beam, BeamTable, SensorModel};
use crate::error::{Error, Result};
use crate::fs::{self, Limit};
use crate::geom::Degrees;

#[derive(Deserialize)]
struct File {
    lasers: Vec<Laser>,
    num_lasers: Option<usize>,
}

#[derive(Deserialize)]
struct Laser {
    laser_id: u16,
    vert_correction: f64,
    #[serde(default)]
    rot_correction: f64,
}

/// Reads a velodyne_pointcloud calibration YAML; the sensor is named after the file.
pub fn read(path: &Path) -> Result<SensorModel> {
    let text = fs::read_text(path, Limit::Text)?;
    parse(&text, path, file_stem(path))
}

/// Parses the YAML text of `path` into a model called `name`.
pub fn parse(text: &str, path: &Path, name: String) -> Result<SensorModel> {
    let file: File = serde_norway::from_str(text).map_err(|e| Error::NotFormat {
        path: path.into(),
        format: "a velodyne_pointcloud calibration (lasers: laser_id, vert_correction)",
        detail: e.to_string(),
    })?;
    if let Some(n) = file.num_lasers.filter(|&n| n != file.lasers.len()) {
        return Err(Error::format(
            path,
            format!(
                "num_lasers is {n} but {} lasers are listed",
                file.lasers.len()
            ),
        ));
    }
    let beams = file
        .lasers
        .iter()
        .map(|l| Beam {
            id: l.laser_id,
            elevation: Degrees(l.vert_correction.to_degrees()),
            azimuth: Degrees(l.rot_correction.to_degrees()),
        })
        .collect();
    Ok(SensorModel::plain(name, BeamTable::new(beams, path)?))
}
