//! READ: point clouds of any spinning LiDAR, beside the KITTI family ([`crate::kitti`]).
//!
//! Each format has one reader module: [`pcd`] (PCD v0.7: `ascii`, `binary`,
//! `binary_compressed`; it writes `binary` too), [`bin`] (flat records of a declared layout,
//! nuScenes' `.pcd.bin` among them), [`bag`] (ROS 2 bags in MCAP, streamed) with
//! [`pointcloud2`] (their `sensor_msgs/msg/PointCloud2` messages), [`nuscenes`] (nuScenes'
//! tables: its scenes, LIDAR_TOP keyframes and lidarseg labels); [`fields`] describes and
//! decodes point records for all of them. Every reader gives a
//! [`LidarCloud`]: the finite points in file order, their intensity as stored, and the beam id
//! of every point where the data has a ring / channel / laser id field. Which beam each point
//! belongs to without such a field is the sensor model's job ([`crate::sensor`]).

pub mod bag;
pub mod bin;
mod cdr;
mod decode;
pub mod fields;
pub mod nuscenes;
pub mod pcd;
pub mod pointcloud2;
pub mod tf;
pub mod unpacked;

use std::path::Path;

use crate::error::{Error, Result};
use crate::geom::Point3;

pub use fields::{Field, FieldType, PointLayout};

/// What to do with `path` when it is a recording that `convert` does not read as it is (a ROS 2
/// bag, another kind of bag, a nuScenes root): the command that makes a sequence folder of it,
/// or `None` when it is none of these.
pub fn needs_unpack(path: &Path) -> Option<String> {
    let shown = path.display();
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("");
    let bag = (path.is_file() && ext == "mcap") || path.join("metadata.yaml").is_file();
    if bag {
        // Its point cloud topics, when they can be read: the one there is goes in the command.
        let clouds: Vec<String> = bag::Bag::open(path)
            .and_then(|b| b.topics())
            .unwrap_or_default()
            .into_iter()
            .filter(|t| t.type_name == pointcloud2::TYPE_NAME)
            .map(|t| t.name)
            .collect();
        let (topic, listed) = match clouds.as_slice() {
            [one] => (one.clone(), String::new()),
            [] => (
                "TOPIC".into(),
                format!("; `kitti2pgm unpack {shown} --list` lists its topics"),
            ),
            many => (
                "TOPIC".into(),
                format!("; its point cloud topics: {}", many.join(", ")),
            ),
        };
        return Some(format!(
            "a ROS 2 bag: make it a sequence folder first, `kitti2pgm unpack {shown} --topic \
             {topic} --out ROOT`, then convert ROOT{listed}"
        ));
    }
    if path.is_file() && (ext == "bag" || ext == "db3") {
        return Some(format!(
            "a {} bag: convert it to an MCAP bag first (`rosbags-convert --src {shown} --dst \
             BAG --dst-storage mcap`, docs/sources.md), then `kitti2pgm unpack BAG --topic \
             TOPIC --out ROOT`",
            if ext == "bag" {
                "ROS 1"
            } else {
                "rosbag2 sqlite3"
            }
        ));
    }
    if nuscenes::is_root(path) {
        return Some(format!(
            "a nuScenes root: make its scenes sequence folders first, `kitti2pgm unpack {shown} \
             --out ROOT`, then convert ROOT with --sensor hdl32e --class-map nuscenes"
        ));
    }
    None
}

/// A cloud as read: finite points in file order with their intensity and, where the data has
/// one, their beam id.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LidarCloud {
    /// Finite points within [`MAX_RANGE_M`](crate::geom::MAX_RANGE_M), in file order, sensor frame, metres.
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
    /// cloud's NaN points; or beyond [`MAX_RANGE_M`](crate::geom::MAX_RANGE_M)), ascending.
    pub dropped: Vec<u32>,
    /// How many of `dropped` were finite but beyond [`MAX_RANGE_M`](crate::geom::MAX_RANGE_M).
    pub dropped_out_of_range: usize,
    /// Bytes after the declared points, left unread (a `binary` PCD some exporters pad).
    pub trailing_bytes: usize,
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

    /// Number of kept points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Whether no point was kept.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }
}

/// Whether `path` names a KITTI `.bin` scan (a `.bin` that is not nuScenes' `.pcd.bin`).
pub fn is_kitti_bin(path: &Path) -> bool {
    let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("");
    name.ends_with(".bin") && !name.ends_with(".pcd.bin")
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
    let name = path.file_name()?.to_str()?;
    // Through `fs::open`: a regular file only, never a FIFO that would block the read.
    let (file, meta) = crate::fs::open(path).ok()?;
    if name.ends_with(".pcd") {
        use std::io::Read;
        let mut head = Vec::with_capacity(4096);
        file.take(64 << 10).read_to_end(&mut head).ok()?;
        return pcd::header(&head, path).ok().map(|h| h.points as u64);
    }
    if let Some(l) = layout.filter(|_| name.ends_with(".bin")) {
        let step = l.step as u64;
        return (meta.len() % step == 0).then(|| meta.len() / step);
    }
    let step = if name.ends_with(".pcd.bin") {
        bin::nuscenes_layout().step
    } else if name.ends_with(".bin") {
        bin::kitti_layout().step
    } else {
        return None;
    };
    Some(meta.len() / step as u64)
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
