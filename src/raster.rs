//! 8-bit RGB rasters and PNG, both ways: the camera images read for colour, and the pictures the
//! tool draws. The one owner of the PNG format (through the `png` crate, which `image` wraps:
//! its colour-management dependencies were the release build's longest chain, issue 48).

use std::path::Path;

use crate::error::{Error, Result};

/// One 8-bit RGB pixel.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Rgb(pub [u8; 3]);

impl std::ops::Index<usize> for Rgb {
    type Output = u8;
    /// Channel `i` (0 red, 1 green, 2 blue).
    fn index(&self, i: usize) -> &u8 {
        &self.0[i]
    }
}

/// An 8-bit RGB image, rows top to bottom, pixels left to right.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct RgbImage {
    width: u32,
    height: u32,
    data: Vec<u8>,
}

impl RgbImage {
    /// A black image.
    pub fn new(width: u32, height: u32) -> RgbImage {
        RgbImage::from_pixel(width, height, Rgb([0, 0, 0]))
    }

    /// An image of one colour.
    pub fn from_pixel(width: u32, height: u32, p: Rgb) -> RgbImage {
        let n = width as usize * height as usize;
        RgbImage {
            width,
            height,
            data: p.0.repeat(n),
        }
    }

    /// An image of the row-major RGB bytes `data`; `None` unless they are `width * height * 3`.
    pub fn from_raw(width: u32, height: u32, data: Vec<u8>) -> Option<RgbImage> {
        (data.len() == width as usize * height as usize * 3).then_some(RgbImage {
            width,
            height,
            data,
        })
    }

    /// Width, pixels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height, pixels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// Width and height, pixels.
    pub fn dimensions(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// The row-major RGB bytes.
    pub fn as_raw(&self) -> &[u8] {
        &self.data
    }

    fn at(&self, x: u32, y: u32) -> usize {
        assert!(
            x < self.width && y < self.height,
            "pixel ({x}, {y}) outside the image"
        );
        (y as usize * self.width as usize + x as usize) * 3
    }

    /// The pixel at column `x`, row `y` (panics outside the image, as indexing does).
    pub fn get_pixel(&self, x: u32, y: u32) -> Rgb {
        let i = self.at(x, y);
        Rgb([self.data[i], self.data[i + 1], self.data[i + 2]])
    }

    /// Sets the pixel at column `x`, row `y` (panics outside the image).
    pub fn put_pixel(&mut self, x: u32, y: u32, p: Rgb) {
        let i = self.at(x, y);
        self.data[i..i + 3].copy_from_slice(&p.0);
    }

    /// The pixels, row-major.
    pub fn pixels(&self) -> impl Iterator<Item = Rgb> + '_ {
        self.data.chunks_exact(3).map(|c| Rgb([c[0], c[1], c[2]]))
    }
}

/// Encodes `img` as an 8-bit RGB PNG.
pub fn encode(img: &RgbImage) -> std::result::Result<Vec<u8>, png::EncodingError> {
    let mut out = Vec::new();
    let mut enc = png::Encoder::new(&mut out, img.width, img.height);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    let mut w = enc.write_header()?;
    w.write_image_data(&img.data)?;
    w.finish()?;
    Ok(out)
}

/// Reads and decodes the PNG at `path` as 8-bit RGB ([`decode_rgb`]).
pub fn read(path: &Path) -> Result<RgbImage> {
    let bytes = crate::fs::read(path, crate::fs::Limit::Data)?;
    decode_rgb(&bytes, path)
}

/// The size of the PNG image at `path`, from its header alone.
pub fn dimensions(path: &Path) -> Result<(u32, u32)> {
    let (file, _) = crate::fs::open(path)?;
    let decoder = png::Decoder::new(std::io::BufReader::new(file));
    let reader = decoder.read_info().map_err(|source| Error::Image {
        path: path.into(),
        source,
    })?;
    let info = reader.info();
    Ok((info.width, info.height))
}

/// Decodes PNG bytes as 8-bit RGB: RGB kept, RGBA's alpha dropped, a palette expanded; a grey or
/// 16-bit image is refused (naming its colour type: colour from it would be wrong). `path`
/// names the file in errors.
pub fn decode_rgb(bytes: &[u8], path: &Path) -> Result<RgbImage> {
    let err = |source| Error::Image {
        path: path.into(),
        source,
    };
    let mut decoder = png::Decoder::new(std::io::Cursor::new(bytes));
    decoder.set_transformations(png::Transformations::EXPAND);
    let mut reader = decoder.read_info().map_err(err)?;
    let (color, depth) = reader.output_color_type();
    let kind = match (color, depth) {
        (png::ColorType::Rgb, png::BitDepth::Eight) => 3,
        (png::ColorType::Rgba, png::BitDepth::Eight) => 4,
        _ => {
            return Err(Error::format(
                path,
                format!(
                    "a {color:?}{} image; colour needs 8-bit RGB (the colour cameras' PNGs; a grey \
                     image is camera 0 or 1's)",
                    depth as u8
                ),
            ))
        }
    };
    let size = reader
        .output_buffer_size()
        .ok_or_else(|| Error::format(path, "an image too large to decode"))?;
    let mut buf = vec![0; size];
    let info = reader.next_frame(&mut buf).map_err(err)?;
    buf.truncate(info.buffer_size());
    let data = if kind == 3 {
        buf
    } else {
        buf.chunks_exact(4)
            .flat_map(|p| [p[0], p[1], p[2]])
            .collect()
    };
    RgbImage::from_raw(info.width, info.height, data)
        .ok_or_else(|| Error::format(path, "decoded data of another size than the header's"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_image_round_trips_through_png() {
        let mut img = RgbImage::from_pixel(5, 3, Rgb([1, 2, 3]));
        img.put_pixel(4, 2, Rgb([200, 100, 50]));
        let back = decode_rgb(&encode(&img).unwrap(), Path::new("x.png")).unwrap();
        assert_eq!(back, img);
        assert_eq!(back.get_pixel(4, 2), Rgb([200, 100, 50]));
        assert_eq!(back.pixels().count(), 15);
    }
}
