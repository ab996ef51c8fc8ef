//! The point message of a point shard: `kitti2pgm.Points`, one scan's points with their rings,
//! labels, instances and colours, unprojected, so that a trainer can augment in 3D and project
//! on the fly (the Python module's `kitti2pgm.project`).

use std::path::Path;

use super::message::PointsMsg;
use crate::error::{Error, Result};
use crate::geom::Point3;

/// What a point message is made from.
#[derive(Debug, Clone, Copy)]
pub struct PointsOf<'a> {
    /// Points, scan order.
    pub points: &'a [Point3],
    /// Reflectance of each point.
    pub intensity: &'a [f32],
    /// Row of each point (0 = the highest beam): the sensor's beam rows where a sensor was
    /// given (`params.map.sensor`), else KITTI's rings when the scan shows all 64.
    pub rings: Option<&'a [u8]>,
    /// Class id of each point.
    pub class: &'a [u8],
    /// Instance id of each point.
    pub instance: &'a [u16],
    /// Colour of each point (`None` where unseen), when colour is on.
    pub colours: Option<&'a [Option<[f32; 3]>]>,
    /// Index of each point in its `.bin` file; `None` when it is the point's position (the
    /// scan dropped no point), stored as an empty array.
    pub file_index: Option<&'a [u32]>,
}

fn le<T: Copy, const N: usize>(v: &[T], f: impl Fn(T) -> [u8; N]) -> Vec<u8> {
    v.iter().flat_map(|&x| f(x)).collect()
}

impl PointsMsg {
    /// The message of one scan.
    pub fn build(
        p: PointsOf<'_>,
        id: &str,
        drive: &str,
        frame_index: u32,
        timestamp_ns: u64,
        split: &str,
    ) -> PointsMsg {
        let mut points = Vec::with_capacity(p.points.len() * 16);
        for (q, &r) in p.points.iter().zip(p.intensity) {
            for v in [q.x, q.y, q.z, r] {
                points.extend_from_slice(&v.to_le_bytes());
            }
        }
        let (rgb, rgb_valid) = match p.colours {
            Some(c) => (
                c.iter()
                    .flat_map(|v| v.unwrap_or([0.0; 3]))
                    .flat_map(f32::to_le_bytes)
                    .collect(),
                c.iter().map(|v| v.is_some() as u8).collect(),
            ),
            None => (Vec::new(), Vec::new()),
        };
        PointsMsg {
            id: id.into(),
            drive: drive.into(),
            frame_index,
            timestamp_ns,
            count: p.points.len() as u32,
            points,
            ring: p.rings.map(<[u8]>::to_vec).unwrap_or_default(),
            label: p.class.to_vec(),
            instance: le(p.instance, u16::to_le_bytes),
            rgb,
            rgb_valid,
            file_index: p
                .file_index
                .map_or_else(Vec::new, |f| le(f, u32::to_le_bytes)),
            split: split.into(),
        }
    }

    /// Checks that every array has the size `count` announces; `path` names the shard.
    pub fn validate(&self, path: &Path) -> Result<()> {
        let n = self.count as usize;
        let optional = |len: usize| len == 0;
        let checks = [
            ("points", self.points.len(), n * 16, false),
            ("ring", self.ring.len(), n, optional(self.ring.len())),
            ("label", self.label.len(), n, false),
            ("instance", self.instance.len(), n * 2, false),
            ("rgb", self.rgb.len(), n * 12, optional(self.rgb.len())),
            (
                "rgb_valid",
                self.rgb_valid.len(),
                if self.rgb.is_empty() { 0 } else { n },
                false,
            ),
            (
                "file_index",
                self.file_index.len(),
                n * 4,
                optional(self.file_index.len()),
            ),
        ];
        for (what, got, want, absent) in checks {
            if got != want && !absent {
                return Err(Error::Length {
                    path: path.into(),
                    what: format!("points {}: {what}", self.id),
                    found: got,
                    expected: want,
                    unit: "bytes",
                });
            }
        }
        if self
            .ring
            .iter()
            .any(|&r| r as usize >= crate::project::LASERS)
        {
            return Err(Error::format(
                path,
                format!("points {}: a ring index is not below 64", self.id),
            ));
        }
        Ok(())
    }

    /// The index in the `.bin` of every point (its position when the message stores none).
    pub fn file_indices(&self) -> Vec<u32> {
        if self.file_index.is_empty() {
            return (0..self.count).collect();
        }
        self.file_index
            .chunks_exact(4)
            .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect()
    }

    /// The points as x, y, z, intensity quadruples.
    pub fn points_f32(&self) -> Vec<[f32; 4]> {
        self.points
            .chunks_exact(16)
            .map(|c| {
                let f = |k: usize| f32::from_le_bytes([c[k], c[k + 1], c[k + 2], c[k + 3]]);
                [f(0), f(4), f(8), f(12)]
            })
            .collect()
    }
}
