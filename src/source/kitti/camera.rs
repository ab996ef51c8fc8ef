//! READ: camera images (`image_0X/data/<frame10>.png`, 8-bit; cameras 2 and 3 are colour).

use std::path::Path;

use crate::error::{Error, Result};

/// An 8-bit RGB image (grey images are expanded).
pub type RgbImage = image::RgbImage;

/// Reads and decodes a camera PNG.
pub fn read_image(path: &Path) -> Result<RgbImage> {
    let bytes = crate::fs::read(path, crate::fs::Limit::Data)?;
    decode_image(&bytes, path)
}

/// Decodes PNG bytes; `path` names the file in errors.
pub fn decode_image(bytes: &[u8], path: &Path) -> Result<RgbImage> {
    let img =
        image::load_from_memory_with_format(bytes, image::ImageFormat::Png).map_err(|source| {
            Error::Image {
                path: path.into(),
                source,
            }
        })?;
    // KITTI's colour cameras (2 and 3) store 8-bit RGB. A grey image (camera 0 or 1's, or a
    // wrong folder) or a 16-bit one would colour every point wrongly: refused, named.
    match img {
        image::DynamicImage::ImageRgb8(rgb) => Ok(rgb),
        image::DynamicImage::ImageRgba8(_) => Ok(img.to_rgb8()),
        other => Err(Error::format(
            path,
            format!(
                "a {:?} image; colour needs 8-bit RGB (the colour cameras' PNGs; a grey image is camera 0 or 1's)",
                other.color()
            ),
        )),
    }
}
