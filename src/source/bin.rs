//! Flat binary point files: records of a declared [`PointLayout`] laid end to end, no header.
//! KITTI's `.bin` is x, y, z, reflectance as float32; nuScenes' LIDAR_TOP `.pcd.bin` is x, y, z,
//! intensity, ring index as float32; `--fields` declares any other.

use std::path::Path;

use super::{FieldType, LidarCloud, PointLayout};
use crate::error::{Error, Result};
use crate::fs::{self, Limit};

/// KITTI's layout: `x,y,z,intensity:f32`.
pub fn kitti_layout() -> PointLayout {
    PointLayout::packed(&[
        ("x", FieldType::F32),
        ("y", FieldType::F32),
        ("z", FieldType::F32),
        ("intensity", FieldType::F32),
    ])
}

/// nuScenes' LIDAR_TOP layout: `x,y,z,intensity,ring:f32`.
pub fn nuscenes_layout() -> PointLayout {
    PointLayout::packed(&[
        ("x", FieldType::F32),
        ("y", FieldType::F32),
        ("z", FieldType::F32),
        ("intensity", FieldType::F32),
        ("ring", FieldType::F32),
    ])
}

/// Reads a flat file of `layout` records.
pub fn read(path: &Path, layout: &PointLayout) -> Result<LidarCloud> {
    let bytes = fs::read(path, Limit::Data)?;
    decode(&bytes, layout, path)
}

/// Decodes the bytes of a flat file of `layout` records; `path` names it in errors.
pub fn decode(bytes: &[u8], layout: &PointLayout, path: &Path) -> Result<LidarCloud> {
    if bytes.is_empty() {
        return Err(Error::format(path, "empty point file (0 bytes)"));
    }
    if !bytes.len().is_multiple_of(layout.step) {
        return Err(Error::Truncated {
            path: path.into(),
            bytes: bytes.len(),
            record: layout.step,
            what: "point",
        });
    }
    layout.decode(bytes, bytes.len() / layout.step, path)
}
