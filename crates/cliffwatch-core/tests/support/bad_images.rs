//! Bad image files, made at run time (the list): a truncated JPEG, a 1-pixel image, a
//! 16-bit TIFF with an odd layout (big-endian, RGB in separate planes, strips of 5 rows, odd
//! width and height) and images beyond the limits (a PNG claiming 10¹⁰ pixels, a file above
//! `MAX_IMAGE_FILE_BYTES`, sparse so it costs no disk).

#![allow(dead_code)]

use std::path::Path;

use cliffwatch_core::detect::{GreyImage, MAX_IMAGE_FILE_BYTES};
use cliffwatch_sim::images::{encode_jpeg, encode_png};

/// CRC-32 (PNG) of `bytes`.
fn crc32(bytes: &[u8]) -> u32 {
    let mut c = 0xffff_ffffu32;
    for &b in bytes {
        c ^= b as u32;
        for _ in 0..8 {
            c = if c & 1 != 0 {
                0xedb8_8320 ^ (c >> 1)
            } else {
                c >> 1
            };
        }
    }
    !c
}

/// A valid small PNG whose header claims `w` × `h` pixels.
pub fn png_claiming(w: u32, h: u32) -> Vec<u8> {
    let img = GreyImage::new(4, 4, 8, vec![7; 16]).unwrap();
    let mut png = encode_png(&img).unwrap();
    // signature (8), IHDR length (4), "IHDR" (4), width, height, ...; CRC after the 13 data bytes
    png[16..20].copy_from_slice(&w.to_be_bytes());
    png[20..24].copy_from_slice(&h.to_be_bytes());
    let crc = crc32(&png[12..29]);
    png[29..33].copy_from_slice(&crc.to_be_bytes());
    png
}

/// `img` as a JPEG cut after 60 % of its bytes.
pub fn truncated_jpeg(img: &GreyImage) -> Vec<u8> {
    let jpeg = encode_jpeg(img, 90).unwrap();
    jpeg[..jpeg.len() * 6 / 10].to_vec()
}

/// A 1 × 1 grey PNG.
pub fn one_pixel_png() -> Vec<u8> {
    encode_png(&GreyImage::new(1, 1, 8, vec![128]).unwrap()).unwrap()
}

/// `img` (16-bit) as an uncompressed big-endian TIFF, 16-bit RGB with R = G = B in separate planes
/// (PlanarConfiguration 2), 5 rows per strip.
pub fn odd_tiff16(img: &GreyImage) -> Vec<u8> {
    assert_eq!(img.bit_depth(), 16);
    let (w, h) = (img.width(), img.height());
    let rows_per_strip = 5u32;
    let strips_per_plane = h.div_ceil(rows_per_strip);
    let mut out: Vec<u8> = b"MM\0\x2a\0\0\0\0".to_vec();
    let mut offsets = Vec::new();
    let mut counts = Vec::new();
    for _plane in 0..3 {
        for s in 0..strips_per_plane {
            offsets.push(out.len() as u32);
            let r0 = s * rows_per_strip;
            let r1 = (r0 + rows_per_strip).min(h);
            for r in r0..r1 {
                for c in 0..w {
                    out.extend_from_slice(&img.get(c as usize, r as usize).to_be_bytes());
                }
            }
            counts.push(out.len() as u32 - offsets.last().unwrap());
        }
    }
    let array = |out: &mut Vec<u8>, v: &[u32]| {
        let at = out.len() as u32;
        for x in v {
            out.extend_from_slice(&x.to_be_bytes());
        }
        at
    };
    let off_at = array(&mut out, &offsets);
    let cnt_at = array(&mut out, &counts);
    let bits_at = out.len() as u32;
    for _ in 0..3 {
        out.extend_from_slice(&16u16.to_be_bytes());
    }
    if out.len() % 2 == 1 {
        out.push(0);
    }
    let ifd = out.len() as u32;
    out[4..8].copy_from_slice(&ifd.to_be_bytes());
    let n = offsets.len() as u32;
    // (tag, type 3 SHORT / 4 LONG, count, value or offset)
    let entries: [(u16, u16, u32, u32); 10] = [
        (256, 4, 1, w),
        (257, 4, 1, h),
        (258, 3, 3, bits_at),
        (259, 3, 1, 1),
        (262, 3, 1, 2),
        (273, 4, n, off_at),
        (277, 3, 1, 3),
        (278, 4, 1, rows_per_strip),
        (279, 4, n, cnt_at),
        (284, 3, 1, 2),
    ];
    out.extend_from_slice(&(entries.len() as u16).to_be_bytes());
    for (tag, ty, count, value) in entries {
        out.extend_from_slice(&tag.to_be_bytes());
        out.extend_from_slice(&ty.to_be_bytes());
        out.extend_from_slice(&count.to_be_bytes());
        if ty == 3 && count == 1 {
            // a SHORT sits in the first two bytes of the value field
            out.extend_from_slice(&(value as u16).to_be_bytes());
            out.extend_from_slice(&[0, 0]);
        } else {
            out.extend_from_slice(&value.to_be_bytes());
        }
    }
    out.extend_from_slice(&0u32.to_be_bytes());
    out
}

/// Makes `path` a sparse file one byte above [`MAX_IMAGE_FILE_BYTES`].
pub fn giant_file(path: &Path) {
    let f = std::fs::File::create(path).unwrap();
    f.set_len(MAX_IMAGE_FILE_BYTES + 1).unwrap();
}
