//! The overlay of `cliffwatch detect --overlay DIR`: the image in grey with each target circled in
//! red and numbered (its index in the JSON line), written as JPEG.

use std::path::Path;

use cliffwatch_core::detect::{GreyImage, Target};
use image::{Rgb, RgbImage};

/// Digits 0–9 in a 3 × 5 bitmap, one row per 3 bits (most significant bit: left).
const DIGITS: [[u8; 5]; 10] = [
    [7, 5, 5, 5, 7],
    [2, 6, 2, 2, 7],
    [7, 1, 7, 4, 7],
    [7, 1, 7, 1, 7],
    [5, 5, 7, 1, 1],
    [7, 4, 7, 1, 7],
    [7, 4, 7, 5, 7],
    [7, 1, 1, 1, 1],
    [7, 5, 7, 5, 7],
    [7, 5, 7, 1, 7],
];

const RED: Rgb<u8> = Rgb([255, 40, 40]);

fn put(img: &mut RgbImage, x: i64, y: i64) {
    if x >= 0 && y >= 0 && (x as u32) < img.width() && (y as u32) < img.height() {
        img.put_pixel(x as u32, y as u32, RED);
    }
}

fn circle(img: &mut RgbImage, c: [f64; 2], r: f64) {
    let n = (2.0 * std::f64::consts::PI * r * 2.0).ceil().max(16.0) as usize;
    for k in 0..n {
        let a = k as f64 / n as f64 * std::f64::consts::TAU;
        for dr in [0.0, 1.0] {
            let (x, y) = (c[0] + (r + dr) * a.cos(), c[1] + (r + dr) * a.sin());
            put(img, x.round() as i64, y.round() as i64);
        }
    }
}

fn number(img: &mut RgbImage, x: i64, y: i64, n: usize, scale: i64) {
    for (k, ch) in n.to_string().bytes().enumerate() {
        let glyph = DIGITS[(ch - b'0') as usize];
        let ox = x + k as i64 * 4 * scale;
        for (row, bits) in glyph.iter().enumerate() {
            for col in 0..3 {
                if bits & (4 >> col) != 0 {
                    for dy in 0..scale {
                        for dx in 0..scale {
                            put(img, ox + col * scale + dx, y + row as i64 * scale + dy);
                        }
                    }
                }
            }
        }
    }
}

/// Writes `img` with `targets` circled and numbered to `path` (JPEG, quality 85).
pub fn write(img: &GreyImage, targets: &[Target], path: &Path) -> anyhow::Result<()> {
    let shift = if img.bit_depth() == 16 { 8 } else { 0 };
    let mut rgb = RgbImage::new(img.width(), img.height());
    for (p, &v) in rgb.pixels_mut().zip(img.data()) {
        let g = (v >> shift) as u8;
        *p = Rgb([g, g, g]);
    }
    let scale = (img.width().max(img.height()) as i64 / 1000).max(1);
    for (i, t) in targets.iter().enumerate() {
        let r = 0.5 * t.diameter_px + 3.0;
        circle(&mut rgb, [t.col, t.row], r);
        number(
            &mut rgb,
            (t.col + r + 2.0) as i64,
            (t.row - r - 2.0) as i64 - 5 * scale,
            i,
            scale,
        );
    }
    let file = std::io::BufWriter::new(std::fs::File::create(path)?);
    let enc = image::codecs::jpeg::JpegEncoder::new_with_quality(file, 85);
    rgb.write_with_encoder(enc)?;
    Ok(())
}
