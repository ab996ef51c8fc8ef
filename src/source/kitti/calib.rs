//! READ: the calibration files of a recording day (`<date>/calib_*.txt`).
//!
//! Each file is a list of `key: values` lines. `calib_cam_to_cam.txt` holds, for cameras 00-03,
//! `S` (image size before rectification), `K`, `D`, `R`, `T` (intrinsics, distortion and pose
//! relative to camera 0), `S_rect`, `R_rect` and `P_rect` (rectified size, rectifying rotation and
//! projection). `calib_velo_to_cam.txt` and `calib_imu_to_velo.txt` hold `R` and `T` of a rigid
//! motion (the first also `delta_f`, `delta_c`). Matrices are row-major in the files.
//!
//! A point in the velodyne frame reaches pixel coordinates of camera `i` by
//! `p_rect_i * rect_00 * velo_to_cam` (KITTI devkit convention; see `docs/conventions.md`).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::geom::{na, Matrix3x4, RigidF64};

/// File name of the camera-to-camera calibration.
pub const CAM_TO_CAM: &str = "calib_cam_to_cam.txt";
/// File name of the velodyne-to-camera calibration.
pub const VELO_TO_CAM: &str = "calib_velo_to_cam.txt";
/// File name of the IMU-to-velodyne calibration.
pub const IMU_TO_VELO: &str = "calib_imu_to_velo.txt";

/// The raw `key: values` content of a calibration file.
#[derive(Debug, Clone)]
pub struct CalibFile {
    path: PathBuf,
    numeric: BTreeMap<String, Vec<f64>>,
    text: BTreeMap<String, String>,
}

impl CalibFile {
    /// Parses calibration text; `path` names the file in errors.
    pub fn parse(text: &str, path: &Path) -> Result<CalibFile> {
        let mut numeric = BTreeMap::new();
        let mut texts = BTreeMap::new();
        let mut lines: BTreeMap<String, usize> = BTreeMap::new();
        for (i, line) in text.lines().enumerate() {
            let line = line.trim();
            if line.is_empty() {
                continue;
            }
            let Some((key, value)) = line.split_once(':') else {
                return Err(Error::Format {
                    path: path.into(),
                    line: Some(i + 1),
                    message: format!("expected `key: values`, found {line:?}"),
                });
            };
            let key = key.trim().to_string();
            if let Some(first) = lines.insert(key.clone(), i + 1) {
                return Err(Error::Format {
                    path: path.into(),
                    line: Some(i + 1),
                    message: format!("key `{key}` appears twice (first on line {first})"),
                });
            }
            let parsed: std::result::Result<Vec<f64>, _> =
                value.split_whitespace().map(str::parse::<f64>).collect();
            match parsed {
                Ok(v) if !v.is_empty() => {
                    if let Some(bad) = v.iter().find(|x| !x.is_finite()) {
                        return Err(Error::Format {
                            path: path.into(),
                            line: Some(i + 1),
                            message: format!("key `{key}` holds a non-finite value {bad}"),
                        });
                    }
                    numeric.insert(key, v);
                }
                _ => {
                    texts.insert(key, value.trim().to_string());
                }
            }
        }
        Ok(CalibFile {
            path: path.into(),
            numeric,
            text: texts,
        })
    }

    /// Reads and parses a calibration file.
    pub fn read(path: &Path) -> Result<CalibFile> {
        let text = crate::fs::read_text(path, crate::fs::Limit::Text)?;
        CalibFile::parse(&text, path)
    }

    /// The file this was read from.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The numbers of `key`, which must hold exactly `n` of them.
    pub fn values(&self, key: &str, n: usize) -> Result<&[f64]> {
        match self.numeric.get(key) {
            Some(v) if v.len() == n => Ok(v),
            Some(v) => Err(Error::format(
                &self.path,
                format!("key `{key}` holds {} numbers, expected {n}", v.len()),
            )),
            None if self.text.contains_key(key) => Err(Error::format(
                &self.path,
                format!("key `{key}` is not a list of numbers: {:?}", self.text[key]),
            )),
            None => Err(Error::MissingKey {
                path: self.path.clone(),
                key: key.into(),
            }),
        }
    }

    /// A text value (such as `calib_time`), if present.
    pub fn text(&self, key: &str) -> Option<&str> {
        self.text.get(key).map(String::as_str)
    }

    fn mat3(&self, key: &str) -> Result<na::Matrix3<f64>> {
        Ok(na::Matrix3::from_row_slice(self.values(key, 9)?))
    }

    /// `key` as a rotation, checked ([`crate::geom::check_rotation`]).
    fn rotation(&self, key: &str) -> Result<na::Matrix3<f64>> {
        let m = self.mat3(key)?;
        self.check_rotation(key, &m)?;
        Ok(m)
    }

    fn check_rotation(&self, key: &str, m: &na::Matrix3<f64>) -> Result<()> {
        crate::geom::check_rotation(m)
            .map_err(|e| Error::format(&self.path, format!("key `{key}` {e}")))
    }

    fn vec3(&self, key: &str) -> Result<na::Vector3<f64>> {
        Ok(na::Vector3::from_row_slice(self.values(key, 3)?))
    }

    fn vec2(&self, key: &str) -> Result<na::Vector2<f64>> {
        Ok(na::Vector2::from_row_slice(self.values(key, 2)?))
    }

    /// `R` and `T` as a rigid motion (rotation kept exactly as written).
    fn rigid(&self, r: &str, t: &str) -> Result<RigidF64> {
        let rot = na::Rotation3::from_matrix_unchecked(self.rotation(r)?);
        Ok(RigidF64::from_parts(
            na::Translation3::from(self.vec3(t)?),
            rot,
        ))
    }
}

/// Calibration of one camera in `calib_cam_to_cam.txt`.
#[derive(Debug, Clone, PartialEq)]
pub struct CameraCalib {
    /// Image size before rectification (width, height), pixels.
    pub size: na::Vector2<f64>,
    /// Intrinsics before rectification.
    pub k: na::Matrix3<f64>,
    /// Distortion coefficients (k1, k2, p1, p2, k3).
    pub d: [f64; 5],
    /// Rotation from camera 0 to this camera.
    pub r: na::Matrix3<f64>,
    /// Translation from camera 0 to this camera, metres.
    pub t: na::Vector3<f64>,
    /// Image size after rectification (width, height), pixels.
    pub size_rect: na::Vector2<f64>,
    /// Rectifying rotation of this camera.
    pub r_rect: na::Matrix3<f64>,
    /// Projection from rectified camera-0 coordinates to this camera's rectified pixels.
    pub p_rect: Matrix3x4,
}

/// `calib_cam_to_cam.txt`: the four cameras.
#[derive(Debug, Clone, PartialEq)]
pub struct CamToCam {
    /// `calib_time`, as written.
    pub calib_time: Option<String>,
    /// `corner_dist`, metres.
    pub corner_dist: Option<f64>,
    /// Cameras 00, 01, 02 and 03.
    pub cameras: [CameraCalib; 4],
}

impl CamToCam {
    /// Builds the typed calibration, requiring every key of the four cameras.
    pub fn from_file(f: &CalibFile) -> Result<CamToCam> {
        let cam = |i: usize| -> Result<CameraCalib> {
            let d = f.values(&format!("D_{i:02}"), 5)?;
            Ok(CameraCalib {
                size: f.vec2(&format!("S_{i:02}"))?,
                k: f.mat3(&format!("K_{i:02}"))?,
                d: [d[0], d[1], d[2], d[3], d[4]],
                r: f.mat3(&format!("R_{i:02}"))?,
                t: f.vec3(&format!("T_{i:02}"))?,
                size_rect: f.vec2(&format!("S_rect_{i:02}"))?,
                r_rect: f.rotation(&format!("R_rect_{i:02}"))?,
                p_rect: Matrix3x4::from_row_slice(f.values(&format!("P_rect_{i:02}"), 12)?),
            })
        };
        Ok(CamToCam {
            calib_time: f.text("calib_time").map(str::to_string),
            corner_dist: f.values("corner_dist", 1).ok().map(|v| v[0]),
            cameras: [cam(0)?, cam(1)?, cam(2)?, cam(3)?],
        })
    }

    /// `R_rect_00` as a 4x4 homogeneous matrix.
    pub fn rect_00(&self) -> na::Matrix4<f64> {
        let mut m = na::Matrix4::identity();
        m.fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&self.cameras[0].r_rect);
        m
    }
}

/// `calib_velo_to_cam.txt`.
#[derive(Debug, Clone, PartialEq)]
pub struct VeloToCam {
    /// `calib_time`, as written.
    pub calib_time: Option<String>,
    /// Velodyne frame to (unrectified) camera-0 frame.
    pub velo_to_cam: RigidF64,
    /// `delta_f`, if present.
    pub delta_f: Option<[f64; 2]>,
    /// `delta_c`, if present.
    pub delta_c: Option<[f64; 2]>,
}

impl VeloToCam {
    /// Builds the typed calibration; `R` and `T` are required.
    pub fn from_file(f: &CalibFile) -> Result<VeloToCam> {
        let pair = |k: &str| f.values(k, 2).ok().map(|v| [v[0], v[1]]);
        Ok(VeloToCam {
            calib_time: f.text("calib_time").map(str::to_string),
            velo_to_cam: f.rigid("R", "T")?,
            delta_f: pair("delta_f"),
            delta_c: pair("delta_c"),
        })
    }
}

/// `calib_imu_to_velo.txt`.
#[derive(Debug, Clone, PartialEq)]
pub struct ImuToVelo {
    /// `calib_time`, as written.
    pub calib_time: Option<String>,
    /// IMU (OXTS) frame to velodyne frame.
    pub imu_to_velo: RigidF64,
}

impl ImuToVelo {
    /// Builds the typed calibration; `R` and `T` are required.
    pub fn from_file(f: &CalibFile) -> Result<ImuToVelo> {
        Ok(ImuToVelo {
            calib_time: f.text("calib_time").map(str::to_string),
            imu_to_velo: f.rigid("R", "T")?,
        })
    }
}

/// The calibration of one recording day.
#[derive(Debug, Clone, PartialEq)]
pub struct Calibration {
    /// Cameras.
    pub cam_to_cam: CamToCam,
    /// Velodyne to camera 0.
    pub velo_to_cam: VeloToCam,
    /// IMU to velodyne; `None` when the file is absent (it is not needed to convert).
    pub imu_to_velo: Option<ImuToVelo>,
}

impl Calibration {
    /// Reads the calibration files in a date folder (`<root>/<date>/`).
    pub fn read_dir(dir: &Path) -> Result<Calibration> {
        let cam_to_cam = CamToCam::from_file(&CalibFile::read(&dir.join(CAM_TO_CAM))?)?;
        let velo_to_cam = VeloToCam::from_file(&CalibFile::read(&dir.join(VELO_TO_CAM))?)?;
        let imu_path = dir.join(IMU_TO_VELO);
        let imu_to_velo = if crate::fs::present(&imu_path) {
            Some(ImuToVelo::from_file(&CalibFile::read(&imu_path)?)?)
        } else {
            None
        };
        Ok(Calibration {
            cam_to_cam,
            velo_to_cam,
            imu_to_velo,
        })
    }

    /// The 3x4 matrix taking homogeneous velodyne points to homogeneous pixels of `camera`
    /// (0-3): `P_rect_0i * R_rect_00 * Tr_velo_to_cam`.
    pub fn velo_to_image(&self, camera: usize) -> Matrix3x4 {
        let p = self.cam_to_cam.cameras[camera].p_rect;
        p * self.cam_to_cam.rect_00() * self.velo_to_cam.velo_to_cam.to_homogeneous()
    }
}

/// The calibration of an odometry sequence (`calib.txt`: `P0`..`P3`, `Tr`) or of an object
/// frame (`calib/<frame6>.txt`: `P0`..`P3`, `R0_rect`, `Tr_velo_to_cam`): the rectified
/// cameras' projections and the velodyne-to-rectified-camera-0 transform.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameCalib {
    /// `P0`..`P3`: rectified camera-0 coordinates to each camera's pixels.
    pub p: [Matrix3x4; 4],
    /// `R0_rect` (identity for odometry sequences, whose `Tr` is already rectified).
    pub r0_rect: na::Matrix3<f64>,
    /// `Tr` / `Tr_velo_to_cam`, velodyne to camera 0, kept as written (3x4).
    pub velo_to_cam: Matrix3x4,
}

impl FrameCalib {
    /// Reads a sequence's `calib.txt` or an object frame's calibration file. A missing key
    /// (`Tr` or `Tr_velo_to_cam`, `P2`, ...) is an error naming the file and the key.
    pub fn read(path: &Path) -> Result<FrameCalib> {
        let f = CalibFile::read(path)?;
        let p = |i: usize| -> Result<Matrix3x4> {
            Ok(Matrix3x4::from_row_slice(f.values(&format!("P{i}"), 12)?))
        };
        // An object frame's file (`Tr_velo_to_cam`) must give `R0_rect`; an odometry
        // sequence's `Tr` is already rectified.
        let object =
            f.numeric.contains_key("Tr_velo_to_cam") || f.text.contains_key("Tr_velo_to_cam");
        let tr_key = if object { "Tr_velo_to_cam" } else { "Tr" };
        let velo_to_cam = Matrix3x4::from_row_slice(f.values(tr_key, 12)?);
        f.check_rotation(tr_key, &velo_to_cam.fixed_view::<3, 3>(0, 0).into_owned())?;
        Ok(FrameCalib {
            p: [p(0)?, p(1)?, p(2)?, p(3)?],
            r0_rect: if object || f.numeric.contains_key("R0_rect") {
                f.rotation("R0_rect")?
            } else {
                na::Matrix3::identity()
            },
            velo_to_cam,
        })
    }

    /// Velodyne to rectified camera 0, 4x4 homogeneous: `R0_rect * Tr`.
    pub fn velo_to_rect(&self) -> na::Matrix4<f64> {
        let mut r = na::Matrix4::identity();
        r.fixed_view_mut::<3, 3>(0, 0).copy_from(&self.r0_rect);
        let mut t = na::Matrix4::identity();
        t.fixed_view_mut::<3, 4>(0, 0).copy_from(&self.velo_to_cam);
        r * t
    }

    /// Homogeneous velodyne points to homogeneous pixels of `camera`: `P_c * R0_rect * Tr`.
    pub fn velo_to_image(&self, camera: usize) -> Matrix3x4 {
        self.p[camera] * self.velo_to_rect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_numbers_and_text() {
        let f = CalibFile::parse(
            "calib_time: 15-Mar-2012 11:37:16\nR: 1 0 0 0 1 0 0 0 1\nT: 1 2 3\n",
            Path::new("v.txt"),
        )
        .unwrap();
        assert_eq!(f.text("calib_time"), Some("15-Mar-2012 11:37:16"));
        let v = VeloToCam::from_file(&f).unwrap();
        let p = v
            .velo_to_cam
            .transform_point(&na::Point3::new(1.0, 1.0, 1.0));
        assert_eq!(p, na::Point3::new(2.0, 3.0, 4.0));
    }

    #[test]
    fn missing_and_malformed_keys_name_the_file() {
        let f = CalibFile::parse("R: 1 0 0 0 1 0 0 0 1\n", Path::new("velo.txt")).unwrap();
        let e = VeloToCam::from_file(&f).unwrap_err().to_string();
        assert!(e.contains("velo.txt") && e.contains("`T`"), "{e}");
        let f = CalibFile::parse("R: 1 0 0\nT: 1 2 3\n", Path::new("velo.txt")).unwrap();
        let e = VeloToCam::from_file(&f).unwrap_err().to_string();
        assert!(e.contains("holds 3 numbers, expected 9"), "{e}");
        let e = CalibFile::parse("garbage line\n", Path::new("c.txt"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("c.txt:1"), "{e}");
    }
}
