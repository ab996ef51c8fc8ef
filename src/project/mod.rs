//! PROJECT: velodyne points to the Polar Grid Map (PGM), SqueezeSeg's range image.
//!
//! Columns come from the azimuth: `column = floor((fov/2 - yaw) / (fov/cols))` with
//! `yaw = atan2(y, x)` (computed in f64), kept when `0 <= column < cols`; the default map is
//! 512 columns over the front 90 degrees, so straight ahead lands on column 256 and the left
//! edge (+45 degrees) on column 0.
//!
//! Rows come from the scan order ([`rings`]): a KITTI scan stores its 64 lasers one after the
//! other, each one revolution with the azimuth increasing, and a new ring starts where
//! `atan2(y, x)` crosses the forward direction from negative to non-negative. Row 0 is the first
//! ring (the top laser, about +2.3 degrees), row 63 the last (about -23.6 degrees). This is
//! exact where elevation binning is not: the lasers' elevations are not evenly spaced, so binning
//! leaves empty rows ("black lines") and stacks neighbouring lasers in one row. A scan that does
//! not show exactly [`LASERS`] rings (a ring with no return in front, a partial scan) falls back
//! to elevation binning between `fov_up` and `fov_down` for that scan, and says so.
//!
//! When several points land in one cell the nearest wins (ties: the earlier point in the scan);
//! the losers are counted as collisions.

pub mod augment;
pub mod camera;
mod cells16;
pub mod channels;
mod claim;
pub mod cloud;
pub mod columns;
pub mod frame;
pub mod preset;
pub mod rows;
pub mod unproject;

pub use augment::Augment;
pub use channels::{Channel, Channels};
use claim::{claim, Claimed};
pub use cloud::{project_cloud, project_cloud_on, Cloud, CloudProjection, IntensityKind};
pub(crate) use columns::Geometry;
pub use columns::{atan2_fast, Columns, ATAN2_FAST_MAX_ERROR, BORDER, OUTSIDE};
pub use frame::{CellColours, PgmFrame};
pub use preset::{MapChoice, MapOrigin, MapPreset, MapValue};
pub use rows::{rings, Rows};
use rows::{row_source, RowSource};

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::geom::{floor_i64, Degrees, Point3};

/// Lasers of the HDL-64E that recorded KITTI.
pub const LASERS: usize = 64;

/// How rows are assigned.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RowMode {
    /// Rings recovered from the scan order, elevation binning as the fallback (the default).
    Rings,
    /// Elevation binning for every scan (what most public scripts do).
    Elevation,
}

crate::named_enum!(RowMode, "row mode", [
    Rings => "rings" [] "Rings recovered from the scan order; elevation binning only where a scan breaks it",
    Elevation => "elevation" [] "Elevation binning between the map's upper and lower field-of-view bounds, for every scan",
]);

/// Shape and field of view of the map.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PgmSpec {
    /// Rows (default 64).
    pub rows: usize,
    /// Columns (default 512).
    pub cols: usize,
    /// Horizontal field of view, centred on the x axis (default 90 degrees; 360 for a full map).
    pub fov: Degrees,
    /// Upper elevation limit for elevation binning (default +2.0 degrees).
    pub fov_up: Degrees,
    /// Lower elevation limit for elevation binning (default -24.9 degrees).
    pub fov_down: Degrees,
    /// Row assignment.
    pub row_mode: RowMode,
}

impl Default for PgmSpec {
    fn default() -> Self {
        PgmSpec {
            rows: 64,
            cols: 512,
            fov: Degrees(90.0),
            fov_up: Degrees(2.0),
            fov_down: Degrees(-24.9),
            row_mode: RowMode::Rings,
        }
    }
}

impl PgmSpec {
    /// Checks that the numbers make a map.
    pub fn validate(&self) -> Result<()> {
        if self.rows == 0 || self.cols == 0 || self.rows > 4096 || self.cols > 65536 {
            return Err(Error::Config(format!(
                "map size {}x{} is out of range",
                self.rows, self.cols
            )));
        }
        if !(self.fov.0 > 0.0 && self.fov.0 <= 360.0) {
            return Err(Error::Config(format!(
                "horizontal FOV {} deg must be in (0, 360]",
                self.fov.0
            )));
        }
        for (name, v) in [("fov-up", self.fov_up.0), ("fov-down", self.fov_down.0)] {
            if !(-90.0..=90.0).contains(&v) {
                return Err(Error::Config(format!(
                    "{name} {v:?} deg must be an elevation in [-90, 90]"
                )));
            }
        }
        if self.fov_up.0.partial_cmp(&self.fov_down.0) != Some(std::cmp::Ordering::Greater) {
            return Err(Error::Config(format!(
                "fov-up {} deg must be above fov-down {} deg",
                self.fov_up.0, self.fov_down.0
            )));
        }
        Ok(())
    }

    /// Number of cells.
    pub fn cells(&self) -> usize {
        self.rows * self.cols
    }

    /// For a map narrower than 180 degrees, the tangent of its half-angle with a margin
    /// (`tan(fov/2) * 1.001 + 1e-6`): the wedge `x > 0, |y| <= x t` holds every point in view,
    /// so rounding never rejects one. `None` for wider maps.
    #[inline]
    pub fn front_wedge(&self) -> Option<f32> {
        (self.fov.0 < 180.0).then(|| (self.fov.to_radians() / 2.0).tan() as f32 * 1.001 + 1e-6)
    }

    /// Row of a point by elevation binning (clamped into the map).
    #[inline]
    pub fn elevation_row(&self, p: &Point3, range: f32) -> usize {
        let up = self.fov_up.to_radians();
        let down = self.fov_down.to_radians();
        let pitch = ((p.z as f64) / (range as f64).max(1e-9))
            .clamp(-1.0, 1.0)
            .asin();
        let r = floor_i64((up - pitch) / (up - down) * self.rows as f64);
        r.clamp(0, self.rows as i64 - 1) as usize
    }

    /// Row of ring `ring` (0..LASERS): the ring itself for 64 rows, scaled otherwise.
    #[inline]
    pub fn ring_row(&self, ring: u8) -> usize {
        self.beam_row(ring, LASERS)
    }

    /// Row of beam row `beam` of a sensor of `beams` beams: the beam itself when the map has
    /// one row per beam, scaled otherwise.
    #[inline]
    pub fn beam_row(&self, beam: u8, beams: usize) -> usize {
        if self.rows == beams {
            beam as usize
        } else {
            beam as usize * self.rows / beams
        }
    }
}

/// What projecting scans found; added up over frames for the conversion summary.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct ProjectionStats {
    /// Points in the field of view.
    pub in_fov: u64,
    /// Cells holding a point.
    pub filled_cells: u64,
    /// Cells of the maps.
    pub total_cells: u64,
    /// Points that lost their cell to a nearer one.
    pub collisions: u64,
    /// Frames whose rows came from elevation binning because the rings were not usable.
    pub ring_fallbacks: u64,
    /// Frames whose rows came from a ring / channel field of the scan (another sensor's).
    #[serde(default)]
    pub ring_field_frames: u64,
    /// Frames whose rows came from the sensor's beam table (nearest beam by elevation).
    #[serde(default)]
    pub beam_table_frames: u64,
    /// Points whose elevation fits no beam of the sensor's table (they keep the nearest beam's
    /// row); many of them mean the scans are not in the sensor's frame.
    #[serde(default)]
    pub off_model: u64,
}

impl ProjectionStats {
    /// Filled cells over all cells (0 without cells).
    pub fn fill_ratio(&self) -> f64 {
        if self.total_cells == 0 {
            0.0
        } else {
            self.filled_cells as f64 / self.total_cells as f64
        }
    }
}

impl std::ops::AddAssign<&ProjectionStats> for ProjectionStats {
    fn add_assign(&mut self, o: &ProjectionStats) {
        self.in_fov += o.in_fov;
        self.filled_cells += o.filled_cells;
        self.total_cells += o.total_cells;
        self.collisions += o.collisions;
        self.ring_fallbacks += o.ring_fallbacks;
        self.ring_field_frames += o.ring_field_frames;
        self.beam_table_frames += o.beam_table_frames;
        self.off_model += o.off_model;
    }
}

/// Sentinel of an empty cell in [`Projection::cell_point`].
pub const EMPTY: u32 = u32::MAX;

/// Which point fills each cell of the map.
#[derive(Debug, Clone)]
pub struct Projection {
    /// The map's shape.
    pub spec: PgmSpec,
    /// Index (into the scan's points) of the point kept in each cell, row-major; [`EMPTY`] if none.
    pub cell_point: Vec<u32>,
    /// Range of the kept point, metres (0 for empty cells).
    pub cell_range: Vec<f32>,
    /// The cell of every point ([`EMPTY`] outside the field of view); empty unless asked for
    /// with [`project_with_point_cells`].
    pub point_cell: Vec<u32>,
    /// Counts (one frame's: `ring_fallbacks` is 0 or 1).
    pub stats: ProjectionStats,
    /// Rings seen in the scan order.
    pub rings_found: usize,
}

impl Projection {
    /// Whether rows came from elevation binning because the rings were not usable.
    pub fn fallback(&self) -> bool {
        self.stats.ring_fallbacks > 0
    }
}

/// Projects a scan's points onto the map.
pub fn project(points: &[Point3], spec: &PgmSpec) -> Projection {
    project_impl(
        points,
        spec,
        PointCells::Drop,
        Rows::FromSpec,
        Geometry::plain(points),
        1,
    )
}

/// Projects a scan's points with the rows of a sensor model ([`crate::sensor`]): `rows` holds
/// the beam row of every point (0 = the highest beam) of a sensor of `beams` beams; `columns`,
/// where given, the column of every point (the sensor's own, below `spec.cols`), else columns
/// are azimuth bins.
pub fn project_beams(
    points: &[Point3],
    spec: &PgmSpec,
    rows: &[u8],
    beams: usize,
    columns: Option<&[u16]>,
) -> Projection {
    beams_impl(points, spec, (rows, beams, columns), PointCells::Drop)
}

/// Like [`project_beams`], and also records the cell of every point.
pub fn project_beams_with_point_cells(
    points: &[Point3],
    spec: &PgmSpec,
    rows: &[u8],
    beams: usize,
    columns: Option<&[u16]>,
) -> Projection {
    beams_impl(points, spec, (rows, beams, columns), PointCells::Keep)
}

fn beams_impl(
    points: &[Point3],
    spec: &PgmSpec,
    (rows, beams, columns): (&[u8], usize, Option<&[u16]>),
    cells: PointCells,
) -> Projection {
    debug_assert!(columns.is_none_or(|c| c.len() == points.len()));
    let geometry = Geometry {
        columns,
        ..Geometry::plain(points)
    };
    project_impl(points, spec, cells, Rows::Beams(rows, beams), geometry, 1)
}

/// Reads the scan at `path` ([`crate::sensor::read_scan`]) and projects it as a conversion with
/// the map `spec` and `sensor` does (another sensor's pose, beam rows and columns), keeping the
/// cell of every point: what carries map predictions back to points (`unproject`, `score` per
/// point). The scan's points are in the sensor's frame, as the map's.
pub fn project_scan(
    spec: &PgmSpec,
    sensor: Option<&crate::sensor::SensorParams>,
    path: &std::path::Path,
) -> crate::error::Result<(crate::source::Scan, Projection)> {
    let (scan, beams) = crate::sensor::read_scan(sensor, path)?;
    Ok(project_prepared(spec, scan, beams))
}

/// [`project_scan`] of a scan read elsewhere (a bag's message, named `what`).
pub fn project_loaded_scan(
    spec: &PgmSpec,
    sensor: Option<&crate::sensor::SensorParams>,
    scan: crate::source::Scan,
    what: &std::path::Path,
) -> crate::error::Result<(crate::source::Scan, Projection)> {
    let (scan, beams) = crate::sensor::prepare_scan(sensor, scan, what)?;
    Ok(project_prepared(spec, scan, beams))
}

fn project_prepared(
    spec: &PgmSpec,
    scan: crate::source::Scan,
    beams: Option<crate::sensor::params::BeamRowsOf>,
) -> (crate::source::Scan, Projection) {
    let proj = match &beams {
        Some(b) => {
            let mut p = project_beams_with_point_cells(
                &scan.points,
                spec,
                &b.rows,
                b.beams,
                b.columns.as_deref(),
            );
            p.stats.off_model = b.off_model;
            p
        }
        None => project_with_point_cells(&scan.points, spec),
    };
    (scan, proj)
}

/// Like [`project`], and also records the cell of every point ([`Projection::point_cell`]),
/// for scoring per point.
pub fn project_with_point_cells(points: &[Point3], spec: &PgmSpec) -> Projection {
    project_impl(
        points,
        spec,
        PointCells::Keep,
        Rows::FromSpec,
        Geometry::plain(points),
        1,
    )
}

/// The range of a point, metres (float32, as every map stores it).
#[inline(always)]
pub fn norm(p: &Point3) -> f32 {
    (p.x * p.x + p.y * p.y + p.z * p.z).sqrt()
}

/// Whether a projection keeps the cell of every point ([`Projection::point_cell`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum PointCells {
    /// Kept (back-projection, per-point scoring, clouds).
    Keep,
    /// Not kept (the conversion: the map alone).
    Drop,
}

/// The projection of `points` (as the map stores them) with rows from `rows` and columns and
/// ranges from `geometry`, its points split among up to `threads` threads ([`claim`]).
pub(crate) fn project_impl(
    points: &[Point3],
    spec: &PgmSpec,
    point_cells: PointCells,
    rows: Rows<'_>,
    geometry: Geometry<'_>,
    threads: usize,
) -> Projection {
    debug_assert_eq!(points.len(), geometry.base.len());
    let RowSource {
        rings: ring_ids,
        found: rings_found,
        beams,
        fallback,
    } = row_source(points, spec, rows);
    let ring_ids = ring_ids.as_deref();
    let Claimed {
        cell_point,
        cell_range,
        point_cell,
        in_fov,
        filled,
    } = claim(
        points,
        spec,
        point_cells,
        (ring_ids, beams),
        geometry,
        threads,
    );
    Projection {
        spec: *spec,
        stats: ProjectionStats::count((filled, cell_point.len()), in_fov, fallback),
        cell_point,
        cell_range,
        point_cell,
        rings_found,
    }
}

impl ProjectionStats {
    /// The statistics of a projection that put `in_fov` points into `filled` of `cells` cells.
    fn count((filled, cells): (u64, usize), in_fov: u64, ring_fallback: bool) -> ProjectionStats {
        ProjectionStats {
            in_fov,
            filled_cells: filled,
            total_cells: cells as u64,
            collisions: in_fov - filled,
            ring_fallbacks: ring_fallback as u64,
            ..Default::default()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn straight_ahead_is_the_middle_column() {
        let s = PgmSpec::default();
        assert_eq!(s.column(&Point3::new(10.0, 0.0, 0.0)), Some(256));
        assert_eq!(s.column(&Point3::new(10.0, 10.0, 0.0)), Some(0)); // +45 deg: left edge
        assert_eq!(s.column(&Point3::new(10.0, -10.0, 0.0)), None); // -45 deg: just outside
        assert_eq!(s.column(&Point3::new(-10.0, 0.0, 0.0)), None);
        let full = PgmSpec {
            fov: Degrees(360.0),
            ..s
        };
        assert_eq!(full.column(&Point3::new(-10.0, 0.0, 0.0)), Some(0));
        assert_eq!(full.column(&Point3::new(10.0, 0.0, 0.0)), Some(256));
    }

    /// A synthetic scan of `n` rings, each a revolution starting just right of forward.
    fn synthetic(n: usize) -> Vec<Point3> {
        let mut pts = Vec::new();
        for r in 0..n {
            let elev = (2.0 - r as f32 * 0.4).to_radians();
            for k in 0..360 {
                let az = ((k as f32) + 0.5).to_radians();
                pts.push(Point3::new(
                    10.0 * az.cos(),
                    10.0 * az.sin(),
                    10.0 * elev.tan(),
                ));
            }
        }
        pts
    }

    #[test]
    fn rings_from_scan_order() {
        let pts = synthetic(64);
        let (r, found) = rings(&pts);
        let r = r.unwrap();
        assert_eq!(found, 64);
        assert_eq!(r[0], 0);
        assert_eq!(r[pts.len() - 1], 63);
        let (r, found) = rings(&pts[..pts.len() / 2]);
        assert!(r.is_none());
        assert_eq!(found, 32);
    }

    #[test]
    fn nearest_point_wins_a_cell() {
        let pts = vec![
            Point3::new(20.0, 0.0, 0.0),
            Point3::new(10.0, 0.0, 0.0),
            Point3::new(30.0, 0.0, 0.0),
        ];
        let spec = PgmSpec {
            row_mode: RowMode::Elevation,
            ..Default::default()
        };
        let p = project(&pts, &spec);
        assert_eq!(p.stats.filled_cells, 1);
        assert_eq!(p.stats.collisions, 2);
        let c = p.cell_point.iter().position(|&c| c != EMPTY).unwrap();
        assert_eq!(p.cell_point[c], 1);
        assert_eq!(p.cell_range[c], 10.0);
    }
}
