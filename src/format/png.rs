//! WRITE: PNG pictures (previews, charts, score pictures), atomically.

use std::path::Path;

use crate::error::{Error, Result};

/// Encodes `img` as PNG and writes it atomically to `path`.
pub fn write(path: &Path, img: &image::RgbImage) -> Result<()> {
    let mut bytes = Vec::new();
    img.write_to(
        &mut std::io::Cursor::new(&mut bytes),
        image::ImageFormat::Png,
    )
    .map_err(|source| Error::Image {
        path: path.into(),
        source,
    })?;
    super::atomic_write(path, &bytes, super::Durability::Renamed)
}
