//! Decoding JPEG, PNG and TIFF bytes (8/16-bit, grey or colour) into a grey plane.

use super::error::DetectError;
use image::{DynamicImage, ImageReader};
use rayon::prelude::*;
use std::io::Cursor;

/// Default limit on the pixel count of a decoded image (250 megapixels).
pub const DEFAULT_MAX_PIXELS: u64 = 250_000_000;

/// Largest image file read (bytes, 512 MiB: a 16-bit colour TIFF of 60 megapixels is 360 MB).
/// A file is read whole before decoding; a larger one is refused (the daemon reads image files
/// through its watched directory's `image_file`).
pub const MAX_IMAGE_FILE_BYTES: u64 = 512 << 20;

/// A grey image: row-major grey levels (0..=255 for 8-bit, 0..=65535 for 16-bit).
#[derive(Debug, Clone, PartialEq)]
pub struct GreyImage {
    width: u32,
    height: u32,
    bit_depth: u8,
    data: Vec<u16>,
}

impl GreyImage {
    /// Wraps a row-major buffer of grey levels; `bit_depth` is 8 or 16 (the range of the levels).
    pub fn new(
        width: u32,
        height: u32,
        bit_depth: u8,
        data: Vec<u16>,
    ) -> Result<Self, DetectError> {
        if width == 0 || height == 0 {
            return Err(DetectError::Empty { width, height });
        }
        if data.len() as u64 != width as u64 * height as u64 {
            return Err(DetectError::BadBuffer {
                len: data.len(),
                width,
                height,
            });
        }
        if bit_depth != 8 && bit_depth != 16 {
            return Err(DetectError::InvalidOptions(format!(
                "bit depth {bit_depth} (8 or 16)"
            )));
        }
        Ok(Self {
            width,
            height,
            bit_depth,
            data,
        })
    }
    /// Width in pixels.
    pub fn width(&self) -> u32 {
        self.width
    }
    /// Height in pixels.
    pub fn height(&self) -> u32 {
        self.height
    }
    /// Bit depth of the source (8 or 16).
    pub fn bit_depth(&self) -> u8 {
        self.bit_depth
    }
    /// Row-major grey levels.
    pub fn data(&self) -> &[u16] {
        &self.data
    }
    /// Grey level at (col, row); no bounds check beyond the slice's.
    #[inline]
    pub fn get(&self, col: usize, row: usize) -> u16 {
        self.data[row * self.width as usize + col]
    }
}

/// Decodes JPEG, PNG or TIFF bytes to a grey image, at most [`DEFAULT_MAX_PIXELS`] pixels.
pub fn decode(bytes: &[u8]) -> Result<GreyImage, DetectError> {
    decode_with_limit(bytes, DEFAULT_MAX_PIXELS)
}

/// Decodes JPEG, PNG or TIFF bytes to a grey image of at most `max_pixels` pixels. Colour becomes
/// luma (Rec. 601 weights); 8-bit stays 0..=255, 16-bit 0..=65535, float images scale to 16-bit.
pub fn decode_with_limit(bytes: &[u8], max_pixels: u64) -> Result<GreyImage, DetectError> {
    let reader = ImageReader::new(Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|e| DetectError::Decode(e.to_string()))?;
    let (width, height) = reader
        .into_dimensions()
        .map_err(|e| DetectError::Decode(e.to_string()))?;
    if width == 0 || height == 0 {
        return Err(DetectError::Empty { width, height });
    }
    if width as u64 * height as u64 > max_pixels {
        return Err(DetectError::TooLarge {
            width,
            height,
            max_pixels,
        });
    }
    let mut reader = ImageReader::new(Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|e| DetectError::Decode(e.to_string()))?;
    if reader.format() == Some(image::ImageFormat::Jpeg) && !jpeg_is_complete(bytes) {
        return Err(DetectError::Truncated { format: "JPEG" });
    }
    if reader.format() == Some(image::ImageFormat::Jpeg) {
        if let Some(grey) = jpeg_luma(bytes, width, height) {
            return Ok(grey);
        }
    }
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(width);
    limits.max_image_height = Some(height);
    limits.max_alloc = Some(max_pixels.saturating_mul(16));
    reader.limits(limits);
    let img = reader
        .decode()
        .map_err(|e| DetectError::Decode(e.to_string()))?;
    from_dynamic(img)
}

/// A JPEG's luma straight from the decoder (zune-jpeg with a luma output: a YCbCr image's Y
/// channel, Rec. 601 luma by the JFIF definition, without colour conversion), when it decodes to
/// `width` × `height` grey pixels; `None` sends the image through the general path (CMYK, or
/// anything this path does not take).
fn jpeg_luma(bytes: &[u8], width: u32, height: u32) -> Option<GreyImage> {
    use zune_core::colorspace::ColorSpace;
    use zune_core::options::DecoderOptions;
    let options = DecoderOptions::default()
        .jpeg_set_out_colorspace(ColorSpace::Luma)
        .set_max_width(width as usize)
        .set_max_height(height as usize);
    let mut decoder = zune_jpeg::JpegDecoder::new_with_options(
        zune_core::bytestream::ZCursor::new(bytes),
        options,
    );
    decoder.decode_headers().ok()?;
    if decoder.output_colorspace()? != ColorSpace::Luma {
        return None;
    }
    let luma = decoder.decode().ok()?;
    if luma.len() as u64 != width as u64 * height as u64 {
        return None;
    }
    GreyImage::new(
        width,
        height,
        8,
        luma.par_iter().map(|&v| u16::from(v)).collect(),
    )
    .ok()
}

/// Whether JPEG `bytes` reach their end-of-image marker: the marker segments are followed from
/// the start (their lengths skip embedded thumbnails), and each scan's entropy-coded data up to the
/// next marker (within it 0xFF is followed by 0x00 or a restart marker 0xD0–0xD7 only).
fn jpeg_is_complete(bytes: &[u8]) -> bool {
    let n = bytes.len();
    let mut i = 2; // after SOI
    while i + 1 < n {
        if bytes[i] != 0xFF {
            return false;
        }
        let m = bytes[i + 1];
        match m {
            0xFF => i += 1, // fill byte
            0xD9 => return true,
            0xD0..=0xD7 | 0x01 => i += 2,
            _ => {
                if i + 3 >= n {
                    return false;
                }
                let len = usize::from(u16::from_be_bytes([bytes[i + 2], bytes[i + 3]]));
                i += 2 + len;
                if m == 0xDA {
                    // entropy-coded data up to the next marker
                    while i + 1 < n
                        && !(bytes[i] == 0xFF
                            && bytes[i + 1] != 0x00
                            && !(0xD0..=0xD7).contains(&bytes[i + 1]))
                    {
                        i += 1;
                    }
                }
            }
        }
    }
    false
}

fn from_dynamic(img: DynamicImage) -> Result<GreyImage, DetectError> {
    let (w, h) = (img.width(), img.height());
    let (depth, data): (u8, Vec<u16>) = match img {
        DynamicImage::ImageLuma8(b) => (8, b.as_raw().par_iter().map(|&v| u16::from(v)).collect()),
        DynamicImage::ImageLumaA8(b) => (8, b.pixels().map(|p| p.0[0] as u16).collect()),
        DynamicImage::ImageLuma16(b) => (16, b.into_raw()),
        DynamicImage::ImageLumaA16(b) => (16, b.pixels().map(|p| p.0[0]).collect()),
        DynamicImage::ImageRgb8(b) => (
            8,
            b.as_raw()
                .par_chunks_exact(3)
                .map(|p| luma(p[0], p[1], p[2]))
                .collect(),
        ),
        DynamicImage::ImageRgba8(b) => (
            8,
            b.pixels().map(|p| luma(p.0[0], p.0[1], p.0[2])).collect(),
        ),
        DynamicImage::ImageRgb16(b) => (
            16,
            b.pixels().map(|p| luma(p.0[0], p.0[1], p.0[2])).collect(),
        ),
        DynamicImage::ImageRgba16(b) => (
            16,
            b.pixels().map(|p| luma(p.0[0], p.0[1], p.0[2])).collect(),
        ),
        other => (16, other.to_luma16().into_raw()),
    };
    GreyImage::new(w, h, depth, data)
}

/// The Rec. 601 luma of an RGB triple, rounded (grey levels of the same depth).
#[inline]
pub fn luma<T: Into<u32>>(r: T, g: T, b: T) -> u16 {
    ((299 * r.into() + 587 * g.into() + 114 * b.into() + 500) / 1000) as u16
}
