//! READ: point clouds of any spinning LiDAR, beside the KITTI family ([`crate::kitti`]).
//!
//! Each format has one reader module: [`pcd`] (PCD v0.7: `ascii`, `binary`,
//! `binary_compressed`), [`bin`] (flat records of a declared layout, nuScenes' `.pcd.bin` among
//! them); [`fields`] describes and decodes point records for all of them. Every reader gives a
//! [`LidarCloud`]: the finite points in file order, their intensity as stored, and the beam id
//! of every point where the data has a ring / channel / laser id field. Which beam each point
//! belongs to without such a field is the sensor model's job ([`crate::sensor`]).

pub mod bin;
pub mod fields;
pub mod pcd;

use std::path::Path;

use crate::error::{Error, Result};
use crate::geom::Point3;
use crate::kitti::velodyne::{Scan, MAX_RANGE_M};

pub use fields::{Field, FieldType, PointLayout};

/// A cloud as read: finite points in file order with their intensity and, where the data has
/// one, their beam id.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LidarCloud {
    /// Finite points within [`MAX_RANGE_M`], in file order, sensor frame, metres.
    pub points: Vec<Point3>,
    /// Intensity of each point as stored (0 where the data has none).
    pub intensity: Vec<f32>,
    /// Whether the data has an intensity field.
    pub has_intensity: bool,
    /// Beam id of each point (the ring / channel / laser id field), where the data has one.
    pub ring: Option<Vec<u16>>,
    /// Points in the file, kept or not.
    pub file_len: usize,
    /// File indices of the dropped points (a non-finite coordinate or intensity: a non-dense
    /// cloud's NaN points; or beyond [`MAX_RANGE_M`]), ascending.
    pub dropped: Vec<u32>,
    /// How many of `dropped` were finite but beyond [`MAX_RANGE_M`].
    pub dropped_out_of_range: usize,
}

impl LidarCloud {
    pub(crate) fn with_capacity(n: usize, intensity: bool, ring: bool) -> LidarCloud {
        LidarCloud {
            points: Vec::with_capacity(n),
            intensity: Vec::with_capacity(n),
            has_intensity: intensity,
            ring: ring.then(|| Vec::with_capacity(n)),
            ..Default::default()
        }
    }

    /// Adds point `index` of the file: kept when finite and within range, else dropped and
    /// counted. A beam id that is not a whole number in 0-65535 is an error naming `path`.
    pub(crate) fn push(
        &mut self,
        index: usize,
        p: Point3,
        intensity: f32,
        ring: Option<f64>,
        path: &Path,
    ) -> Result<()> {
        let finite = p.x.is_finite() && p.y.is_finite() && p.z.is_finite() && intensity.is_finite();
        let far = finite && p.coords.cast::<f64>().norm() > MAX_RANGE_M as f64;
        if !finite || far {
            self.dropped.push(index as u32);
            self.dropped_out_of_range += far as usize;
            return Ok(());
        }
        if let (Some(rings), Some(r)) = (self.ring.as_mut(), ring) {
            if !(r >= 0.0 && r <= u16::MAX as f64 && r.fract() == 0.0) {
                return Err(Error::format(
                    path,
                    format!("point {index} has beam id (ring) {r}, not a whole number in 0-65535"),
                ));
            }
            rings.push(r as u16);
        }
        self.points.push(p);
        self.intensity.push(intensity);
        Ok(())
    }

    /// Number of kept points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Whether no point was kept.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// The cloud as the conversion's [`Scan`] (intensity as stored in `reflectance`) and its
    /// beam ids.
    pub fn into_scan(self) -> (Scan, Option<Vec<u16>>) {
        (
            Scan {
                points: self.points,
                reflectance: self.intensity,
                file_len: self.file_len,
                dropped: self.dropped,
                dropped_out_of_range: self.dropped_out_of_range,
            },
            self.ring,
        )
    }
}

/// Reads a point cloud file by its name: `.pcd` (PCD), `.pcd.bin` (nuScenes: x, y, z,
/// intensity, ring as float32), or `.bin` with `layout` (KITTI's x, y, z, reflectance float32
/// when none is given).
pub fn read_cloud(path: &Path, layout: Option<&PointLayout>) -> Result<LidarCloud> {
    let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("");
    if name.ends_with(".pcd") {
        return pcd::read(path);
    }
    if name.ends_with(".pcd.bin") && layout.is_none() {
        return bin::read(path, &bin::nuscenes_layout());
    }
    if name.ends_with(".bin") {
        return bin::read(path, layout.unwrap_or(&bin::kitti_layout()));
    }
    Err(Error::format(
        path,
        "not a point cloud kitti2pgm reads: expected .pcd, .pcd.bin (nuScenes) or .bin",
    ))
}
