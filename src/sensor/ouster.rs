//! Ouster sensor metadata (the JSON the sensor and its SDK write): beam altitude and azimuth
//! angles, `lidar_origin_to_beam_origin_mm`, `lidar_to_sensor_transform`, and the data format
//! (pixels per column, columns per frame, pixel shift by row). Both layouts are read: the flat
//! one of firmware 2.0-2.3 and the nested one (`beam_intrinsics`, `lidar_intrinsics`,
//! `lidar_data_format`, `sensor_info`) of later firmware.
//!
//! Ouster's beam angles differ from unit to unit: there is no nominal table, each unit's own
//! metadata file is the model.

use std::path::Path;

use serde_json::Value;

use super::{file_stem, Beam, BeamTable, SensorModel};
use crate::error::{Error, Result};
use crate::fs::{self, Limit};
use crate::geom::{check_rotation, na, Degrees, Point3};

/// Ouster's frame layout: the image the vendor's tools show (rows = beams in metadata order,
/// columns = measurement ids, destaggered by each row's pixel shift).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct OusterFormat {
    /// Beams (pixels per column).
    pub pixels_per_column: usize,
    /// Columns (measurements) per frame.
    pub columns_per_frame: usize,
    /// The pixel shift of each row (staggered -> destaggered).
    pub pixel_shift_by_row: Vec<i64>,
}

/// An Ouster unit's own model: its beams as the neutral [`SensorModel`], and its frame layout
/// with what its columns need (each row's beam azimuth and pixel shift, the inverse of the
/// lidar-to-sensor transform), built once when the metadata is read.
#[derive(Debug, Clone, PartialEq)]
pub struct OusterModel {
    /// The beams, their origin offset and the sensor frame.
    pub sensor: SensorModel,
    /// The frame layout.
    pub format: OusterFormat,
    /// Per row: sine and cosine of the beam's azimuth as the SDK's lookup table turns it, and
    /// the row's pixel shift.
    rows: Vec<(f64, f64, i64)>,
    /// The points' frame to the lidar frame.
    to_lidar: na::Isometry3<f64>,
}

/// Reads an Ouster metadata JSON as a beam model; the sensor is named by its `prod_line` (else
/// the file). [`read_model`] keeps its frame layout too.
pub fn read(path: &Path) -> Result<SensorModel> {
    Ok(read_model(path)?.sensor)
}

/// Reads an Ouster metadata JSON as the unit's own model (its columns).
pub fn read_model(path: &Path) -> Result<OusterModel> {
    let text = fs::read_text(path, Limit::Text)?;
    parse_model(&text, path)
}

/// Parses the metadata text of `path` as a beam model.
pub fn parse(text: &str, path: &Path) -> Result<SensorModel> {
    Ok(parse_model(text, path)?.sensor)
}

/// Looks `key` up at the top level or in one of the nested sections.
fn field<'a>(root: &'a Value, sections: &[&str], key: &str) -> Option<&'a Value> {
    root.get(key)
        .or_else(|| sections.iter().find_map(|s| root.get(*s)?.get(key)))
}

fn numbers(v: &Value, path: &Path, key: &str) -> Result<Vec<f64>> {
    let bad = || Error::format(path, format!("{key} is not a list of numbers"));
    v.as_array()
        .ok_or_else(bad)?
        .iter()
        .map(|x| x.as_f64().filter(|x| x.is_finite()).ok_or_else(bad))
        .collect()
}

/// The largest offset inside a unit that a metadata file may state (the beam origin's from the
/// lidar's, the lidar's from the sensor's): Ouster's are tens of millimetres; a metre or more
/// is a damaged or made-up file, whose points would all miss the beam model.
const MAX_INTERNAL_OFFSET_MM: f64 = 1000.0;

/// `lidar_to_sensor_transform` (row-major 4x4, millimetres) as a rigid motion in metres.
fn sensor_frame(root: &Value, path: &Path) -> Result<na::Isometry3<f64>> {
    let key = "lidar_to_sensor_transform";
    let v = field(root, &["lidar_intrinsics"], key).ok_or_else(|| {
        Error::format(
            path,
            format!("no {key}: not the metadata of an Ouster sensor"),
        )
    })?;
    let transform = numbers(v, path, key)?;
    if transform.len() != 16 {
        return Err(Error::format(
            path,
            format!("{key} has {} numbers, expected 16", transform.len()),
        ));
    }
    let m = na::Matrix4::from_row_slice(&transform);
    let rotation = m.fixed_view::<3, 3>(0, 0).into_owned();
    check_rotation(&rotation).map_err(|e| Error::format(path, format!("{key} {e}")))?;
    let translation = na::Vector3::new(m[(0, 3)], m[(1, 3)], m[(2, 3)]) / 1000.0;
    let norm = translation.norm();
    if norm.is_nan() || norm > MAX_INTERNAL_OFFSET_MM / 1000.0 {
        return Err(Error::format(
            path,
            format!(
                "{key} moves the lidar {} mm from the sensor's origin: not an Ouster unit's \
                 (tens of millimetres; at most {MAX_INTERNAL_OFFSET_MM} mm taken)",
                crate::error::shown(norm * 1000.0)
            ),
        ));
    }
    Ok(na::Isometry3::from_parts(
        translation.into(),
        na::UnitQuaternion::from_matrix(&rotation),
    ))
}

/// The frame layout of a sensor of `beams` beams.
fn data_format(root: &Value, path: &Path, beams: usize) -> Result<OusterFormat> {
    let need = |key: &str| {
        field(root, &["data_format", "lidar_data_format"], key).ok_or_else(|| {
            Error::format(
                path,
                format!("no {key}: not the metadata of an Ouster sensor"),
            )
        })
    };
    let count = |key: &str| -> Result<usize> {
        need(key)?
            .as_u64()
            .filter(|&v| v > 0 && v <= 1 << 16)
            .map(|v| v as usize)
            .ok_or_else(|| Error::format(path, format!("{key} is not a positive whole number")))
    };
    let format = OusterFormat {
        pixels_per_column: count("pixels_per_column")?,
        columns_per_frame: count("columns_per_frame")?,
        pixel_shift_by_row: numbers(need("pixel_shift_by_row")?, path, "pixel_shift_by_row")?
            .into_iter()
            .map(|v| v as i64)
            .collect(),
    };
    if format.pixels_per_column != beams || format.pixel_shift_by_row.len() != beams {
        return Err(Error::format(
            path,
            format!(
                "{beams} beams, but pixels_per_column is {} and pixel_shift_by_row has {} values",
                format.pixels_per_column,
                format.pixel_shift_by_row.len()
            ),
        ));
    }
    Ok(format)
}

/// Parses the metadata text of `path` as the unit's own model.
pub fn parse_model(text: &str, path: &Path) -> Result<OusterModel> {
    let root: Value = serde_json::from_str(text).map_err(|e| Error::NotFormat {
        path: path.into(),
        format: "Ouster metadata (JSON)",
        detail: e.to_string(),
    })?;
    let need = |sections: &[&str], key: &str| {
        field(&root, sections, key).ok_or_else(|| {
            Error::format(
                path,
                format!("no {key}: not the metadata of an Ouster sensor"),
            )
        })
    };
    let beam = ["beam_intrinsics"];
    let altitude = numbers(
        need(&beam, "beam_altitude_angles")?,
        path,
        "beam_altitude_angles",
    )?;
    let azimuth = numbers(
        need(&beam, "beam_azimuth_angles")?,
        path,
        "beam_azimuth_angles",
    )?;
    if altitude.len() != azimuth.len() {
        return Err(Error::format(
            path,
            format!(
                "{} beam altitude angles but {} azimuth angles",
                altitude.len(),
                azimuth.len()
            ),
        ));
    }
    let offset_mm = need(&beam, "lidar_origin_to_beam_origin_mm")?
        .as_f64()
        .filter(|v| (0.0..=MAX_INTERNAL_OFFSET_MM).contains(v))
        .ok_or_else(|| {
            Error::format(
                path,
                format!(
                    "lidar_origin_to_beam_origin_mm is not a number of 0-{MAX_INTERNAL_OFFSET_MM} \
                     mm (an Ouster unit's is 15-30 mm)"
                ),
            )
        })?;
    let lidar_to_points = sensor_frame(&root, path)?;
    let beams = altitude
        .iter()
        .zip(&azimuth)
        .enumerate()
        .map(|(i, (&alt, &az))| Beam {
            id: i as u16,
            elevation: Degrees(alt),
            azimuth: Degrees(az),
        })
        .collect();
    let table = BeamTable::new(beams, path)?;
    let name = field(&root, &["sensor_info"], "prod_line")
        .and_then(Value::as_str)
        .map_or_else(|| file_stem(path), str::to_string);
    let sensor = SensorModel {
        name,
        table,
        beam_origin_offset: offset_mm / 1000.0,
        lidar_to_points,
    };
    Ok(OusterModel::new(
        sensor,
        data_format(&root, path, altitude.len())?,
    ))
}

impl OusterModel {
    /// The model of `sensor` with the frame layout `format`: its tables built.
    pub fn new(sensor: SensorModel, format: OusterFormat) -> OusterModel {
        let rows = (sensor.table.beams().iter())
            .map(|b| {
                let t = -b.azimuth.to_radians();
                (t.sin(), t.cos(), format.pixel_shift_by_row[b.id as usize])
            })
            .collect();
        let to_lidar = sensor.lidar_to_points.inverse();
        OusterModel {
            sensor,
            format,
            rows,
            to_lidar,
        }
    }

    /// Checks that a map of `cols` columns over `fov` can hold Ouster's columns: a full turn of
    /// exactly the columns per frame.
    pub fn check_map(&self, cols: usize, fov: Degrees) -> Result<()> {
        let w = self.format.columns_per_frame;
        if cols != w || fov.0 != 360.0 {
            return Err(Error::Config(format!(
                "Ouster columns: the map must be {w} columns over 360 degrees (the sensor's \
                 columns per frame), not {cols} over {} degrees",
                fov.0
            )));
        }
        Ok(())
    }

    /// The destaggered column of every point (Ouster's own image: the SDK's `destagger` of its
    /// measurement ids) of a cloud whose beam rows are `rows`.
    ///
    /// Ouster's `XYZLut` puts the pixel of beam `u`, measurement id `m` at
    /// `T * ((r - n) d + n (cos e, sin e, 0))`: encoder angle `e = 2 pi (1 - m / W)`, direction
    /// `d` at `e - azimuth[u]` and `altitude[u]`, `n` the beam origin offset, `T` the lidar to
    /// sensor transform. Undone here in closed form: with `a` the horizontal reach from the beam
    /// origin, the point's horizontal distance `rho` from the axis is
    /// `|a u(e + t) + n u(e)|` (`t` the beam's azimuth), so `a = -n cos t + sqrt(rho^2 - n^2
    /// sin^2 t)` and `e = atan2(y, x) - atan2(a sin t, a cos t + n)`; `m` is `e` rounded to the
    /// nearest measurement, then shifted by the row's pixel shift.
    pub fn columns(&self, points: &[Point3], rows: &[u8]) -> Vec<u16> {
        use std::f64::consts::TAU;
        let (to_lidar, per_row) = (&self.to_lidar, &self.rows);
        let n = self.sensor.beam_origin_offset;
        let w = self.format.columns_per_frame as f64;
        let width = self.format.columns_per_frame as i64;
        points
            .iter()
            .zip(rows)
            .map(|(p, &row)| {
                let q = to_lidar * na::Point3::new(p.x as f64, p.y as f64, p.z as f64);
                let (sin_t, cos_t, shift) = per_row[row as usize];
                let rho2 = q.x * q.x + q.y * q.y;
                let a = -n * cos_t + (rho2 - n * n * sin_t * sin_t).max(0.0).sqrt();
                let e = q.y.atan2(q.x) - (a * sin_t).atan2(a * cos_t + n);
                let m = (w * (1.0 - e / TAU)).round() as i64;
                (m + shift).rem_euclid(width) as u16
            })
            .collect()
    }
}
