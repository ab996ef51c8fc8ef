//! PROJECT: a point cloud held in memory (the Python module's input) to a map, optionally
//! augmented first.
//!
//! [`project_cloud`] is the conversion's own projection ([`super::project`] and
//! [`super::frame::assemble`]) on arrays instead of a scan file: for the points of a scan as
//! read (finite, in range, in file order), their labels and colours, it gives the map `convert`
//! writes, byte for byte. Rows come from the given ring indices, else from the scan order; with
//! an [`Augment`] the rings are taken from the original order first, so that augmenting never
//! moves a point to another row.

use super::augment::Augment;
use super::frame::{assemble_on, CellColours, PgmFrame, PointValues};
use super::{
    project_impl, rings, Geometry, PgmSpec, PointCells, ProjectionStats, RowMode, Rows, EMPTY,
    LASERS,
};
use crate::error::{Error, Result};
use crate::geom::Point3;
use crate::label::ClassId;
use crate::simd::first_where;
use crate::source::kitti::velodyne::{MAX_RANGE_M, REFLECTANCE_RANGE};

/// A cloud to project: one entry per point in every array, in scan order.
#[derive(Debug, Clone, Copy)]
pub struct Cloud<'a> {
    /// Coordinates, velodyne frame, metres.
    pub points: &'a [Point3],
    /// Reflectance (0-1).
    pub intensity: &'a [f32],
    /// Beam row of each point (0 = the highest beam), below `beams`; `None`: from the scan
    /// order.
    pub rings: Option<&'a [u8]>,
    /// The beams `rings` counts ([`LASERS`] for KITTI's HDL-64E; a sensor model's beams).
    pub beams: usize,
    /// Column of each point, given (the sensor's own: Ouster's destaggered measurement ids),
    /// below the map's columns; `None`: by azimuth. Rotations and flips move points off such
    /// columns and are refused with them.
    pub columns: Option<&'a [u16]>,
    /// What the intensities are, and so which values are valid.
    pub intensity_kind: IntensityKind,
    /// Class id of each point; `None`: 0 everywhere.
    pub labels: Option<&'a [ClassId]>,
    /// Instance id of each point; `None`: 0 everywhere.
    pub instance: Option<&'a [u16]>,
    /// Colour of each point (0-1) when the map has colour channels.
    pub colours: Option<&'a [[f32; 3]]>,
    /// Whether each point has a colour; `None`: all have.
    pub colour_valid: Option<&'a [bool]>,
}

/// What a cloud's intensities are.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum IntensityKind {
    /// KITTI's reflectance: 0 to 1, as the converter checks every scan.
    #[default]
    Reflectance,
    /// Another sensor's intensity as its reader stored it (0-255 for most): any finite value.
    AsStored,
}

/// A projected cloud: its map (a [`PgmFrame`], the one type of a map in memory) and where
/// each point went.
#[derive(Debug, Clone)]
pub struct CloudProjection {
    /// The map (channels in the `.npy` order; colour channels when the cloud had colours).
    pub frame: PgmFrame,
    /// The cell (`row * cols + col`) of every input point; [`EMPTY`] outside the field of view
    /// or dropped by the augmentation.
    pub point_cell: Vec<u32>,
    /// Index of the input point kept in each cell; [`EMPTY`] for empty cells.
    pub cell_point: Vec<u32>,
    /// What the projection found.
    pub stats: ProjectionStats,
    /// Rings seen in the scan order (64 when the rings were given).
    pub rings_found: usize,
}

impl Cloud<'_> {
    /// A cloud of points alone.
    pub fn of_points<'a>(points: &'a [Point3], intensity: &'a [f32]) -> Cloud<'a> {
        Cloud {
            points,
            intensity,
            rings: None,
            beams: LASERS,
            columns: None,
            intensity_kind: IntensityKind::Reflectance,
            labels: None,
            instance: None,
            colours: None,
            colour_valid: None,
        }
    }

    /// Checks lengths, finiteness and ring indices; the error says which array and which point.
    pub fn validate(&self) -> Result<()> {
        let n = self.points.len();
        let len = |name: &str, m: Option<usize>| match m {
            Some(m) if m != n => Err(Error::Config(format!(
                "{name} has {m} entries for {n} points"
            ))),
            _ => Ok(()),
        };
        len("intensity", Some(self.intensity.len()))?;
        len("rings", self.rings.map(<[u8]>::len))?;
        len("columns", self.columns.map(<[u16]>::len))?;
        len("labels", self.labels.map(<[ClassId]>::len))?;
        len("instance", self.instance.map(<[u16]>::len))?;
        len("colours", self.colours.map(<[[f32; 3]]>::len))?;
        len("colour_valid", self.colour_valid.map(<[bool]>::len))?;
        if self.colour_valid.is_some() && self.colours.is_none() {
            return Err(Error::Config("colour_valid without colours".into()));
        }
        // The converter's rules (`kitti::velodyne`): finite, within MAX_RANGE_M, reflectance
        // in 0..1 ([`first_where`]: a branch-free pass, the culprit searched for on failure).
        let max2 = MAX_RANGE_M * MAX_RANGE_M;
        let ok_point = |p: &Point3| {
            p.x.is_finite() & p.y.is_finite() & p.z.is_finite() & (p.coords.norm_squared() <= max2)
        };
        let range = match self.intensity_kind {
            IntensityKind::Reflectance => REFLECTANCE_RANGE,
            IntensityKind::AsStored => f32::MIN..=f32::MAX,
        };
        let ok_intensity = |v: f32| (v >= *range.start()) & (v <= *range.end());
        if let Some(i) = first_where(self.points, |p| !ok_point(p)) {
            return Err(Error::Config(format!(
                "point {i} is not finite or beyond {MAX_RANGE_M} m ({:?})",
                self.points[i].coords.as_slice()
            )));
        }
        if let Some(i) = first_where(self.intensity, |v| !ok_intensity(*v)) {
            return Err(Error::Config(format!(
                "intensity of point {i} is {:?}, outside {:?} (KITTI reflectance; another \
                 sensor's intensity is taken as stored when its beams are given)",
                self.intensity[i], range
            )));
        }
        self.validate_rings_and_colours()
    }

    fn validate_rings_and_colours(&self) -> Result<()> {
        if let Some(c) = self.colours {
            if let Some(i) = c.iter().position(|v| !v.iter().all(|x| x.is_finite())) {
                return Err(Error::Config(format!(
                    "colour of point {i} is not finite ({:?})",
                    c[i]
                )));
            }
        }
        if self.beams == 0 || self.beams > crate::sensor::MAX_BEAMS {
            return Err(Error::Config(format!(
                "{} beams: a sensor has 1 to {}",
                self.beams,
                crate::sensor::MAX_BEAMS
            )));
        }
        if let Some(r) = self.rings {
            if let Some(i) = r.iter().position(|&v| v as usize >= self.beams) {
                return Err(Error::Config(format!(
                    "ring {} of point {i} is not below {}",
                    r[i], self.beams
                )));
            }
        }
        Ok(())
    }
}

/// Projects a cloud, augmented first when `augment` is given (and not the identity).
pub fn project_cloud(
    cloud: &Cloud<'_>,
    spec: &PgmSpec,
    augment: Option<&Augment>,
) -> Result<CloudProjection> {
    project_cloud_on(cloud, spec, augment, 1)
}

/// [`project_cloud`] on up to `threads` threads (rayon's pool): the points' claims on their
/// cells in parts of at least 16,384 points, the map in bands of at least 16,384 cells; the
/// same projection, byte for byte, whatever `threads` (0 counts as 1).
pub fn project_cloud_on(
    cloud: &Cloud<'_>,
    spec: &PgmSpec,
    augment: Option<&Augment>,
    threads: usize,
) -> Result<CloudProjection> {
    let threads = threads.max(1);
    spec.validate()?;
    cloud.validate()?;
    check_columns(cloud, spec, augment)?;
    let n = cloud.points.len();
    let zeros_class;
    let zeros_instance;
    let class = match cloud.labels {
        Some(l) => l,
        None => {
            zeros_class = vec![0 as ClassId; n];
            &zeros_class[..]
        }
    };
    let instance = match cloud.instance {
        Some(l) => l,
        None => {
            zeros_instance = vec![0u16; n];
            &zeros_instance[..]
        }
    };
    let colour_of = |i: usize| -> Option<[f32; 3]> {
        let c = cloud.colours?;
        match cloud.colour_valid {
            Some(v) if !v[i] => None,
            _ => Some(c[i]),
        }
    };
    let aug = match augment {
        Some(a) => {
            a.validate()?;
            (*a != Augment {
                seed: a.seed,
                ..Augment::default()
            })
            .then_some(a)
        }
        None => None,
    };
    match aug {
        None => Ok(plain(cloud, spec, (class, instance), &colour_of, threads)),
        Some(aug) => augmented(
            cloud,
            spec,
            aug,
            (class, instance),
            &colour_of,
            (Cull::Early, threads),
        ),
    }
}

/// The projection of [`project_cloud_on`] without augmentation.
fn plain(
    cloud: &Cloud<'_>,
    spec: &PgmSpec,
    (class, instance): (&[ClassId], &[u16]),
    colour_of: &dyn Fn(usize) -> Option<[f32; 3]>,
    threads: usize,
) -> CloudProjection {
    let rows = cloud
        .rings
        .map_or(Rows::FromSpec, |r| Rows::Beams(r, cloud.beams));
    let geometry = Geometry {
        columns: cloud.columns,
        ..Geometry::plain(cloud.points)
    };
    let (points, keep) = (cloud.points, PointCells::Keep);
    let proj = project_impl(points, spec, keep, rows, geometry, threads);
    let values = PointValues {
        points,
        intensity: cloud.intensity,
        class,
        instance,
    };
    let colour = cloud.colours.map(|_| CellColours::of(&proj, colour_of));
    let frame = assemble_on(values, &proj, colour.as_ref(), threads);
    CloudProjection {
        frame,
        point_cell: proj.point_cell,
        cell_point: proj.cell_point,
        stats: proj.stats,
        rings_found: proj.rings_found,
    }
}

/// Given columns: each below the map's columns, and no augmentation that turns or mirrors the
/// cloud (its points would leave their columns).
fn check_columns(cloud: &Cloud<'_>, spec: &PgmSpec, augment: Option<&Augment>) -> Result<()> {
    let Some(c) = cloud.columns else {
        return Ok(());
    };
    if let Some(i) = c.iter().position(|&c| c as usize >= spec.cols) {
        return Err(Error::Config(format!(
            "column {} of point {i} is not below the map's {} columns",
            c[i], spec.cols
        )));
    }
    if augment.is_some_and(|a| a.rotate != 0.0 || a.flip) {
        return Err(Error::Config(
            "a rotation or flip moves points off the sensor's own columns: turn the map \
             instead (a shift along its columns)"
                .into(),
        ));
    }
    Ok(())
}

/// Whether the points that cannot reach a view narrower than 180 degrees are left out early
/// (the same map, a quarter of the work at 90 degrees: tested against [`Cull::Never`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Cull {
    Early,
    #[cfg_attr(not(test), allow(dead_code))]
    Never,
}

/// The augmented projection of [`project_cloud`], each point with its class and instance.
fn augmented(
    cloud: &Cloud<'_>,
    spec: &PgmSpec,
    aug: &Augment,
    (class, instance): (&[ClassId], &[u16]),
    colour_of: &dyn Fn(usize) -> Option<[f32; 3]>,
    (cull, threads): (Cull, usize),
) -> Result<CloudProjection> {
    let n = cloud.points.len();
    // Rings from the original order, before any point moves or goes.
    let (recovered, rings_found) = match (cloud.rings, spec.row_mode) {
        (_, RowMode::Elevation) => (None, 0),
        (Some(_), RowMode::Rings) => (None, cloud.beams),
        (None, RowMode::Rings) => rings(cloud.points),
    };
    // For a view narrower than 180 degrees, points that cannot reach its wedge (the one the
    // projection rejects by) are left out early: the same map, a quarter of the work at 90.
    let view = spec
        .front_wedge()
        .filter(|_| cull == Cull::Early && cloud.columns.is_none());
    let a = aug.apply_in_view(cloud.points, view);
    let all_rings = cloud.rings.or(recovered.as_deref());
    let kept_rings = all_rings.map(|r| pick(&a.kept, r));
    let beams = if cloud.rings.is_some() {
        cloud.beams
    } else {
        LASERS
    };
    let rows = match &kept_rings {
        Some(r) => Rows::Beams(r, beams),
        None if spec.row_mode == RowMode::Rings => Rows::Fallback,
        None => Rows::FromSpec,
    };
    let (rotate, scale) = (a.rotate, a.scale);
    let kept_columns = cloud.columns.map(|c| pick(&a.kept, c));
    let geometry = Geometry {
        columns: kept_columns.as_deref(),
        ..Geometry::moved(&a.base, rotate, scale)
    };
    let proj = project_impl(&a.points, spec, PointCells::Keep, rows, geometry, threads);
    let (k_int, k_class, k_inst) = (
        pick(&a.kept, cloud.intensity),
        pick(&a.kept, class),
        pick(&a.kept, instance),
    );
    let values = PointValues {
        points: &a.points,
        intensity: &k_int,
        class: &k_class,
        instance: &k_inst,
    };
    let kept_colour = |k: usize| colour_of(a.kept[k] as usize);
    let colour = cloud.colours.map(|_| CellColours::of(&proj, kept_colour));
    let frame = assemble_on(values, &proj, colour.as_ref(), threads);
    // Back to the input's indices.
    let mut point_cell = vec![EMPTY; n];
    for (k, &i) in a.kept.iter().enumerate() {
        point_cell[i as usize] = proj.point_cell[k];
    }
    let cell_point = proj
        .cell_point
        .iter()
        .map(|&k| {
            if k == EMPTY {
                EMPTY
            } else {
                a.kept[k as usize]
            }
        })
        .collect();
    Ok(CloudProjection {
        frame,
        point_cell,
        cell_point,
        stats: proj.stats,
        rings_found,
    })
}

/// The entries of `v` at `kept`.
fn pick<T: Copy>(kept: &[u32], v: &[T]) -> Vec<T> {
    kept.iter().map(|&i| v[i as usize]).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::source::Scan;

    #[test]
    fn culling_leaves_the_map_unchanged() {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(
            "fixtures/raw/2011_09_26/2011_09_26_drive_0001_sync/velodyne_points/data/0000000000.bin",
        );
        let scan = Scan::read(&path).unwrap();
        let cloud = Cloud::of_points(&scan.points, &scan.intensity);
        let n = scan.len();
        let (class, instance) = (vec![1u8; n], vec![0u16; n]);
        let none = |_: usize| None;
        for (deg, rotate) in [(90.0, 2.0), (90.0, -0.3), (170.0, 3.0), (30.0, 1.0)] {
            let spec = PgmSpec {
                fov: crate::geom::Degrees(deg),
                ..Default::default()
            };
            let aug = Augment {
                rotate,
                scale: 0.97,
                flip: true,
                jitter: 0.05,
                drop: 0.2,
                seed: 11,
            };
            let run = |cull| {
                augmented(&cloud, &spec, &aug, (&class, &instance), &none, (cull, 1)).unwrap()
            };
            let (a, b) = (run(Cull::Early), run(Cull::Never));
            assert_eq!(a.frame, b.frame, "{deg} deg, rotate {rotate}");
            assert_eq!(a.point_cell, b.point_cell);
            assert_eq!(a.stats, b.stats);
            assert!(a.stats.in_fov > 1000);
        }
    }
}
