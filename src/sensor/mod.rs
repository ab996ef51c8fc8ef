//! The SENSOR MODEL: which beam of a spinning LiDAR measured each point, so that the map's rows
//! are the sensor's beams, exactly, for any sensor whose beam table is known.
//!
//! A [`BeamTable`] lists the beams (an id as the sensor's driver numbers it, and the beam's
//! elevation); the rows of a map are the beams ordered from the highest elevation (row 0) to the
//! lowest, as KITTI's rings are. Tables come from the vendors' calibration files, each read by
//! its own module ([`velodyne`]: velodyne_pointcloud's YAML, [`hesai`]: Hesai's angle-correction
//! CSV, [`ouster`]: Ouster's metadata JSON), or from the built-in [`presets`] by sensor name.
//!
//! A point's beam is the beam of the nearest elevation ([`SensorModel::beams`]), seen from the
//! beam's origin: Ouster's beams start `lidar_origin_to_beam_origin_mm` off the axis, and its
//! points are written in the sensor frame (`lidar_to_sensor_transform`), both undone first. A
//! point farther from its nearest beam than half the smallest gap between that beam and its
//! neighbours fits no beam: it keeps the nearest beam's row and is counted ([`BeamRows::off_model`]);
//! many of them mean the cloud is not in the sensor's frame.

pub mod hesai;
pub mod ouster;
pub mod params;
pub mod pose;
pub mod presets;
mod read;
mod slopes;
pub mod velodyne;

use std::path::Path;

use serde::{Deserialize, Serialize};

pub use params::{SensorParams, SensorSource};
pub use pose::SensorPose;
pub use read::{prepare_scan, read_scan};

use crate::error::{Error, Result};
use crate::geom::{na, Degrees, Point3};
use slopes::Slopes;

/// The most beams a table may have (rows of a map are `u8` ring ids).
pub const MAX_BEAMS: usize = 256;

/// Two beams closer in elevation than this (degrees) are one elevation: a table with them cannot
/// tell their points apart.
pub const SAME_ELEVATION_DEG: f64 = 1e-4;

/// One beam (laser) of a spinning sensor.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Beam {
    /// The beam's id in its calibration table, 0-based (Velodyne's `laser_id`, Hesai's laser id
    /// - 1, Ouster's beam index). Drivers' ring fields count otherwise: [`ring_rows`].
    pub id: u16,
    /// Elevation above the horizontal plane.
    pub elevation: Degrees,
    /// Azimuth offset of the beam (informative; columns come from each point's own azimuth).
    pub azimuth: Degrees,
}

/// The beams of a sensor, ordered from the highest elevation (row 0) to the lowest.
#[derive(Debug, Clone, PartialEq)]
pub struct BeamTable {
    beams: Vec<Beam>,
    /// Elevations in radians, in row order (for the assignment).
    elevations: Vec<f64>,
    /// Half the smallest gap around each beam, radians.
    tolerance: Vec<f64>,
    /// The slopes (tangents) of the boundaries between rows k and k + 1, descending, and of
    /// each beam's tolerance band: `nearest` without an arc tangent per point.
    slopes: Slopes,
}

impl BeamTable {
    /// A table of `beams` (any order). Errors (naming `path`, the file they came from): no
    /// beam, more than [`MAX_BEAMS`], a non-finite or impossible elevation, two beams with one
    /// id, two beams at one elevation.
    pub fn new(mut beams: Vec<Beam>, path: &Path) -> Result<BeamTable> {
        let bad = |m: String| Error::format(path, m);
        if beams.is_empty() {
            return Err(bad("the table has no beam".into()));
        }
        if beams.len() > MAX_BEAMS {
            return Err(bad(format!(
                "the table has {} beams, more than the {MAX_BEAMS} a map's rows can hold",
                beams.len()
            )));
        }
        for b in &beams {
            if !(b.elevation.0.is_finite() && (-90.0..=90.0).contains(&b.elevation.0)) {
                return Err(bad(format!(
                    "beam {} has elevation {} deg, not an angle in [-90, 90]",
                    b.id, b.elevation.0
                )));
            }
            if !b.azimuth.0.is_finite() {
                return Err(bad(format!("beam {} has a non-finite azimuth", b.id)));
            }
        }
        let mut ids: Vec<u16> = beams.iter().map(|b| b.id).collect();
        ids.sort_unstable();
        if let Some(w) = ids.windows(2).find(|w| w[0] == w[1]) {
            return Err(bad(format!("two beams have id {}", w[0])));
        }
        beams.sort_by(|a, b| {
            b.elevation
                .0
                .total_cmp(&a.elevation.0)
                .then(a.id.cmp(&b.id))
        });
        if let Some(w) = beams
            .windows(2)
            .find(|w| w[0].elevation.0 - w[1].elevation.0 < SAME_ELEVATION_DEG)
        {
            return Err(bad(format!(
                "beams {} and {} are at one elevation ({} deg): their points cannot be told apart",
                w[0].id, w[1].id, w[0].elevation.0
            )));
        }
        let elevations: Vec<f64> = beams.iter().map(|b| b.elevation.to_radians()).collect();
        let n = elevations.len();
        let tolerance: Vec<f64> = (0..n)
            .map(|i| {
                let up = (i > 0).then(|| elevations[i - 1] - elevations[i]);
                let down = (i + 1 < n).then(|| elevations[i] - elevations[i + 1]);
                // A one-beam table takes anything within 1 degree.
                let gap = match (up, down) {
                    (Some(a), Some(b)) => a.min(b),
                    (Some(a), None) | (None, Some(a)) => a,
                    (None, None) => 2f64.to_radians(),
                };
                gap / 2.0
            })
            .collect();
        let slopes = Slopes::new(&elevations, &tolerance);
        Ok(BeamTable {
            beams,
            elevations,
            tolerance,
            slopes,
        })
    }

    /// The beams in row order (highest elevation first).
    pub fn beams(&self) -> &[Beam] {
        &self.beams
    }

    /// Number of beams (the map's rows).
    pub fn len(&self) -> usize {
        self.beams.len()
    }

    /// Whether the table has no beam (never: [`BeamTable::new`] refuses it).
    pub fn is_empty(&self) -> bool {
        self.beams.is_empty()
    }

    /// The row of the beam with id `id`, if the table has it.
    pub fn row_of_id(&self, id: u32) -> Option<u8> {
        self.beams
            .iter()
            .position(|b| u32::from(b.id) == id)
            .map(|row| row as u8)
    }

    /// The row of the beam nearest to elevation `e` (radians), and whether `e` fits that beam
    /// (within half the smallest gap around it).
    #[inline]
    pub fn nearest(&self, e: f64) -> (u8, bool) {
        // Elevations descend: the first beam at or below `e`.
        let k = self.elevations.partition_point(|&b| b > e);
        let row = if k == 0 {
            0
        } else if k == self.elevations.len() || self.elevations[k - 1] - e <= e - self.elevations[k]
        {
            k - 1
        } else {
            k
        };
        let fits = (self.elevations[row] - e).abs() <= self.tolerance[row];
        (row as u8, fits)
    }

    /// [`BeamTable::nearest`] for the elevation `z.atan2(horizontal)`, compared as a slope
    /// (the same row but where rounding decides a point exactly on a boundary; 4x faster).
    #[inline]
    pub fn nearest_slope(&self, z: f64, horizontal: f64) -> (u8, bool) {
        self.nearest_at_slope(slope(z, horizontal), || (z, horizontal))
    }

    /// The row of slope `t` ([`slope`]) of a point whose height and horizontal distance
    /// `seen` gives: by the slope where it is finite, else by the arc tangent.
    #[inline(always)]
    fn nearest_at_slope(&self, t: f64, seen: impl FnOnce() -> (f64, f64)) -> (u8, bool) {
        if t.is_finite() {
            self.slopes.row(t)
        } else {
            let (z, horizontal) = seen();
            self.nearest(z.atan2(horizontal))
        }
    }
}

/// The slope `z / horizontal` of a point in front of its beam's origin (`horizontal > 0`); NaN
/// otherwise, where the arc tangent decides.
#[inline(always)]
fn slope(z: f64, horizontal: f64) -> f64 {
    if horizontal > 0.0 {
        z / horizontal
    } else {
        f64::NAN
    }
}

/// Points per block of [`SensorModel::assign`]'s two passes (slopes, vectorised; then rows).
const BLOCK: usize = 256;

/// Where the points of a cloud are, relative to the beams' origins: Ouster's beams start
/// `beam_origin_offset` metres off the axis, and its points are in the sensor frame.
#[derive(Debug, Clone, PartialEq)]
pub struct SensorModel {
    /// The sensor's name (`VLP-16`, `OS-1-32-G`, a calibration file's name).
    pub name: String,
    /// The beams.
    pub table: BeamTable,
    /// Distance from the lidar's axis to each beam's origin, metres (Ouster; 0 otherwise).
    pub beam_origin_offset: f64,
    /// The lidar frame (beams) to the frame the points are written in (Ouster's
    /// `lidar_to_sensor_transform`; identity otherwise), metres.
    pub lidar_to_points: na::Isometry3<f64>,
}

/// The beam of every point of a cloud.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct BeamRows {
    /// The row (beam rank by elevation, 0 = highest) of every point.
    pub rows: Vec<u8>,
    /// Points whose elevation fits no beam (they keep the nearest beam's row).
    pub off_model: u64,
}

impl SensorModel {
    /// A model of beams at the origin, points in the lidar frame (Velodyne, Hesai).
    pub fn plain(name: impl Into<String>, table: BeamTable) -> SensorModel {
        SensorModel {
            name: name.into(),
            table,
            beam_origin_offset: 0.0,
            lidar_to_points: na::Isometry3::identity(),
        }
    }

    /// Number of beams (rows).
    pub fn beams(&self) -> usize {
        self.table.len()
    }

    /// The elevation of `p` seen from its beam's origin, radians.
    #[inline]
    pub fn elevation(&self, p: &Point3, points_to_lidar: &na::Isometry3<f64>) -> f64 {
        let (z, horizontal) = self.seen_from_beams(p, points_to_lidar);
        z.atan2(horizontal)
    }

    /// `p`'s height and horizontal distance from its beam's origin, metres.
    #[inline]
    fn seen_from_beams(&self, p: &Point3, points_to_lidar: &na::Isometry3<f64>) -> (f64, f64) {
        let q = points_to_lidar * na::Point3::new(p.x as f64, p.y as f64, p.z as f64);
        (
            q.z,
            (q.x * q.x + q.y * q.y).sqrt() - self.beam_origin_offset,
        )
    }

    /// The beam row of every point (nearest elevation), and how many fit no beam.
    pub fn assign(&self, points: &[Point3]) -> BeamRows {
        let inverse = self.lidar_to_points.inverse();
        let plain = self.beam_origin_offset == 0.0 && inverse == na::Isometry3::identity();
        let seen = |p: &Point3| {
            if plain {
                let (x, y) = (p.x as f64, p.y as f64);
                (p.z as f64, (x * x + y * y).sqrt())
            } else {
                self.seen_from_beams(p, &inverse)
            }
        };
        let mut off_model = 0u64;
        let mut rows = vec![0u8; points.len()];
        let mut slopes = [0f64; BLOCK];
        for (block, rows) in points.chunks(BLOCK).zip(rows.chunks_mut(BLOCK)) {
            let slopes = &mut slopes[..block.len()];
            for (t, p) in slopes.iter_mut().zip(block) {
                let (z, horizontal) = seen(p);
                *t = slope(z, horizontal);
            }
            // Counted in a local: a count behind a reference was a store-to-load chain.
            let mut off = 0u64;
            for ((row, p), &t) in rows.iter_mut().zip(block).zip(slopes.iter()) {
                let (beam, fits) = self.table.nearest_at_slope(t, || seen(p));
                *row = beam;
                off += u64::from(!fits);
            }
            off_model += off;
        }
        BeamRows { rows, off_model }
    }
}

/// How a ring / channel field numbers the beams.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash)]
pub enum RingOrder {
    /// Ring 0 is the lowest beam (velodyne_pointcloud's `ring`, nebula's `channel`, nuScenes'
    /// ring index).
    #[default]
    BottomUp,
    /// Ring 0 is the highest beam (Hesai's own driver, Ouster's channel).
    TopDown,
}

crate::named_enum!(RingOrder, "ring order", [
    BottomUp => "bottom-up" [] "Ring 0 is the lowest beam (velodyne_pointcloud, nebula, nuScenes)",
    TopDown => "top-down" [] "Ring 0 is the highest beam (Hesai's driver, Ouster)",
]);

/// The rows of a cloud whose points carry their ring (a ring / channel / laser id field) of a
/// sensor of `beams` beams: row 0 the highest beam. A ring at or beyond `beams` is an error
/// naming `path`.
pub fn ring_rows(rings: &[u16], beams: usize, order: RingOrder, path: &Path) -> Result<Vec<u8>> {
    if beams == 0 || beams > MAX_BEAMS {
        return Err(Error::Config(format!(
            "{beams} beams: a sensor has 1 to {MAX_BEAMS}"
        )));
    }
    if let Some((i, r)) = rings.iter().enumerate().find(|(_, &r)| r as usize >= beams) {
        return Err(Error::format(
            path,
            format!(
                "point {i} has ring {r}, but the sensor has {beams} beams (rings 0-{}); give the \
                 sensor (--sensor, --sensor-calibration) or its beam count (--beams)",
                beams - 1
            ),
        ));
    }
    Ok(match order {
        RingOrder::BottomUp => rings
            .iter()
            .map(|&r| (beams - 1 - r as usize) as u8)
            .collect(),
        RingOrder::TopDown => rings.iter().map(|&r| r as u8).collect(),
    })
}

/// Reads a sensor model from a vendor's calibration file, by its extension: `.yaml` / `.yml`
/// (velodyne_pointcloud), `.csv` (Hesai), `.json` (Ouster metadata).
pub fn read_calibration(path: &Path) -> Result<SensorModel> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    match ext.as_deref() {
        Some("yaml" | "yml") => velodyne::read(path),
        Some("csv") => hesai::read(path),
        Some("json") => ouster::read(path),
        _ => Err(Error::format(
            path,
            "not a calibration table kitti2pgm reads: expected a velodyne_pointcloud .yaml, a \
             Hesai angle-correction .csv or an Ouster metadata .json",
        )),
    }
}

/// A sensor model by a built-in sensor's name (`vlp16`, `pandar64`: [`presets::Sensor`]) or a
/// calibration file's path (`.yaml`, `.csv`, `.json`: [`read_calibration`]).
pub fn model_named_or_file(name: &str) -> Result<SensorModel> {
    if let Ok(s) = name.parse::<presets::Sensor>() {
        return Ok(s.model_table());
    }
    let path = Path::new(name);
    if path.extension().is_some() {
        return read_calibration(path);
    }
    Err(unknown_sensor(name))
}

/// The error for a sensor name that is neither built in nor a calibration file.
pub(crate) fn unknown_sensor(name: &str) -> Error {
    let names: Vec<&str> = presets::Sensor::ALL.iter().map(|s| s.as_str()).collect();
    Error::Config(format!(
        "sensor {name:?} is neither a built-in sensor ({}) nor a calibration file (.yaml, .csv, \
         .json)",
        names.join(", ")
    ))
}

/// The sensor name of a calibration file: its stem.
pub(crate) fn file_stem(path: &Path) -> String {
    path.file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or("sensor")
        .to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn beam(id: u16, e: f64) -> Beam {
        Beam {
            id,
            elevation: Degrees(e),
            azimuth: Degrees(0.0),
        }
    }

    #[test]
    fn slopes_give_the_rows_and_fits_of_the_elevations() {
        // Every preset, elevations every 0.0007 degrees over [-40, 25] at three distances: the
        // slope comparison agrees with the arc tangent but within 1e-9 rad of a boundary.
        for sensor in presets::Sensor::ALL {
            let t = sensor.model_table().table;
            let e = &t.elevations;
            let mut edges: Vec<f64> = e.windows(2).map(|w| (w[0] + w[1]) / 2.0).collect();
            edges.extend((0..e.len()).flat_map(|i| [e[i] - t.tolerance[i], e[i] + t.tolerance[i]]));
            let mut checked = 0;
            for k in 0..(65.0f64 / 0.0007) as i64 {
                let deg = -40.0 + k as f64 * 0.0007;
                for h in [0.5, 7.3, 80.0] {
                    let z = h * deg.to_radians().tan();
                    let a = z.atan2(h);
                    if edges.iter().any(|b| (a - b).abs() < 1e-9) {
                        continue;
                    }
                    assert_eq!(t.nearest_slope(z, h), t.nearest(a), "{sensor:?} {deg} deg");
                    checked += 1;
                }
            }
            assert!(checked > 270_000);
        }
        let t = presets::Sensor::Vlp16.model_table().table;
        // On the axis, and behind it (negative horizontal distance), the arc tangent decides.
        assert_eq!(t.nearest_slope(1.0, 0.0), t.nearest(1f64.atan2(0.0)));
        assert_eq!(t.nearest_slope(0.0, 0.0), t.nearest(0.0));
        assert_eq!(t.nearest_slope(0.1, -2.0), t.nearest(0.1f64.atan2(-2.0)));
    }

    #[test]
    fn rows_run_from_the_highest_beam() {
        let t = BeamTable::new(
            vec![beam(0, -15.0), beam(1, 1.0), beam(2, -13.0)],
            Path::new("t"),
        )
        .unwrap();
        assert_eq!(t.row_of_id(1), Some(0));
        assert_eq!(t.row_of_id(2), Some(1));
        assert_eq!(t.row_of_id(0), Some(2));
        assert_eq!(t.row_of_id(3), None);
        // Half the smallest gap around beam 2 (-13) is 1 degree.
        assert_eq!(t.nearest((-13.9f64).to_radians()), (1, true));
        assert_eq!(t.nearest((-14.1f64).to_radians()), (2, true));
        // 5 degrees above the top beam (half its gap: 7 degrees) still fits; 8 do not.
        assert_eq!(t.nearest(6f64.to_radians()), (0, true));
        assert_eq!(t.nearest(9f64.to_radians()), (0, false));
    }

    #[test]
    fn bad_tables_are_refused() {
        let p = Path::new("calib.csv");
        let e = BeamTable::new(vec![], p).unwrap_err().to_string();
        assert!(e.contains("calib.csv") && e.contains("no beam"), "{e}");
        let e = BeamTable::new(vec![beam(0, 1.0), beam(1, 1.0)], p)
            .unwrap_err()
            .to_string();
        assert!(e.contains("one elevation"), "{e}");
        let e = BeamTable::new(vec![beam(0, 1.0), beam(0, 2.0)], p)
            .unwrap_err()
            .to_string();
        assert!(e.contains("two beams have id 0"), "{e}");
        let e = BeamTable::new(vec![beam(0, f64::NAN)], p)
            .unwrap_err()
            .to_string();
        assert!(e.contains("not an angle"), "{e}");
    }
}
