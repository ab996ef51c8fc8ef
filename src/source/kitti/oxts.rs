//! READ: OXTS GPS/IMU records (`oxts/data/<frame10>.txt`, 30 numbers on one line).
//!
//! Field names and units follow KITTI's `oxts/dataformat.txt`.

use std::path::Path;

use serde::Serialize;

use crate::error::{Error, Result};

/// One OXTS record.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Oxts {
    /// Latitude (deg), longitude (deg), altitude (m).
    pub lat: f64,
    /// Longitude, degrees.
    pub lon: f64,
    /// Altitude, metres.
    pub alt: f64,
    /// Roll, pitch, yaw (rad): 0 = level, east-facing.
    pub roll: f64,
    /// Pitch, radians.
    pub pitch: f64,
    /// Heading, radians (0 = east, positive counter-clockwise).
    pub yaw: f64,
    /// Velocities, m/s: north, east, forward, leftward, upward.
    pub vn: f64,
    /// East velocity, m/s.
    pub ve: f64,
    /// Forward velocity, m/s.
    pub vf: f64,
    /// Leftward velocity, m/s.
    pub vl: f64,
    /// Upward velocity, m/s.
    pub vu: f64,
    /// Accelerations, m/s^2: x, y, z (vehicle frame) then forward, leftward, upward.
    pub ax: f64,
    /// y acceleration, m/s^2.
    pub ay: f64,
    /// z acceleration, m/s^2.
    pub az: f64,
    /// Forward acceleration, m/s^2.
    pub af: f64,
    /// Leftward acceleration, m/s^2.
    pub al: f64,
    /// Upward acceleration, m/s^2.
    pub au: f64,
    /// Angular rates, rad/s: about x, y, z then forward, leftward, upward axes.
    pub wx: f64,
    /// Angular rate about y, rad/s.
    pub wy: f64,
    /// Angular rate about z, rad/s.
    pub wz: f64,
    /// Angular rate about the forward axis, rad/s.
    pub wf: f64,
    /// Angular rate about the leftward axis, rad/s.
    pub wl: f64,
    /// Angular rate about the upward axis, rad/s.
    pub wu: f64,
    /// Position accuracy (north/east), metres.
    pub pos_accuracy: f64,
    /// Velocity accuracy (north/east), m/s.
    pub vel_accuracy: f64,
    /// Navigation status.
    pub navstat: i32,
    /// Number of satellites tracked by the primary GPS receiver.
    pub numsats: i32,
    /// Position mode of the primary receiver.
    pub posmode: i32,
    /// Velocity mode of the primary receiver.
    pub velmode: i32,
    /// Orientation mode of the primary receiver.
    pub orimode: i32,
}

impl Oxts {
    /// Parses one record line; `path` names the file in errors.
    pub fn parse(text: &str, path: &Path) -> Result<Oxts> {
        let v: Vec<f64> = text
            .split_whitespace()
            .map(|s| s.parse::<f64>())
            .collect::<std::result::Result<_, _>>()
            .map_err(|e| Error::format(path, format!("oxts record: {e}")))?;
        // Every field refused alike when not finite, used by the conversion or not.
        if let Some(k) = v.iter().position(|x| !x.is_finite()) {
            return Err(Error::NotFinite {
                path: path.into(),
                what: format!("oxts value {}", k + 1),
                value: v[k],
            });
        }
        if v.len() != 30 {
            return Err(Error::Length {
                path: path.into(),
                what: "the oxts record".into(),
                found: v.len(),
                expected: 30,
                unit: "values",
            });
        }
        let i = |k: usize| v[k] as i32;
        Ok(Oxts {
            lat: v[0],
            lon: v[1],
            alt: v[2],
            roll: v[3],
            pitch: v[4],
            yaw: v[5],
            vn: v[6],
            ve: v[7],
            vf: v[8],
            vl: v[9],
            vu: v[10],
            ax: v[11],
            ay: v[12],
            az: v[13],
            af: v[14],
            al: v[15],
            au: v[16],
            wx: v[17],
            wy: v[18],
            wz: v[19],
            wf: v[20],
            wl: v[21],
            wu: v[22],
            pos_accuracy: v[23],
            vel_accuracy: v[24],
            navstat: i(25),
            numsats: i(26),
            posmode: i(27),
            velmode: i(28),
            orimode: i(29),
        })
    }

    /// Reads a record file.
    pub fn read(path: &Path) -> Result<Oxts> {
        let text = crate::fs::read_text(path, crate::fs::Limit::Text)?;
        Oxts::parse(&text, path)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_field_must_be_finite() {
        let mut fields = vec!["1.0"; 30];
        assert!(Oxts::parse(&fields.join(" "), Path::new("o.txt")).is_ok());
        fields[20] = "nan";
        match Oxts::parse(&fields.join(" "), Path::new("o.txt")) {
            Err(Error::NotFinite { path, what, value }) => {
                assert_eq!(path, Path::new("o.txt"));
                assert_eq!(what, "oxts value 21");
                assert!(value.is_nan());
            }
            other => panic!("{other:?}"),
        }
    }
}
