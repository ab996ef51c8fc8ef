//! WRITE: PNG pictures (previews, charts, score pictures), atomically ([`crate::raster`] owns
//! the encoding).

use std::path::Path;

use crate::error::{Error, Result};
use crate::raster::RgbImage;

/// Encodes `img` as PNG and writes it atomically to `path`.
pub fn write(path: &Path, img: &RgbImage) -> Result<()> {
    let bytes = crate::raster::encode(img).map_err(|e| Error::Write {
        path: path.into(),
        source: std::io::Error::other(e),
    })?;
    super::atomic_write(path, &bytes, super::Durability::Renamed)
}
