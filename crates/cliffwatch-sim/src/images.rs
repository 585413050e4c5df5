//! Rendered target images with ground truth (pure, seeded): anti-aliased ellipses (supersampled
//! coverage), Gaussian blur, a gradient background, clutter (elongated glints, bright bands), Gaussian
//! noise, quantised to 8 or 16 bits. Coordinates follow the contract: the centre of the top-left pixel
//! is (0, 0), columns grow right, rows down; a pixel covers ±0.5 px around its centre.

use cliffwatch_core::detect::ellipse::normal_cdf;
use cliffwatch_core::detect::GreyImage;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// Largest image the renderer accepts (pixels).
pub const MAX_PIXELS: u64 = 100_000_000;

/// Why an image could not be rendered or encoded.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    /// A field of the [`ImageSpec`] is out of range.
    #[error("invalid image spec: {0}")]
    InvalidSpec(String),
    /// The encoder failed.
    #[error("cannot encode image: {0}")]
    Encode(String),
}

/// One target and its truth: an ellipse of uniform brightness.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TargetTruth {
    /// Centre column in px.
    pub col: f64,
    /// Centre row in px.
    pub row: f64,
    /// Semi-major axis in px.
    pub semi_major_px: f64,
    /// Semi-minor axis in px.
    pub semi_minor_px: f64,
    /// Angle of the major axis from the column axis toward the row axis, in radians.
    pub angle_rad: f64,
    /// Brightness above the background in grey levels (negative: dark target).
    pub contrast: f64,
}

impl TargetTruth {
    /// Equivalent diameter 2·√(a·b) in px.
    pub fn diameter_px(&self) -> f64 {
        2.0 * (self.semi_major_px * self.semi_minor_px).sqrt()
    }
}

/// Clutter that is not a target.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Clutter {
    /// An elongated specular glint: a capsule (rounded stroke) of `length_px` × `width_px`.
    Glint {
        /// Centre column in px.
        col: f64,
        /// Centre row in px.
        row: f64,
        /// Length in px (end to end).
        length_px: f64,
        /// Width in px.
        width_px: f64,
        /// Direction from the column axis in radians.
        angle_rad: f64,
        /// Brightness above the background in grey levels.
        contrast: f64,
    },
    /// A straight bright band crossing the whole image (a lit rock edge, a cable).
    Band {
        /// A point of the centre line, column in px.
        col: f64,
        /// A point of the centre line, row in px.
        row: f64,
        /// Direction from the column axis in radians.
        angle_rad: f64,
        /// Width in px.
        width_px: f64,
        /// Brightness above the background in grey levels.
        contrast: f64,
    },
}

/// Everything needed to render one image.
#[derive(Debug, Clone, PartialEq)]
pub struct ImageSpec {
    /// Width in px.
    pub width: u32,
    /// Height in px.
    pub height: u32,
    /// 8 or 16.
    pub bit_depth: u8,
    /// Background level at the image centre in grey levels.
    pub background: f64,
    /// Background gradient in grey levels per px along (col, row).
    pub gradient: [f64; 2],
    /// Gaussian blur σ in px (optics), applied to targets and glints.
    pub blur_sigma_px: f64,
    /// Noise σ in grey levels (Gaussian, independent per pixel).
    pub noise_sigma: f64,
    /// Subsamples per pixel side for the coverage of ellipses and glints (1..=32).
    pub supersample: u32,
    /// Targets.
    pub targets: Vec<TargetTruth>,
    /// Clutter.
    pub clutter: Vec<Clutter>,
}

impl ImageSpec {
    /// An empty scene like the shared reference images: background 40 (8-bit) or 40·257 (16-bit),
    /// a gradient of 0.01 grey levels per px per 8-bit level, blur 0.7 px, noise σ 3 (×257 at 16 bits),
    /// supersampling 16.
    pub fn new(width: u32, height: u32, bit_depth: u8) -> Self {
        let k = if bit_depth == 16 { 257.0 } else { 1.0 };
        Self {
            width,
            height,
            bit_depth,
            background: 40.0 * k,
            gradient: [0.01 * k, 0.006 * k],
            blur_sigma_px: 0.7,
            noise_sigma: 3.0 * k,
            supersample: 16,
            targets: Vec::new(),
            clutter: Vec::new(),
        }
    }
}

/// A rendered image and its targets' truth.
#[derive(Debug, Clone, PartialEq)]
pub struct Rendered {
    /// The image.
    pub image: GreyImage,
    /// The targets rendered (truth centres in px).
    pub targets: Vec<TargetTruth>,
}

fn finite_nonneg(v: f64) -> bool {
    v.is_finite() && v >= 0.0
}

fn validate(s: &ImageSpec) -> Result<(), RenderError> {
    let bad = |m: &str| Err(RenderError::InvalidSpec(m.to_string()));
    if s.width == 0 || s.height == 0 {
        return bad("zero size");
    }
    if s.width as u64 * s.height as u64 > MAX_PIXELS {
        return bad("more than MAX_PIXELS pixels");
    }
    if s.bit_depth != 8 && s.bit_depth != 16 {
        return bad("bit depth must be 8 or 16");
    }
    if !(finite_nonneg(s.blur_sigma_px) && s.blur_sigma_px <= 20.0) {
        return bad("blur σ must be in 0..=20 px");
    }
    if !(finite_nonneg(s.noise_sigma) && s.background.is_finite()) {
        return bad("noise and background must be finite, noise ≥ 0");
    }
    if !(s.gradient[0].is_finite() && s.gradient[1].is_finite()) {
        return bad("gradient must be finite");
    }
    if !(1..=32).contains(&s.supersample) {
        return bad("supersample must be 1..=32");
    }
    for t in &s.targets {
        let ok = t.col.is_finite()
            && t.row.is_finite()
            && t.angle_rad.is_finite()
            && t.contrast.is_finite()
            && t.semi_minor_px > 0.0
            && t.semi_major_px >= t.semi_minor_px
            && t.semi_major_px <= 1000.0;
        if !ok {
            return bad("target with non-finite field or axes not 0 < minor ≤ major ≤ 1000 px");
        }
    }
    for c in &s.clutter {
        let ok = match *c {
            Clutter::Glint {
                col,
                row,
                length_px,
                width_px,
                angle_rad,
                contrast,
            } => {
                col.is_finite()
                    && row.is_finite()
                    && angle_rad.is_finite()
                    && contrast.is_finite()
                    && width_px > 0.0
                    && length_px >= width_px
                    && length_px <= 2000.0
            }
            Clutter::Band {
                col,
                row,
                angle_rad,
                width_px,
                contrast,
            } => {
                col.is_finite()
                    && row.is_finite()
                    && angle_rad.is_finite()
                    && contrast.is_finite()
                    && width_px > 0.0
                    && width_px <= 1000.0
            }
        };
        if !ok {
            return bad("clutter with non-finite or out-of-range field");
        }
    }
    Ok(())
}

/// Discrete normalised Gaussian kernel of σ px (radius ⌈4σ⌉); [1] for σ = 0.
fn kernel(sigma: f64) -> Vec<f64> {
    if sigma < 1e-6 {
        return vec![1.0];
    }
    let r = (4.0 * sigma).ceil() as i64;
    let k: Vec<f64> = (-r..=r)
        .map(|i| (-(i * i) as f64 / (2.0 * sigma * sigma)).exp())
        .collect();
    let s: f64 = k.iter().sum();
    k.into_iter().map(|v| v / s).collect()
}

/// Adds `gain` × (blurred coverage of `inside`) over the bounding box `[c0, r0, c1, r1]` (px, grown
/// by the blur margin and clipped to the image).
#[allow(clippy::too_many_arguments)]
fn add_shape(
    buf: &mut [f32],
    w: usize,
    h: usize,
    bbox: [f64; 4],
    ss: u32,
    ker: &[f64],
    gain: f64,
    inside: impl Fn(f64, f64) -> bool,
) {
    let m = (ker.len() / 2) as i64 + 1;
    let x0 = (bbox[0].floor() as i64 - m).max(0);
    let y0 = (bbox[1].floor() as i64 - m).max(0);
    let x1 = (bbox[2].ceil() as i64 + m).min(w as i64 - 1);
    let y1 = (bbox[3].ceil() as i64 + m).min(h as i64 - 1);
    if x1 < x0 || y1 < y0 {
        return;
    }
    let (pw, ph) = ((x1 - x0 + 1) as usize, (y1 - y0 + 1) as usize);
    let mut cov = vec![0.0f64; pw * ph];
    let inv = 1.0 / ss as f64;
    let n = (ss * ss) as f64;
    for j in 0..ph {
        for i in 0..pw {
            let (px, py) = ((x0 + i as i64) as f64, (y0 + j as i64) as f64);
            let mut k = 0u32;
            for sy in 0..ss {
                let y = py - 0.5 + (sy as f64 + 0.5) * inv;
                for sx in 0..ss {
                    let x = px - 0.5 + (sx as f64 + 0.5) * inv;
                    if inside(x, y) {
                        k += 1;
                    }
                }
            }
            cov[j * pw + i] = k as f64 / n;
        }
    }
    // separable blur inside the patch (the margin holds the whole kernel of the shape)
    let r = (ker.len() / 2) as i64;
    let mut tmp = vec![0.0f64; pw * ph];
    for j in 0..ph {
        for i in 0..pw {
            let mut s = 0.0;
            for (t, kv) in ker.iter().enumerate() {
                let ii = i as i64 + t as i64 - r;
                if ii >= 0 && (ii as usize) < pw {
                    s += kv * cov[j * pw + ii as usize];
                }
            }
            tmp[j * pw + i] = s;
        }
    }
    for j in 0..ph {
        for i in 0..pw {
            let mut s = 0.0;
            for (t, kv) in ker.iter().enumerate() {
                let jj = j as i64 + t as i64 - r;
                if jj >= 0 && (jj as usize) < ph {
                    s += kv * tmp[jj as usize * pw + i];
                }
            }
            let idx = (y0 as usize + j) * w + x0 as usize + i;
            buf[idx] += (gain * s) as f32;
        }
    }
}

/// Renders `spec` with noise from the seed. Deterministic for a given spec and seed.
pub fn render(spec: &ImageSpec, seed: u64) -> Result<Rendered, RenderError> {
    validate(spec)?;
    let (w, h) = (spec.width as usize, spec.height as usize);
    let (cx, cy) = (0.5 * (w as f64 - 1.0), 0.5 * (h as f64 - 1.0));
    let mut buf = vec![0.0f32; w * h];
    for (y, line) in buf.chunks_mut(w).enumerate() {
        let base = spec.background + spec.gradient[1] * (y as f64 - cy);
        for (x, v) in line.iter_mut().enumerate() {
            *v = (base + spec.gradient[0] * (x as f64 - cx)) as f32;
        }
    }
    let ker = kernel(spec.blur_sigma_px);
    for t in &spec.targets {
        let (a, b) = (t.semi_major_px, t.semi_minor_px);
        let (c, s) = (t.angle_rad.cos(), t.angle_rad.sin());
        let e = a;
        add_shape(
            &mut buf,
            w,
            h,
            [t.col - e, t.row - e, t.col + e, t.row + e],
            spec.supersample,
            &ker,
            t.contrast,
            |x, y| {
                let (dx, dy) = (x - t.col, y - t.row);
                let (u, v) = (dx * c + dy * s, -dx * s + dy * c);
                (u / a).powi(2) + (v / b).powi(2) <= 1.0
            },
        );
    }
    // edge blur of straight bands: optics and pixel integration
    let s_band = (spec.blur_sigma_px.powi(2) + 1.0 / 12.0).sqrt();
    for cl in &spec.clutter {
        match *cl {
            Clutter::Glint {
                col,
                row,
                length_px,
                width_px,
                angle_rad,
                contrast,
            } => {
                let (c, s) = (angle_rad.cos(), angle_rad.sin());
                let half = 0.5 * (length_px - width_px);
                let rad = 0.5 * width_px;
                let e = 0.5 * length_px;
                add_shape(
                    &mut buf,
                    w,
                    h,
                    [col - e, row - e, col + e, row + e],
                    spec.supersample.min(8),
                    &ker,
                    contrast,
                    |x, y| {
                        let (dx, dy) = (x - col, y - row);
                        let u = (dx * c + dy * s).clamp(-half, half);
                        let (px, py) = (dx - u * c, dy - u * s);
                        px * px + py * py <= rad * rad
                    },
                );
            }
            Clutter::Band {
                col,
                row,
                angle_rad,
                width_px,
                contrast,
            } => {
                // signed distance from the centre line along its normal
                let (nx, ny) = (-angle_rad.sin(), angle_rad.cos());
                let hw = 0.5 * width_px;
                for (y, line) in buf.chunks_mut(w).enumerate() {
                    for (x, v) in line.iter_mut().enumerate() {
                        let d = (x as f64 - col) * nx + (y as f64 - row) * ny;
                        if d.abs() > hw + 6.0 * s_band {
                            continue;
                        }
                        let f = normal_cdf((hw - d) / s_band) - normal_cdf((-hw - d) / s_band);
                        *v += (contrast * f) as f32;
                    }
                }
            }
        }
    }
    let max = if spec.bit_depth == 16 { 65535.0 } else { 255.0 };
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let normal = Normal::new(0.0, spec.noise_sigma.max(0.0))
        .map_err(|e| RenderError::InvalidSpec(e.to_string()))?;
    let data: Vec<u16> = buf
        .iter()
        .map(|&v| {
            let n = if spec.noise_sigma > 0.0 {
                normal.sample(&mut rng)
            } else {
                0.0
            };
            (v as f64 + n).round().clamp(0.0, max) as u16
        })
        .collect();
    let image = GreyImage::new(spec.width, spec.height, spec.bit_depth, data)
        .map_err(|e| RenderError::InvalidSpec(e.to_string()))?;
    Ok(Rendered {
        image,
        targets: spec.targets.clone(),
    })
}

/// `n` targets of about `diameter_px` (± 5 %) and `contrast`, axis ratio up to `max_aspect`, at random
/// angles, on a jittered grid so that no two are closer than 3 diameters and none is within
/// 2 diameters + 8 px of the border. Fewer than `n` if the image is too small.
pub fn scatter_targets(
    width: u32,
    height: u32,
    n: usize,
    diameter_px: f64,
    contrast: f64,
    max_aspect: f64,
    seed: u64,
) -> Vec<TargetTruth> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x7a46_6574);
    if n == 0 || !(diameter_px > 0.0 && diameter_px.is_finite()) {
        return Vec::new();
    }
    let margin = 2.0 * diameter_px + 8.0;
    let (uw, uh) = (width as f64 - 2.0 * margin, height as f64 - 2.0 * margin);
    if uw <= 0.0 || uh <= 0.0 {
        return Vec::new();
    }
    // enough cells for n, but none narrower than 3 diameters + 2 px
    let min_cell = 3.0 * diameter_px + 2.0;
    let max_nx = ((uw / min_cell).floor() as usize).max(1);
    let max_ny = ((uh / min_cell).floor() as usize).max(1);
    let nx = ((n as f64 * uw / uh).sqrt().ceil() as usize).clamp(1, max_nx);
    let ny = n.div_ceil(nx).clamp(1, max_ny);
    let (cw, ch) = (uw / nx as f64, uh / ny as f64);
    let jit = (0.5 * (cw.min(ch) - 3.0 * diameter_px)).max(0.0);
    let max_aspect = if max_aspect.is_finite() {
        max_aspect.max(1.0)
    } else {
        1.0
    };
    let mut out = Vec::new();
    for j in 0..ny {
        for i in 0..nx {
            if out.len() >= n {
                return out;
            }
            let col = margin + (i as f64 + 0.5) * cw + rng.gen_range(-1.0..=1.0) * jit;
            let row = margin + (j as f64 + 0.5) * ch + rng.gen_range(-1.0..=1.0) * jit;
            let d = diameter_px * rng.gen_range(0.95..=1.05);
            let q: f64 = rng.gen_range(1.0..=max_aspect);
            let (a, b) = (0.5 * d * q.sqrt(), 0.5 * d / q.sqrt());
            out.push(TargetTruth {
                col,
                row,
                semi_major_px: a,
                semi_minor_px: b,
                angle_rad: rng.gen_range(0.0..std::f64::consts::PI),
                contrast,
            });
        }
    }
    out
}

/// Random clutter over a `width` × `height` image: `glints` elongated glints (length 10–40 px, axis
/// ratio 4–12) and `bands` straight bands (width 2–6 px), brightness 0.5–1.2 × `contrast`.
pub fn random_clutter(
    width: u32,
    height: u32,
    glints: usize,
    bands: usize,
    contrast: f64,
    seed: u64,
) -> Vec<Clutter> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x636c_7574);
    let (w, h) = (width as f64, height as f64);
    let mut out = Vec::with_capacity(glints + bands);
    for _ in 0..glints {
        let length_px = rng.gen_range(10.0..=40.0);
        let ratio: f64 = rng.gen_range(4.0..=12.0);
        out.push(Clutter::Glint {
            col: rng.gen_range(0.0..=w),
            row: rng.gen_range(0.0..=h),
            length_px,
            width_px: length_px / ratio,
            angle_rad: rng.gen_range(0.0..std::f64::consts::PI),
            contrast: contrast * rng.gen_range(0.5..=1.2),
        });
    }
    for _ in 0..bands {
        out.push(Clutter::Band {
            col: rng.gen_range(0.0..=w),
            row: rng.gen_range(0.0..=h),
            angle_rad: rng.gen_range(0.0..std::f64::consts::PI),
            width_px: rng.gen_range(2.0..=6.0),
            contrast: contrast * rng.gen_range(0.5..=1.2),
        });
    }
    out
}

fn to_dynamic(img: &GreyImage) -> Result<image::DynamicImage, RenderError> {
    let (w, h) = (img.width(), img.height());
    let size_err = || RenderError::Encode("buffer does not match the size".into());
    Ok(if img.bit_depth() == 16 {
        let b = image::ImageBuffer::<image::Luma<u16>, _>::from_raw(w, h, img.data().to_vec())
            .ok_or_else(size_err)?;
        image::DynamicImage::ImageLuma16(b)
    } else {
        let raw: Vec<u8> = img.data().iter().map(|&v| v.min(255) as u8).collect();
        let b =
            image::ImageBuffer::<image::Luma<u8>, _>::from_raw(w, h, raw).ok_or_else(size_err)?;
        image::DynamicImage::ImageLuma8(b)
    })
}

/// Encodes an image as PNG in memory (8- or 16-bit grey).
pub fn encode_png(img: &GreyImage) -> Result<Vec<u8>, RenderError> {
    let mut out = Vec::new();
    to_dynamic(img)?
        .write_to(&mut std::io::Cursor::new(&mut out), image::ImageFormat::Png)
        .map_err(|e| RenderError::Encode(e.to_string()))?;
    Ok(out)
}

/// Encodes an image as baseline JPEG in memory at `quality` (1–100); 16-bit images are reduced to
/// 8 bits (divided by 257).
pub fn encode_jpeg(img: &GreyImage, quality: u8) -> Result<Vec<u8>, RenderError> {
    let eight = if img.bit_depth() == 16 {
        let d: Vec<u16> = img.data().iter().map(|&v| v / 257).collect();
        GreyImage::new(img.width(), img.height(), 8, d)
            .map_err(|e| RenderError::Encode(e.to_string()))?
    } else {
        img.clone()
    };
    let mut out = Vec::new();
    let enc = image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, quality.clamp(1, 100));
    to_dynamic(&eight)?
        .write_with_encoder(enc)
        .map_err(|e| RenderError::Encode(e.to_string()))?;
    Ok(out)
}
