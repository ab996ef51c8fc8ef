//! A ROS 2 bag's static transforms (`/tf_static`, `tf2_msgs/msg/TFMessage`): where each frame
//! sits in its parent, and so where a sensor sits in the frame its clouds are written in
//! ([`sensor_pose_in`]).

use std::path::Path;

use serde::{Deserialize, Serialize};

use super::cdr::Cdr;
use crate::error::{Error, Result};
use crate::geom::na;

/// The message type of `/tf_static`.
pub const TYPE_NAME: &str = "tf2_msgs/msg/TFMessage";

/// One transform: the `child` frame's pose in its `parent` (ROS's `TransformStamped`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StaticTransform {
    /// The parent frame (`header.frame_id`).
    pub parent: String,
    /// The child frame.
    pub child: String,
    /// The child's origin in the parent, metres.
    pub translation: [f64; 3],
    /// The child's orientation in the parent, quaternion x, y, z, w.
    pub rotation: [f64; 4],
}

impl StaticTransform {
    /// Child frame -> parent frame.
    pub fn isometry(&self) -> na::Isometry3<f64> {
        let [x, y, z, w] = self.rotation;
        na::Isometry3::from_parts(
            na::Translation3::new(
                self.translation[0],
                self.translation[1],
                self.translation[2],
            ),
            na::UnitQuaternion::from_quaternion(na::Quaternion::new(w, x, y, z)),
        )
    }
}

/// Decodes one `TFMessage` (CDR); `what` names it in errors (the bag and the message).
pub fn decode(message: &[u8], what: &Path) -> Result<Vec<StaticTransform>> {
    let bad = |m: String| Error::format(what, format!("tf2_msgs/msg/TFMessage: {m}"));
    let mut c = Cdr::new(message).map_err(bad)?;
    let n = c.u32("transforms").map_err(bad)? as usize;
    let mut out = Vec::with_capacity(n.min(1024));
    for _ in 0..n {
        let t = (|| {
            c.i32("header.stamp.sec")?;
            c.u32("header.stamp.nanosec")?;
            let parent = c.string("header.frame_id")?;
            let child = c.string("child_frame_id")?;
            let mut v = [0.0; 7];
            for (k, x) in v.iter_mut().enumerate() {
                *x = c.f64(["x", "y", "z", "qx", "qy", "qz", "qw"][k])?;
            }
            Ok::<_, String>(StaticTransform {
                parent,
                child,
                translation: [v[0], v[1], v[2]],
                rotation: [v[3], v[4], v[5], v[6]],
            })
        })()
        .map_err(bad)?;
        let norm = t.rotation.iter().map(|q| q * q).sum::<f64>().sqrt();
        if !(t
            .translation
            .iter()
            .chain(&t.rotation)
            .all(|v| v.is_finite())
            && (norm - 1.0).abs() < 1e-3)
        {
            return Err(bad(format!(
                "the transform {} -> {} is not a rigid motion (rotation norm {norm})",
                t.parent, t.child
            )));
        }
        out.push(t);
    }
    Ok(out)
}

/// The static transforms of `bag` (its `/tf_static` topic; none without one): a later
/// transform of the same parent and child replaces an earlier one. The messages are read until
/// the topic's count (usually a few, at the bag's start; the rest of the bag is not read then).
pub fn read_static(bag: &super::bag::Bag) -> Result<Vec<StaticTransform>> {
    let Some(topic) = bag
        .topics()?
        .into_iter()
        .find(|t| t.name == "/tf_static" && t.type_name == TYPE_NAME)
    else {
        return Ok(Vec::new());
    };
    let mut out: Vec<StaticTransform> = Vec::new();
    for m in bag.messages(&topic).take(topic.messages as usize) {
        // A transform lost with a damaged chunk could be the one asked for: no pose then.
        let m = match m? {
            super::bag::Next::Message(m) => m,
            super::bag::Next::Lost(lost) => return Err(lost.damage.error),
        };
        let what = m.file.join(format!("/tf_static message {}", m.index));
        for t in decode(&m.data, &what)? {
            out.retain(|o| (&o.parent, &o.child) != (&t.parent, &t.child));
            out.push(t);
        }
    }
    Ok(out)
}

/// The pose of frame `sensor` in frame `points` (sensor -> points), through the static
/// transforms (a path of parent / child steps either way). `None` when no chain joins them.
pub fn sensor_pose_in(
    transforms: &[StaticTransform],
    sensor: &str,
    points: &str,
) -> Option<na::Isometry3<f64>> {
    // Breadth-first from `sensor`, each frame with its pose in... `sensor` -> frame.
    let mut seen: Vec<(String, na::Isometry3<f64>)> =
        vec![(sensor.to_string(), na::Isometry3::identity())];
    let mut at = 0;
    while at < seen.len() {
        let (frame, to_frame) = seen[at].clone();
        if frame == points {
            return Some(to_frame);
        }
        for t in transforms {
            // child -> parent is t.isometry(); parent -> child its inverse.
            let step = if t.child == frame {
                Some((t.parent.clone(), t.isometry() * to_frame))
            } else if t.parent == frame {
                Some((t.child.clone(), t.isometry().inverse() * to_frame))
            } else {
                None
            };
            if let Some((next, pose)) = step {
                if !seen.iter().any(|(f, _)| *f == next) {
                    seen.push((next, pose));
                }
            }
        }
        at += 1;
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tf(parent: &str, child: &str, xyz: [f64; 3], yaw_deg: f64) -> StaticTransform {
        let q = na::UnitQuaternion::from_euler_angles(0.0, 0.0, yaw_deg.to_radians());
        StaticTransform {
            parent: parent.into(),
            child: child.into(),
            translation: xyz,
            rotation: [q.i, q.j, q.k, q.w],
        }
    }

    #[test]
    fn chains_of_static_transforms_give_the_sensor_s_pose() {
        // base_link -> lidar_mount (1 m up), lidar_mount -> velodyne (0.8 m up, yawed 90 deg).
        let ts = [
            tf("base_link", "lidar_mount", [0.5, 0.0, 1.0], 0.0),
            tf("lidar_mount", "velodyne", [0.0, 0.0, 0.8], 90.0),
            tf("base_link", "camera", [1.0, 0.0, 1.2], 0.0),
        ];
        let pose = sensor_pose_in(&ts, "velodyne", "base_link").unwrap();
        let origin = pose * na::Point3::origin();
        assert!((origin - na::Point3::new(0.5, 0.0, 1.8)).norm() < 1e-12);
        // The sensor's x axis is base_link's y axis.
        let x = pose.rotation * na::Vector3::x();
        assert!((x - na::Vector3::y()).norm() < 1e-12);
        // Either way round, through a sibling, or not at all.
        let back = sensor_pose_in(&ts, "base_link", "velodyne").unwrap();
        assert!((back * pose).translation.vector.norm() < 1e-12);
        assert!(sensor_pose_in(&ts, "velodyne", "camera").is_some());
        assert!(sensor_pose_in(&ts, "velodyne", "map").is_none());
        assert_eq!(
            sensor_pose_in(&ts, "velodyne", "velodyne"),
            Some(na::Isometry3::identity())
        );
    }
}
