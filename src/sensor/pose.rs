//! Where the sensor sits in the frame its points are written in: a cloud already moved to a
//! vehicle frame (a ROS bag's `base_link`) is brought back to the sensor's own frame before rows
//! are decided, so that elevations are seen from the beams again.

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::geom::{na, Point3};

/// The sensor's pose in the points' frame: translation in metres, then roll, pitch and yaw in
/// degrees (rotations about the fixed x, y, z axes in that order: ROS's RPY convention).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SensorPose {
    /// Position of the sensor's origin, metres.
    pub xyz: [f64; 3],
    /// Roll, pitch, yaw, degrees.
    pub rpy_deg: [f64; 3],
}

/// The farthest a sensor can sit from the origin of its points' frame: a mounting on a vehicle
/// or a rig is metres away; a pose beyond this is a typing error (`1e30`), which would carry every
/// point past the range limit.
pub const MAX_MOUNT_OFFSET_M: f64 = 100.0;

impl SensorPose {
    /// Parses `x,y,z` or `x,y,z,roll,pitch,yaw` (metres, degrees); a position farther than
    /// [`MAX_MOUNT_OFFSET_M`] from the origin is not a mounting and is refused.
    pub fn parse(text: &str) -> Result<SensorPose> {
        let bad = |m: &str| Error::Config(format!("--sensor-pose {text:?}: {m}"));
        let v: Vec<f64> = text
            .split(',')
            .map(|s| s.trim().parse::<f64>().ok().filter(|x| x.is_finite()))
            .collect::<Option<_>>()
            .ok_or_else(|| bad("not a list of finite numbers"))?;
        let pose = match v[..] {
            [x, y, z] => SensorPose {
                xyz: [x, y, z],
                rpy_deg: [0.0; 3],
            },
            [x, y, z, r, p, w] => SensorPose {
                xyz: [x, y, z],
                rpy_deg: [r, p, w],
            },
            _ => return Err(bad("expected x,y,z or x,y,z,roll,pitch,yaw")),
        };
        let offset = pose.xyz.iter().map(|c| c * c).sum::<f64>().sqrt();
        if offset > MAX_MOUNT_OFFSET_M {
            return Err(bad(&format!(
                "the sensor {} m from the points' origin is not a mounting (at most \
                 {MAX_MOUNT_OFFSET_M} m): the pose is the sensor's place on the vehicle",
                crate::error::shown(offset)
            )));
        }
        if pose.rpy_deg.iter().any(|a| a.abs() > 360.0) {
            return Err(bad("roll, pitch and yaw are degrees within -360..360"));
        }
        Ok(pose)
    }

    /// The pose of a rigid motion sensor frame -> points' frame (a bag's static transforms).
    pub fn from_isometry(iso: &na::Isometry3<f64>) -> SensorPose {
        let (r, p, y) = iso.rotation.euler_angles();
        let t = iso.translation.vector;
        SensorPose {
            xyz: [t.x, t.y, t.z],
            rpy_deg: [r, p, y].map(f64::to_degrees),
        }
    }

    /// The sensor frame -> the points' frame.
    pub fn isometry(&self) -> na::Isometry3<f64> {
        let [r, p, y] = self.rpy_deg.map(f64::to_radians);
        na::Isometry3::from_parts(
            na::Translation3::new(self.xyz[0], self.xyz[1], self.xyz[2]),
            na::UnitQuaternion::from_euler_angles(r, p, y),
        )
    }

    /// Moves `points` from their frame into the sensor's (computed in f64).
    pub fn to_sensor_frame(&self, points: &mut [Point3]) {
        let inverse = self.isometry().inverse();
        for p in points {
            let q = inverse * na::Point3::new(p.x as f64, p.y as f64, p.z as f64);
            *p = Point3::new(q.x as f32, q.y as f32, q.z as f32);
        }
    }
}

impl std::fmt::Display for SensorPose {
    /// `x,y,z,roll,pitch,yaw` as `--sensor-pose` takes it (metres to 0.1 mm, degrees to 1e-4).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let [x, y, z] = self.xyz;
        let [r, p, w] = self.rpy_deg;
        // `+ 0.0` turns -0 into 0.
        write!(
            f,
            "{:.4},{:.4},{:.4},{:.4},{:.4},{:.4}",
            x + 0.0,
            y + 0.0,
            z + 0.0,
            r + 0.0,
            p + 0.0,
            w + 0.0
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_and_moves_points_into_the_sensor_frame() {
        let p = SensorPose::parse("1, 0, 1.8").unwrap();
        let mut pts = [Point3::new(11.0, 0.0, 1.8)];
        p.to_sensor_frame(&mut pts);
        assert!((pts[0] - Point3::new(10.0, 0.0, 0.0)).norm() < 1e-6);
        // Yawed 90 degrees: the sensor's x axis is the points' y axis.
        let p = SensorPose::parse("0,0,0,0,0,90").unwrap();
        let mut pts = [Point3::new(0.0, 5.0, 0.0)];
        p.to_sensor_frame(&mut pts);
        assert!((pts[0] - Point3::new(5.0, 0.0, 0.0)).norm() < 1e-6);
        // Round trip through an isometry, and its text as --sensor-pose takes it.
        let p = SensorPose::parse("0.5,-0.2,1.8,1,-2,30").unwrap();
        let back = SensorPose::from_isometry(&p.isometry());
        for (a, b) in p
            .xyz
            .iter()
            .chain(&p.rpy_deg)
            .zip(back.xyz.iter().chain(&back.rpy_deg))
        {
            assert!((a - b).abs() < 1e-9, "{p:?} {back:?}");
        }
        assert_eq!(
            SensorPose::parse(&back.to_string()).unwrap().to_string(),
            back.to_string()
        );
        for bad in [
            "1,2",
            "1,2,3,4",
            "1,x,3",
            "1,2,inf",
            "1e30,0,0",
            "600,0,0",
            "0,0,0,0,0,1e9",
        ] {
            assert!(SensorPose::parse(bad).is_err(), "{bad}");
        }
    }
}
