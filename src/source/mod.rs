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

pub mod bag;
pub mod bin;
mod cdr;
mod decode;
pub mod fields;
pub mod kitti;
pub mod nuscenes;
pub mod pcd;
pub mod pointcloud2;
pub mod scan;
pub mod tf;
pub mod unpacked;

use std::path::Path;

use crate::error::{Error, Result};

pub use fields::{Field, FieldType, PointLayout};
pub use scan::{DropRule, Scan};

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
        nuscenes::point_layout().step
    } else if name.ends_with(".bin") {
        kitti::velodyne::POINT_BYTES
    } else {
        return None;
    };
    Some(meta.len() / step as u64)
}

/// Reads a scan file by its name: `.pcd` (PCD), `.pcd.bin` (nuScenes: x, y, z, intensity, ring
/// as float32), or `.bin`: records of `layout` where one is declared (`--fields`), else KITTI's
/// x, y, z, reflectance float32 with KITTI's drop rule ([`kitti::velodyne`]). The one function
/// that turns a file into a [`Scan`]; reading it as its conversion did (a sensor's pose, beam
/// rows) is [`crate::sensor::read_scan`].
pub fn read_file(path: &Path, layout: Option<&PointLayout>) -> Result<Scan> {
    let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("");
    if name.ends_with(".pcd") {
        return pcd::read(path);
    }
    match layout {
        Some(l) if name.ends_with(".bin") => bin::read(path, l),
        None if name.ends_with(".pcd.bin") => bin::read(path, &nuscenes::point_layout()),
        None if name.ends_with(".bin") => kitti::velodyne::read(path),
        _ => Err(Error::format(
            path,
            "not a point cloud kitti2pgm reads: expected .pcd, .pcd.bin (nuScenes) or .bin",
        )),
    }
}
