//! PROJECT: velodyne points to camera pixels, and colour sampling for the RGB channels.
//!
//! A velodyne point `p` maps to homogeneous pixel `(u w, v w, w) = P_rect_0c * R_rect_00 *
//! Tr_velo_to_cam * (p, 1)` ([`crate::source::kitti::calib::Calibration::velo_to_image`]). It has a colour
//! when it is in front of the camera (`w > 0`) and its sample falls inside the image. Pixel
//! coordinates have integer values at pixel centres (KITTI / OpenCV): pixel (0, 0) covers
//! u in [-0.5, 0.5).
//!
//! Sampling: [`Sampling::Nearest`] takes the pixel whose centre is nearest (`round(u)`,
//! `round(v)`), inside when `-0.5 <= u < width - 0.5`; [`Sampling::Bilinear`] blends the four
//! surrounding pixels, inside when `0 <= u <= width - 1`. Colours are scaled to [0, 1].

use serde::Serialize;

use crate::geom::{floor_i64, Matrix3x4, Point3};
use crate::source::kitti::camera::RgbImage;

/// How a colour is read at a sub-pixel position.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Sampling {
    /// The nearest pixel (default): exact colours, no blending across object borders.
    #[default]
    Nearest,
    /// Bilinear interpolation of the four neighbours.
    Bilinear,
}

crate::named_enum!(Sampling, "colour sampling", [
    Nearest => "nearest" [] "The pixel whose centre is nearest",
    Bilinear => "bilinear" [] "Bilinear blend of the four neighbouring pixels",
]);

/// `c / 255` for every 8-bit value `c` (the same quotients, without a division a sample).
static UNIT: [f32; 256] = {
    let mut t = [0.0; 256];
    let mut c = 0;
    while c < 256 {
        t[c] = c as f32 / 255.0;
        c += 1;
    }
    t
};

/// Pixel coordinates of velodyne point `p` through `velo_to_image` (velodyne to homogeneous
/// pixels), or `None` behind the camera.
#[inline]
pub fn pixel(velo_to_image: &Matrix3x4, p: &Point3) -> Option<(f64, f64)> {
    let m = velo_to_image;
    let (x, y, z) = (p.x as f64, p.y as f64, p.z as f64);
    let w = m[(2, 0)] * x + m[(2, 1)] * y + m[(2, 2)] * z + m[(2, 3)];
    if w <= 0.0 {
        return None;
    }
    let u = (m[(0, 0)] * x + m[(0, 1)] * y + m[(0, 2)] * z + m[(0, 3)]) / w;
    let v = (m[(1, 0)] * x + m[(1, 1)] * y + m[(1, 2)] * z + m[(1, 3)]) / w;
    Some((u, v))
}

/// Projects velodyne points into one camera's rectified image.
#[derive(Debug, Clone)]
pub struct CameraProjector {
    /// Velodyne to homogeneous pixels.
    pub velo_to_image: Matrix3x4,
    /// Sampling rule.
    pub sampling: Sampling,
}

impl CameraProjector {
    /// Pixel coordinates of `p`, or `None` behind the camera.
    #[inline]
    pub fn pixel(&self, p: &Point3) -> Option<(f64, f64)> {
        pixel(&self.velo_to_image, p)
    }

    /// Colour of `p` in `image`, scaled to [0, 1], or `None` when it has none.
    #[inline(always)]
    pub fn colour(&self, image: &RgbImage, p: &Point3) -> Option<[f32; 3]> {
        let (u, v) = self.pixel(p)?;
        let (w, h) = (image.width() as f64, image.height() as f64);
        match self.sampling {
            Sampling::Nearest => {
                if !(u >= -0.5 && v >= -0.5 && u < w - 0.5 && v < h - 0.5) {
                    return None;
                }
                let (cu, cv) = (floor_i64(u + 0.5), floor_i64(v + 0.5));
                let px = image.get_pixel(cu as u32, cv as u32).0;
                Some(px.map(|c| UNIT[c as usize]))
            }
            Sampling::Bilinear => {
                if !(u >= 0.0 && v >= 0.0 && u <= w - 1.0 && v <= h - 1.0) {
                    return None;
                }
                let (u0, v0) = (floor_i64(u) as u32, floor_i64(v) as u32);
                let (u1, v1) = (
                    (u0 + 1).min(image.width() - 1),
                    (v0 + 1).min(image.height() - 1),
                );
                let (fu, fv) = (u - u0 as f64, v - v0 as f64);
                let px = |a: u32, b: u32| image.get_pixel(a, b).0;
                let (p00, p10, p01, p11) = (px(u0, v0), px(u1, v0), px(u0, v1), px(u1, v1));
                let mut out = [0f32; 3];
                for k in 0..3 {
                    let top = p00[k] as f64 * (1.0 - fu) + p10[k] as f64 * fu;
                    let bottom = p01[k] as f64 * (1.0 - fu) + p11[k] as f64 * fu;
                    out[k] = ((top * (1.0 - fv) + bottom * fv) / 255.0) as f32;
                }
                Some(out)
            }
        }
    }
}

/// Colour channels: which camera, how sampled.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, serde::Deserialize)]
pub struct RgbOptions {
    /// Camera 2 (left colour, default) or 3 (right colour).
    pub camera: u8,
    /// Sampling rule.
    pub sampling: Sampling,
}
