//! A downscaled, contrast-stretched JPEG of a station's image for the epoch page (pure: bytes in,
//! bytes out). The image is averaged over k × k pixel boxes, k the smallest integer that brings the
//! longer side to at most `max_side` px, and its grey levels are stretched linearly from the 0.5 %
//! quantile to the brightest level (targets cover far less than 0.1 % of a frame, so any lower
//! upper quantile would be background), so a dark telephoto frame stays readable. An 8-bit grey
//! or colour JPEG is decoded at a reduced scale (1/2, 1/4 or 1/8, from its DCT coefficients)
//! when the preview still gets at least three quarters of `max_side` px (or the image's own
//! size), so a 24-megapixel frame is not decoded in full for a 1280 px preview.

use image::codecs::jpeg::JpegEncoder;
use image::ExtendedColorType;

use cliffwatch_core::detect::decode::{decode_with_limit, luma, GreyImage};
use cliffwatch_core::detect::DetectError;

/// Longest side of a preview in px.
pub const PREVIEW_MAX_SIDE: u32 = 1280;

/// Largest image a preview is made of, in pixels (the detector's own limit).
const MAX_PIXELS: u64 = cliffwatch_core::detect::decode::DEFAULT_MAX_PIXELS;

/// A preview: JPEG bytes, its size in px and the box size k (1 preview px = k image px).
#[derive(Debug, Clone)]
pub struct Preview {
    /// JPEG bytes (grey, quality 85).
    pub jpeg: Vec<u8>,
    /// Width in px.
    pub width: u32,
    /// Height in px.
    pub height: u32,
    /// Image px per preview px.
    pub factor: u32,
}

/// Why no preview could be made.
#[derive(Debug, thiserror::Error)]
pub enum PreviewError {
    /// The bytes are not an image the detector reads.
    #[error("the image cannot be decoded: {0}")]
    Decode(#[from] DetectError),
    /// JPEG encoding failed.
    #[error("the preview cannot be encoded: {0}")]
    Encode(String),
}

/// The preview of JPEG/PNG/TIFF `bytes` (8- or 16-bit, grey or colour), longer side ≤ `max_side` px.
pub fn preview(bytes: &[u8], max_side: u32) -> Result<Preview, PreviewError> {
    let max_side = max_side.max(1);
    let (img, scale) = match scaled_jpeg(bytes, max_side) {
        Some(scaled) => scaled,
        None => (decode_with_limit(bytes, MAX_PIXELS)?, 1),
    };
    let (small, width, height, k) = box_downscale(&img, max_side);
    let factor = k * scale;
    let (lo, hi) = stretch_range(&small, 0.005);
    let span = (hi - lo).max(1.0);
    let grey: Vec<u8> = small
        .iter()
        .map(|&v| (((v - lo) / span) * 255.0).clamp(0.0, 255.0).round() as u8)
        .collect();
    let mut jpeg = Vec::new();
    JpegEncoder::new_with_quality(&mut jpeg, 85)
        .encode(&grey, width, height, ExtendedColorType::L8)
        .map_err(|e| PreviewError::Encode(e.to_string()))?;
    Ok(Preview {
        jpeg,
        width,
        height,
        factor,
    })
}

/// An 8-bit grey or colour JPEG decoded at the smallest DCT scale (1/2, 1/4, 1/8) after which
/// the boxes of [`box_downscale`] still give a longer side of at least three quarters of
/// `max_side` (or the image's own), as grey levels, with the scale's divisor (image px per
/// decoded px). None when no scale qualifies or for anything else (PNG, TIFF, 16-bit or CMYK
/// JPEG, an image above the pixel limit, a decoding error): the full decoder then reads it or
/// refuses it by name.
fn scaled_jpeg(bytes: &[u8], max_side: u32) -> Option<(GreyImage, u32)> {
    use jpeg_decoder::{Decoder, PixelFormat};
    if !bytes.starts_with(&[0xFF, 0xD8]) {
        return None;
    }
    let mut decoder = Decoder::new(bytes);
    decoder.read_info().ok()?;
    let info = decoder.info()?;
    let (w, h) = (u32::from(info.width), u32::from(info.height));
    if w == 0 || h == 0 || u64::from(w) * u64::from(h) > MAX_PIXELS {
        return None;
    }
    let longer = w.max(h);
    // The preview's longer side when the image is decoded at 1/s.
    let preview_side = |s: u32| {
        let side = longer.div_ceil(s);
        side.div_ceil(side.div_ceil(max_side))
    };
    let enough = longer.min(max_side * 3 / 4);
    let s = [8, 4, 2].into_iter().find(|&s| preview_side(s) >= enough)?;
    // The decoder picks the smallest scale that gives at least the size asked for: 1/s.
    let (sw, sh) = decoder
        .scale(w.div_ceil(s) as u16, h.div_ceil(s) as u16)
        .ok()?;
    let pixels = decoder.decode().ok()?;
    let (sw, sh) = (u32::from(sw), u32::from(sh));
    let grey: Vec<u16> = match info.pixel_format {
        PixelFormat::L8 => pixels.iter().map(|&v| u16::from(v)).collect(),
        PixelFormat::RGB24 => pixels
            .chunks_exact(3)
            .map(|p| luma(p[0], p[1], p[2]))
            .collect(),
        _ => return None,
    };
    Some((GreyImage::new(sw, sh, 8, grey).ok()?, s))
}

/// Box-averages `img` by the smallest integer k with max(w, h) / k ≤ `max_side` (the last partial
/// box of a row or column averages what it holds). Returns the levels, width, height and k.
fn box_downscale(img: &GreyImage, max_side: u32) -> (Vec<f64>, u32, u32, u32) {
    let (w, h) = (img.width(), img.height());
    let k = w.max(h).div_ceil(max_side).max(1);
    let (sw, sh) = (w.div_ceil(k), h.div_ceil(k));
    let mut sum = vec![0u64; (sw * sh) as usize];
    let mut count = vec![0u32; (sw * sh) as usize];
    for (row, line) in img.data().chunks_exact(w as usize).enumerate() {
        let base = row / k as usize * sw as usize;
        for (j, chunk) in line.chunks(k as usize).enumerate() {
            sum[base + j] += chunk.iter().map(|&v| u64::from(v)).sum::<u64>();
            count[base + j] += chunk.len() as u32;
        }
    }
    let levels = sum
        .iter()
        .zip(&count)
        .map(|(&s, &n)| s as f64 / n.max(1) as f64)
        .collect();
    (levels, sw, sh, k)
}

/// The `lo` quantile (a fraction) and the maximum of `v`, in linear time.
fn stretch_range(v: &[f64], lo: f64) -> (f64, f64) {
    if v.is_empty() {
        return (0.0, 1.0);
    }
    let mut s = v.to_vec();
    let k = ((s.len() - 1) as f64 * lo).round() as usize;
    let (_, low, _) = s.select_nth_unstable_by(k, f64::total_cmp);
    let low = *low;
    (low, v.iter().copied().fold(f64::NEG_INFINITY, f64::max))
}

#[cfg(test)]
mod tests {
    use super::*;
    use cliffwatch_sim::images::{encode_png, render, ImageSpec, TargetTruth};

    /// A 2160 × 1440 frame with one bright target: the preview is 1080 × 720 (k = 2), a JPEG, and
    /// the target's box is the brightest part of it, where the image has it.
    #[test]
    fn preview_keeps_the_target_where_it_is() {
        let mut spec = ImageSpec::new(2160, 1440, 8);
        spec.targets = vec![TargetTruth {
            col: 1500.0,
            row: 300.0,
            semi_major_px: 6.0,
            semi_minor_px: 6.0,
            angle_rad: 0.0,
            contrast: 120.0,
        }];
        let img = render(&spec, 7).unwrap().image;
        let p = preview(&encode_png(&img).unwrap(), PREVIEW_MAX_SIDE).unwrap();
        assert_eq!((p.width, p.height, p.factor), (1080, 720, 2));
        assert_eq!(&p.jpeg[..2], &[0xFF, 0xD8], "JPEG start of image");
        let back = image::load_from_memory(&p.jpeg).unwrap().to_luma8();
        assert_eq!(back.dimensions(), (1080, 720));
        // the centroid of the bright preview pixels is the target's centre halved
        let (mut n, mut sx, mut sy) = (0.0, 0.0, 0.0);
        for (x, y, px) in back.enumerate_pixels() {
            if px.0[0] > 200 {
                (n, sx, sy) = (n + 1.0, sx + x as f64, sy + y as f64);
            }
        }
        assert!((4.0..=60.0).contains(&n), "{n} bright preview px");
        let (dx, dy) = (sx / n - 749.75, sy / n - 149.75);
        assert!(
            dx.hypot(dy) <= 0.5,
            "bright preview px centred at ({dx}, {dy}) off"
        );
    }

    /// Small images are not enlarged; garbage is an error, not a panic.
    #[test]
    fn small_images_stay_and_garbage_is_refused() {
        let img = render(&ImageSpec::new(300, 200, 8), 1).unwrap().image;
        let p = preview(&encode_png(&img).unwrap(), PREVIEW_MAX_SIDE).unwrap();
        assert_eq!((p.width, p.height, p.factor), (300, 200, 1));
        assert!(matches!(
            preview(b"not an image", PREVIEW_MAX_SIDE),
            Err(PreviewError::Decode(_))
        ));
    }

    /// A JPEG big enough to be decoded at half scale gives the same preview as the full decode
    /// of the same frame (lossless PNG): the same size, the target in the same place, grey levels
    /// within a few steps.
    #[test]
    fn a_jpeg_decoded_at_half_scale_previews_like_the_full_image() {
        let mut spec = ImageSpec::new(2560, 1920, 8);
        spec.targets = vec![TargetTruth {
            col: 1800.0,
            row: 700.0,
            semi_major_px: 8.0,
            semi_minor_px: 8.0,
            angle_rad: 0.0,
            contrast: 120.0,
        }];
        let img = render(&spec, 3).unwrap().image;
        let grey: Vec<u8> = img.data().iter().map(|&v| v.min(255) as u8).collect();
        let mut jpeg = Vec::new();
        JpegEncoder::new_with_quality(&mut jpeg, 95)
            .encode(&grey, 2560, 1920, ExtendedColorType::L8)
            .unwrap();
        assert!(
            scaled_jpeg(&jpeg, PREVIEW_MAX_SIDE).is_some(),
            "the scaled path is taken"
        );
        let from_jpeg = preview(&jpeg, PREVIEW_MAX_SIDE).unwrap();
        let from_png = preview(&encode_png(&img).unwrap(), PREVIEW_MAX_SIDE).unwrap();
        let size = |p: &Preview| (p.width, p.height, p.factor);
        assert_eq!(size(&from_jpeg), (1280, 960, 2));
        assert_eq!(size(&from_jpeg), size(&from_png));
        let a = image::load_from_memory(&from_jpeg.jpeg).unwrap().to_luma8();
        let b = image::load_from_memory(&from_png.jpeg).unwrap().to_luma8();
        let diff: f64 = a
            .as_raw()
            .iter()
            .zip(b.as_raw())
            .map(|(&x, &y)| (f64::from(x) - f64::from(y)).abs())
            .sum::<f64>()
            / a.as_raw().len() as f64;
        assert!(diff < 3.0, "mean grey difference {diff}");
        let brightest = |g: &image::GrayImage| {
            let (mut best, mut at) = (0u8, (0, 0));
            for (x, y, p) in g.enumerate_pixels() {
                if p.0[0] > best {
                    (best, at) = (p.0[0], (x, y));
                }
            }
            at
        };
        let (pa, pb) = (brightest(&a), brightest(&b));
        assert!(
            pa.0.abs_diff(pb.0) <= 2 && pa.1.abs_diff(pb.1) <= 2,
            "{pa:?} {pb:?}"
        );
        assert!(pa.0.abs_diff(900) <= 5 && pa.1.abs_diff(350) <= 5, "{pa:?}");
    }
}
