//! Circular target detection and sub-pixel centring (pure: bytes in, targets out; no I/O).
//!
//! Pipeline: [`decode`] (JPEG/PNG/TIFF, 8/16-bit, grey/colour → grey) → [`threshold`] (robust
//! background grid, noise σ, runs above background + k·σ) → [`components`] (8-connected regions,
//! shape tests: area, aspect, fill) → [`centroid`] (plane background from an annulus, Gaussian-windowed
//! centroid iterated on the re-centred window) → for targets of ≥ 6 px, [`ellipse`] (least-squares fit of
//! a blurred-ellipse model started from the centroid) → [`Target`] (centre, size, contrast, quality,
//! [`CentreMethod`] used).

pub(crate) mod centroid;
pub(crate) mod components;
pub(crate) mod decode;
pub(crate) mod ellipse;
pub(crate) mod error;
pub mod first_epoch;
pub mod identify;
pub(crate) mod multiview;
pub(crate) mod naming;
pub(crate) mod re_pointing;
pub(crate) mod target;
pub mod threshold;

pub use decode::{decode, decode_with_limit, GreyImage, MAX_IMAGE_FILE_BYTES};
pub use error::DetectError;
pub use target::{CentreMethod, DetectOptions, Polarity, Target};

use rayon::prelude::*;
use std::time::{Duration, Instant};

/// Time spent in each stage of [`detect_bytes`].
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StageTimings {
    /// Decoding the bytes.
    pub decode: Duration,
    /// Background grid, noise and threshold runs.
    pub threshold: Duration,
    /// Connected components and shape tests.
    pub components: Duration,
    /// Sub-pixel centring and final tests.
    pub centring: Duration,
}

/// The targets of one image with the image's figures.
#[derive(Debug, Clone, PartialEq)]
pub struct Detections {
    /// Image width in px.
    pub width: u32,
    /// Image height in px.
    pub height: u32,
    /// Bit depth of the image (8 or 16).
    pub bit_depth: u8,
    /// Estimated noise σ in grey levels.
    pub noise: f64,
    /// Targets, ordered by row then column.
    pub targets: Vec<Target>,
    /// Time per stage.
    pub timings: StageTimings,
}

/// Decodes JPEG/PNG/TIFF bytes and detects targets.
pub fn detect_bytes(bytes: &[u8], opts: &DetectOptions) -> Result<Detections, DetectError> {
    let t0 = Instant::now();
    let img = decode(bytes)?;
    let dec = t0.elapsed();
    let mut d = detect(&img, opts)?;
    d.timings.decode = dec;
    Ok(d)
}

fn validate(o: &DetectOptions) -> Result<(), DetectError> {
    let ok = o.min_diameter_px.is_finite()
        && o.max_diameter_px.is_finite()
        && o.min_diameter_px > 0.0
        && o.max_diameter_px >= o.min_diameter_px
        && o.threshold_sigma.is_finite()
        && o.threshold_sigma > 0.0
        && o.min_snr.is_finite()
        && !o.edge_fit_min_diameter_px.is_nan()
        && o.max_aspect >= 1.0
        && o.fill_range.0 < o.fill_range.1
        && o.background_cell_px >= 8;
    if ok {
        Ok(())
    } else {
        Err(DetectError::InvalidOptions(format!("{o:?}")))
    }
}

/// Most row segments above the threshold an image may hold (a 6000 × 4000 photograph of 100
/// targets with clutter holds a few thousand): beyond, the connected components' memory would
/// grow to gigabytes on a crafted image.
pub const MAX_RUNS: usize = 2_000_000;

/// Most candidate blobs an image may hold: identification compares detections pairwise, so a
/// noise image of a million "targets" would hold the watcher for hours.
pub const MAX_BLOBS: usize = 20_000;

/// Detects and centres circular targets in a grey image.
pub fn detect(img: &GreyImage, opts: &DetectOptions) -> Result<Detections, DetectError> {
    validate(opts)?;
    let t0 = Instant::now();
    let bg = threshold::estimate_background(img, opts.background_cell_px);
    let runs = threshold::threshold_runs(img, &bg, opts.polarity, opts.threshold_sigma * bg.noise);
    let t1 = Instant::now();
    if runs.len() > MAX_RUNS {
        return Err(DetectError::TooManyBlobs {
            what: "runs",
            found: runs.len(),
            limit: MAX_RUNS,
        });
    }
    let comps = components::components(&runs);
    let max_area = std::f64::consts::FRAC_PI_4 * (opts.max_diameter_px + 4.0).powi(2) * 1.2;
    let cands: Vec<_> = comps
        .into_iter()
        .filter(|c| {
            c.area >= 3.0
                && c.area <= max_area
                && c.aspect() <= opts.max_aspect
                && (c.area < 12.0
                    || (c.fill() >= opts.fill_range.0 && c.fill() <= opts.fill_range.1))
        })
        .collect();
    if cands.len() > MAX_BLOBS {
        return Err(DetectError::TooManyBlobs {
            what: "blobs",
            found: cands.len(),
            limit: MAX_BLOBS,
        });
    }
    let t2 = Instant::now();
    let mut targets: Vec<Target> = cands
        .par_iter()
        .filter_map(|c| {
            let r = (c.area / std::f64::consts::PI).sqrt();
            let sigma_w = (0.25 * r * r + 0.6).sqrt();
            let r_bg = (4.0 * sigma_w).max(r + 3.0) + 1.0;
            let ct =
                centroid::windowed_centroid(img, opts.polarity, [c.col, c.row], sigma_w, r_bg)?;
            let snr = ct.peak / bg.noise;
            // signal second moment through a Gaussian window of σw: 1/m = 1/m_true + 1/σw²
            let m_true = if ct.m2 < sigma_w * sigma_w * 0.999 {
                1.0 / (1.0 / ct.m2 - 1.0 / (sigma_w * sigma_w))
            } else {
                ct.m2
            };
            let mut diameter = 4.0 * m_true.max(0.0).sqrt();
            let (mut centre, mut method, mut sigma_px) = (
                ct.centre,
                CentreMethod::WindowedCentroid,
                ct.sigma_unit * bg.noise,
            );
            if 2.0 * r >= opts.edge_fit_min_diameter_px {
                if let Some(e) =
                    ellipse::fit_ellipse(img, opts.polarity, ct.centre, r, r + 4.0 + 0.2 * r)
                {
                    centre = e.centre;
                    method = CentreMethod::EllipseFit;
                    sigma_px = e.sigma_px;
                    diameter = 2.0 * (e.semi_axes[0] * e.semi_axes[1]).sqrt();
                }
            }
            (snr >= opts.min_snr
                && diameter >= opts.min_diameter_px * 0.5
                && diameter <= opts.max_diameter_px * 1.5)
                .then_some(Target {
                    col: centre[0],
                    row: centre[1],
                    diameter_px: diameter,
                    contrast: ct.peak,
                    snr,
                    sigma_px,
                    aspect: c.aspect(),
                    method,
                })
        })
        .collect();
    targets.sort_by(|a, b| {
        (a.row, a.col)
            .partial_cmp(&(b.row, b.col))
            .unwrap_or(std::cmp::Ordering::Equal)
    });
    let t3 = Instant::now();
    Ok(Detections {
        width: img.width(),
        height: img.height(),
        bit_depth: img.bit_depth(),
        noise: bg.noise,
        targets,
        timings: StageTimings {
            decode: Duration::ZERO,
            threshold: t1 - t0,
            components: t2 - t1,
            centring: t3 - t2,
        },
    })
}
