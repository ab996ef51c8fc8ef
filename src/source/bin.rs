//! Flat binary point files: records of a declared [`PointLayout`] laid end to end, no header.
//! KITTI's `.bin` ([`super::kitti::velodyne::layout`]) and nuScenes' LIDAR_TOP `.pcd.bin`
//! ([`super::nuscenes::point_layout`]) are two; `--fields` declares any other.

use std::path::Path;

use super::scan::{DropRule, Scan};
use super::PointLayout;
use crate::error::{Error, Result};
use crate::fs::{self, Limit};

/// Reads a flat file of `layout` records.
pub fn read(path: &Path, layout: &PointLayout) -> Result<Scan> {
    let bytes = fs::read(path, Limit::Data)?;
    decode(&bytes, layout, path)
}

/// Decodes the bytes of a flat file of `layout` records; `path` names it in errors.
pub fn decode(bytes: &[u8], layout: &PointLayout, path: &Path) -> Result<Scan> {
    decode_with(bytes, layout, path, &DropRule::ANY)
}

/// [`decode`] with the drop rule of the source (KITTI's reflectance range).
pub fn decode_with(
    bytes: &[u8],
    layout: &PointLayout,
    path: &Path,
    rule: &DropRule,
) -> Result<Scan> {
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
    layout.decode_with(bytes, bytes.len() / layout.step, path, rule)
}
