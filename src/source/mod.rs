//! READ: every input the tool reads: KITTI's family and the point clouds of any spinning LiDAR.
//!
//! Each format has one reader module: [`pcd`] (PCD v0.7: `ascii`, `binary`,
//! `binary_compressed`; it writes `binary` too), [`bin`] (flat records of a declared layout,
//! nuScenes' `.pcd.bin` among them), [`bag`] (ROS 2 bags in MCAP, streamed) with
//! [`pointcloud2`] (their `sensor_msgs/msg/PointCloud2` messages), [`nuscenes`] (nuScenes'
//! tables: its scenes, LIDAR_TOP keyframes and lidarseg labels); [`fields`] describes and
//! decodes point records for all of them; [`kitti`] reads the KITTI family (raw drives,
//! odometry sequences, the object set). Every reader gives the neutral [`Scan`] ([`scan`]):
//! the kept points in file order, their intensity as stored, and the beam id of every point
//! where the data has a ring / channel / laser id field. Which beam each point
//! belongs to without such a field is the sensor model's job ([`crate::sensor`]).

pub mod annotations;
pub mod bag;
pub mod bin;
pub mod boxes;
mod cdr;
pub mod dataset;
mod decode;
pub mod fields;
pub mod kitti;
pub mod nuscenes;
pub mod pcd;
pub mod pointcloud2;
mod recording;
pub mod scan;
pub mod tf;
pub mod unpacked;

use std::path::Path;

use crate::error::{Error, Result};

pub use dataset::DatasetKind;
pub use fields::{Field, FieldType, PointLayout};
pub use recording::Recording;
pub use scan::{DropRule, Scan};

/// What a scan file is, by its name, and with a declared record layout (`--fields`) where one
/// is given: the one place that decides which reader reads it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ScanFile<'a> {
    /// A `.pcd` ([`pcd`]).
    Pcd,
    /// nuScenes' `.pcd.bin` ([`nuscenes::point_layout`]).
    NuScenesBin,
    /// KITTI's `.bin` ([`kitti::velodyne`], its drop rule).
    KittiBin,
    /// A `.bin` of a declared layout ([`bin`]).
    Declared(&'a PointLayout),
}

impl<'a> ScanFile<'a> {
    /// What `path` is, with `layout` declared for flat `.bin` files (nuScenes' too); `None`
    /// when it is no scan file kitti2pgm reads.
    pub fn of(path: &Path, layout: Option<&'a PointLayout>) -> Option<ScanFile<'a>> {
        let name = path.file_name()?.to_str()?;
        Some(match layout {
            _ if name.ends_with(".pcd") => ScanFile::Pcd,
            Some(l) if name.ends_with(".bin") => ScanFile::Declared(l),
            None if name.ends_with(".pcd.bin") => ScanFile::NuScenesBin,
            None if name.ends_with(".bin") => ScanFile::KittiBin,
            _ => return None,
        })
    }
}

/// Whether `path` names a KITTI `.bin` scan (a `.bin` that is not nuScenes' `.pcd.bin`).
pub fn is_kitti_bin(path: &Path) -> bool {
    ScanFile::of(path, None) == Some(ScanFile::KittiBin)
}

/// How many points a scan file holds, from its size or header alone (the per-point `.label`
/// files hold one label each): KITTI `.bin` size / 16, nuScenes `.pcd.bin` size / 20, a PCD's
/// `POINTS`. `None` when the file cannot be read or is not a scan.
pub fn points_in_file(path: &Path) -> Option<u64> {
    points_in_file_as(path, None)
}

/// [`points_in_file`], a `.bin` being records of `layout` where one is declared (`--fields`);
/// `None` too when its size is not whole records.
pub fn points_in_file_as(path: &Path, layout: Option<&PointLayout>) -> Option<u64> {
    let kind = ScanFile::of(path, layout)?;
    // Through `fs::open`: a regular file only, never a FIFO that would block the read.
    let (file, meta) = crate::fs::open(path).ok()?;
    let step = match kind {
        ScanFile::Pcd => {
            use std::io::Read;
            let mut head = Vec::with_capacity(4096);
            file.take(64 << 10).read_to_end(&mut head).ok()?;
            return pcd::header(&head, path).ok().map(|h| h.points as u64);
        }
        ScanFile::Declared(l) => {
            let step = l.step as u64;
            return (meta.len() % step == 0).then(|| meta.len() / step);
        }
        ScanFile::NuScenesBin => nuscenes::point_layout().step,
        ScanFile::KittiBin => kitti::velodyne::POINT_BYTES,
    };
    Some(meta.len() / step as u64)
}

/// Reads a scan file by its name: `.pcd` (PCD), `.pcd.bin` (nuScenes: x, y, z, intensity, ring
/// as float32), or `.bin`: records of `layout` where one is declared (`--fields`), else KITTI's
/// x, y, z, reflectance float32 with KITTI's drop rule ([`kitti::velodyne`]). The one function
/// that turns a file into a [`Scan`]; reading it as its conversion did (a sensor's pose, beam
/// rows) is [`crate::sensor::read_scan`].
pub fn read_file(path: &Path, layout: Option<&PointLayout>) -> Result<Scan> {
    match ScanFile::of(path, layout) {
        Some(ScanFile::Pcd) => pcd::read(path),
        Some(ScanFile::Declared(l)) => bin::read(path, l),
        Some(ScanFile::NuScenesBin) => bin::read(path, &nuscenes::point_layout()),
        Some(ScanFile::KittiBin) => kitti::velodyne::read(path),
        None => Err(Error::format(
            path,
            "not a point cloud kitti2pgm reads: expected .pcd, .pcd.bin (nuScenes) or .bin",
        )),
    }
}
