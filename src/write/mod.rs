//! WRITE: files on disk, always atomically.
//!
//! Every output is first written to a temporary file in the destination folder and renamed into
//! place, so a crash or a full disk never leaves a half-written file under a final name.

pub mod npy;
pub mod shard;
pub mod viz;

use std::io::Write;
use std::path::Path;

use crate::error::{Error, Result};

/// Writes `bytes` to `path` atomically (temporary file in the same folder, then rename).
///
/// The rename makes the file appear whole or not at all, whatever happens to the process. With
/// `durable`, the data is also flushed to the device before the rename, so that the file survives
/// a power cut as well; that costs a disk round trip per file, so it is an option (`--sync`).
pub fn atomic_write(path: &Path, bytes: &[u8], durable: bool) -> Result<()> {
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let werr = |source| Error::Write {
        path: path.into(),
        source,
    };
    let mut tmp = temp_builder()
        .tempfile_in(dir)
        .map_err(|source| Error::Write {
            path: dir.into(),
            source,
        })?;
    tmp.write_all(bytes).map_err(werr)?;
    if durable {
        tmp.as_file().sync_data().map_err(werr)?;
    }
    tmp.persist(path).map_err(|e| werr(e.error))?;
    Ok(())
}

/// A temporary-file builder for outputs: hidden `.tmp-` name, and on Unix the mode of an
/// ordinary new file (0666 less the umask) instead of tempfile's private 0600, so that the file
/// keeps normal permissions once renamed into place.
pub fn temp_builder() -> tempfile::Builder<'static, 'static> {
    let mut b = tempfile::Builder::new();
    b.prefix(".tmp-");
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        b.permissions(std::fs::Permissions::from_mode(0o666));
    }
    b
}

/// Path of a frame's `.npy` in a convert output folder: `DIR/lidar_2d/<frame id>.npy`.
pub fn npy_path(dir: &Path, id: &crate::kitti::FrameId) -> std::path::PathBuf {
    dir.join("lidar_2d").join(format!("{id}.npy"))
}

/// Path of a frame's `.label` in a convert output folder:
/// `DIR/labels/<date>_drive_<NNNN>_sync/<frame10>.label`.
pub fn label_path(dir: &Path, id: &crate::kitti::FrameId) -> std::path::PathBuf {
    dir.join("labels")
        .join(format!("{}_drive_{:04}_sync", id.date, id.drive))
        .join(format!("{:010}.label", id.frame))
}

/// Encodes `img` as PNG and writes it atomically to `path`.
pub fn write_png(path: &Path, img: &image::RgbImage) -> Result<()> {
    let mut bytes = Vec::new();
    img.write_to(
        &mut std::io::Cursor::new(&mut bytes),
        image::ImageFormat::Png,
    )
    .map_err(|source| Error::Image {
        path: path.into(),
        source,
    })?;
    atomic_write(path, &bytes, false)
}

/// Creates a folder and its parents, naming it in the error.
pub fn create_dir(path: &Path) -> Result<()> {
    std::fs::create_dir_all(path).map_err(|source| Error::Write {
        path: path.into(),
        source,
    })
}

/// The bytes of a `.label` file: one little-endian u32 per point, class in the low 16 bits,
/// instance id in the high 16 bits.
pub fn label_file_bytes(class: &[u8], instance: &[u16]) -> Vec<u8> {
    debug_assert_eq!(class.len(), instance.len());
    let mut out = Vec::with_capacity(class.len() * 4);
    for (c, i) in class.iter().zip(instance) {
        out.extend_from_slice(&((*i as u32) << 16 | *c as u32).to_le_bytes());
    }
    out
}
