//! READ: camera images (`image_0X/data/<frame10>.png`, 8-bit; cameras 2 and 3 are colour).

use std::path::Path;

use crate::error::Result;

/// An 8-bit RGB image.
pub type RgbImage = crate::raster::RgbImage;

/// Reads and decodes a camera PNG.
pub fn read_image(path: &Path) -> Result<RgbImage> {
    let bytes = crate::fs::read(path, crate::fs::Limit::Data)?;
    decode_image(&bytes, path)
}

/// Decodes PNG bytes; `path` names the file in errors. KITTI's colour cameras (2 and 3) store
/// 8-bit RGB; a grey image (camera 0 or 1's, or a wrong folder) or a 16-bit one would colour
/// every point wrongly: refused, named ([`crate::raster::decode_rgb`]).
pub fn decode_image(bytes: &[u8], path: &Path) -> Result<RgbImage> {
    crate::raster::decode_rgb(bytes, path)
}
