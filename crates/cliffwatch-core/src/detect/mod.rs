//! Circular target detection and sub-pixel centring (pure: bytes in, targets out; no I/O).
//!
//! Pipeline: [`decode`](mod@decode) (JPEG/PNG/TIFF, 8/16-bit, grey/colour → grey) → [`threshold`] (robust
//! background grid, noise σ, runs above background + k·σ) → `components` (8-connected regions,
//! shape tests: area, aspect, fill) → `centroid` (plane background from an annulus, Gaussian-windowed
//! centroid iterated on the re-centred window) → for targets of ≥ 6 px, [`ellipse`] (least-squares fit of
//! a blurred-ellipse model started from the centroid) → [`Target`] (centre, size, contrast, quality,
//! [`CentreMethod`] used).

pub(crate) mod centroid;
pub(crate) mod components;
pub mod convergent;
pub mod decode;
pub mod dual_conic;
pub mod ellipse;
pub(crate) mod error;
pub mod first_epoch;
pub mod identify;
pub(crate) mod multiview;
pub(crate) mod naming;
pub(crate) mod re_pointing;
pub mod settings;
pub(crate) mod target;
pub mod threshold;

pub use decode::{decode, decode_with_limit, GreyImage, MAX_IMAGE_FILE_BYTES};
pub use error::DetectError;
pub use target::{CentreMethod, DetectOptions, DetectWarning, Polarity, Target, SIGMA_FLOOR_PX};

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
    /// The polarity of the targets reported (the one searched, or under automatic polarity the one
    /// that yielded more targets).
    pub polarity: Polarity,
    /// Candidate regions of that polarity that passed the shape tests (before centring).
    pub candidates: usize,
    /// What makes the result implausible, if anything (none, thousands of candidates, both
    /// polarities at once).
    pub warnings: Vec<DetectWarning>,
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
        && o.threshold_fraction > 0.0
        && o.threshold_fraction < 1.0
        && o.min_snr.is_finite()
        && !o.edge_fit_min_diameter_px.is_nan()
        && !o.dual_conic_min_diameter_px.is_nan()
        && o.max_aspect >= 1.0
        && o.fill_range.0 < o.fill_range.1
        && o.background_cell_px >= 8
        && o.sigma_floor_px.is_finite()
        && o.sigma_floor_px >= 0.0;
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

/// Candidates (blobs passing the shape tests) beyond which an image is reported as implausible
/// ([`DetectWarning::ManyCandidates`]): texture, print or noise rather than a target field.
pub const MANY_CANDIDATES: usize = 5_000;

/// Factor on the windowed centroid's propagated σ that makes it agree with the error against
/// truth on rendered images (rms of error/σ 2.25–2.3 without it at 3 px, `tests/detect/sigma.rs`):
/// the propagation takes the window as fixed, but the iteration re-centres it on the noise too.
pub const CENTROID_SIGMA_FACTOR: f64 = 2.27;

/// Factor on the dual-conic fit's noise-propagated σ ([`dual_conic::DualConicFit::sigma_unit`])
/// that makes it agree with the error against truth on rendered images (`tests/detect/sigma.rs`):
/// neighbouring pixels' gradients share pixels, which the propagation takes as independent.
pub const DUAL_CONIC_SIGMA_FACTOR: f64 = 3.0;

/// A centre's σ per coordinate (px): the centring's propagated σ and the floor, in quadrature.
fn with_floor(sigma: f64, floor: f64) -> f64 {
    sigma.hypot(floor)
}

/// Least width and height of an image searched, px: the smallest target with its background
/// ring (and the smallest background cell) needs 8 px; a smaller image is refused
/// ([`DetectError::TooSmall`]), not reported as holding no target.
pub const MIN_IMAGE_SIDE_PX: u32 = 8;

/// What one polarity's search gave.
struct Search {
    polarity: Polarity,
    targets: Vec<Target>,
    candidates: usize,
}

/// Detects and centres circular targets in a grey image. With `opts.polarity` `None` both
/// polarities are searched and the one with more targets is kept; the other's count is reported
/// in a warning when it is comparable (at least 10 and three quarters of the kept count:
/// [`DetectWarning::BothPolarities`]).
pub fn detect(img: &GreyImage, opts: &DetectOptions) -> Result<Detections, DetectError> {
    validate(opts)?;
    if img.width() < MIN_IMAGE_SIDE_PX || img.height() < MIN_IMAGE_SIDE_PX {
        return Err(DetectError::TooSmall {
            width: img.width(),
            height: img.height(),
            min: MIN_IMAGE_SIDE_PX,
        });
    }
    let t0 = Instant::now();
    let bg = threshold::estimate_background(img, opts.background_cell_px);
    // never closer to the background than the noise allows, nor than one grey level of 8-bit
    let level_unit = if img.bit_depth() == 16 { 257.0 } else { 1.0 };
    let min_offset = (opts.threshold_sigma * bg.noise).max(level_unit);
    let mut timings = StageTimings {
        threshold: t0.elapsed(),
        ..StageTimings::default()
    };
    let polarities: &[Polarity] = match opts.polarity {
        Some(Polarity::BrightOnDark) => &[Polarity::BrightOnDark],
        Some(Polarity::DarkOnBright) => &[Polarity::DarkOnBright],
        None => &[Polarity::BrightOnDark, Polarity::DarkOnBright],
    };
    let mut found: Vec<Search> = Vec::new();
    let mut refused: Vec<(Polarity, DetectError)> = Vec::new();
    for &p in polarities {
        match search(img, &bg, p, min_offset, opts, &mut timings) {
            Ok(s) => found.push(s),
            Err(e) => refused.push((p, e)),
        }
    }
    // most targets first; on a tie the bright polarity (listed first) stays first
    found.sort_by_key(|s| std::cmp::Reverse(s.targets.len()));
    let mut warnings = Vec::new();
    let mut it = found.into_iter();
    let best = match it.next() {
        Some(b) if !b.targets.is_empty() || refused.is_empty() => b,
        _ => return Err(refused.remove(0).1),
    };
    if let Some(other) = it.next() {
        let (n, m) = (best.targets.len(), other.targets.len());
        if m >= 10 && 4 * m >= 3 * n {
            warnings.push(DetectWarning::BothPolarities {
                kept: best.polarity,
                kept_targets: n,
                other_targets: m,
            });
        }
    }
    for (p, e) in &refused {
        warnings.push(DetectWarning::PolarityRefused {
            polarity: *p,
            reason: e.to_string(),
        });
    }
    if best.candidates > MANY_CANDIDATES {
        warnings.push(DetectWarning::ManyCandidates {
            candidates: best.candidates,
        });
    }
    if best.targets.is_empty() {
        warnings.push(DetectWarning::NoTargets);
    }
    Ok(Detections {
        width: img.width(),
        height: img.height(),
        bit_depth: img.bit_depth(),
        noise: bg.noise,
        polarity: best.polarity,
        candidates: best.candidates,
        warnings,
        targets: best.targets,
        timings,
    })
}

/// Threshold, components, shape tests and centring for one polarity.
fn search(
    img: &GreyImage,
    bg: &threshold::Background,
    polarity: Polarity,
    min_offset: f64,
    opts: &DetectOptions,
    timings: &mut StageTimings,
) -> Result<Search, DetectError> {
    let t0 = Instant::now();
    let levels = bg.levels(polarity, opts.threshold_fraction, min_offset);
    let runs = threshold::threshold_runs(img, &levels, polarity);
    let t1 = Instant::now();
    timings.threshold += t1 - t0;
    if runs.len() > MAX_RUNS {
        return Err(DetectError::TooManyBlobs {
            what: "runs",
            found: runs.len(),
            limit: MAX_RUNS,
        });
    }
    let comps = components::components(&runs);
    let max_area = std::f64::consts::FRAC_PI_4 * (opts.max_diameter_px + 4.0).powi(2) * 1.2;
    let (w, h) = (img.width(), img.height());
    let cands: Vec<_> = comps
        .into_iter()
        .filter(|c| {
            // a region touching the image border may be a cut target: its centre would be wrong
            let inside = c.bbox[0] > 0 && c.bbox[1] > 0 && c.bbox[2] + 1 < w && c.bbox[3] + 1 < h;
            inside
                && c.area >= 3.0
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
    timings.components += t2 - t1;
    let mut targets: Vec<Target> = cands
        .par_iter()
        .filter_map(|c| centre_one(img, bg.noise, polarity, c, opts))
        .collect();
    targets.sort_by(|a, b| {
        (a.row, a.col)
            .partial_cmp(&(b.row, b.col))
            .unwrap_or(std::cmp::Ordering::Equal)
    });
    timings.centring += t2.elapsed();
    Ok(Search {
        polarity,
        targets,
        candidates: cands.len(),
    })
}

/// Centres one candidate region and applies the final tests (contrast, size).
fn centre_one(
    img: &GreyImage,
    noise: f64,
    polarity: Polarity,
    c: &components::Component,
    opts: &DetectOptions,
) -> Option<Target> {
    let r = (c.area / std::f64::consts::PI).sqrt();
    if 2.0 * r >= opts.dual_conic_min_diameter_px {
        let region = dual_conic::Region {
            centre: [c.col, c.row],
            m2: c.m2,
        };
        let f = dual_conic::fit_dual_conic(img, &region)?;
        let k = DUAL_CONIC_SIGMA_FACTOR * noise;
        let sigma = [
            with_floor(k * f.sigma_unit[0], opts.sigma_floor_px),
            with_floor(k * f.sigma_unit[1], opts.sigma_floor_px),
        ];
        let r_fit = (f.semi_axes[0] * f.semi_axes[1]).sqrt();
        let contrast =
            dual_conic::contrast(img, polarity, f.centre, f.semi_axes[0], f.semi_axes[1]);
        let snr = contrast / noise;
        let ok = snr >= opts.min_snr
            && r_fit >= 0.7 * r
            && r_fit <= 1.4 * r
            && f.semi_axes[0] <= opts.max_aspect * 1.25 * f.semi_axes[1]
            && (f.centre[0] - c.col).hypot(f.centre[1] - c.row) <= 0.5 * r
            && 2.0 * r_fit >= opts.min_diameter_px * 0.5
            && 2.0 * r_fit <= opts.max_diameter_px * 1.5;
        return ok.then_some(Target {
            col: f.centre[0],
            row: f.centre[1],
            diameter_px: 2.0 * r_fit,
            contrast,
            snr,
            sigma_px: 0.5 * (sigma[0] + sigma[1]),
            sigma_col_px: sigma[0],
            sigma_row_px: sigma[1],
            aspect: c.aspect(),
            method: CentreMethod::DualConic,
        });
    }
    let sigma_w = (0.25 * r * r + 0.6).sqrt();
    let r_bg = (4.0 * sigma_w).max(r + 3.0) + 1.0;
    let ct = centroid::windowed_centroid(img, polarity, [c.col, c.row], sigma_w, r_bg)?;
    let snr = ct.peak / noise;
    // The contrast test does not depend on the edge fit: a faint speck is refused before it
    // (on dbat-camcal the bright polarity's thousands of specks cost most of the time).
    if snr < opts.min_snr {
        return None;
    }
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
        CENTROID_SIGMA_FACTOR * ct.sigma_unit * noise,
    );
    if 2.0 * r >= opts.edge_fit_min_diameter_px {
        if let Some(e) = ellipse::fit_ellipse(img, polarity, ct.centre, r, r + 4.0 + 0.2 * r) {
            centre = e.centre;
            method = CentreMethod::EllipseFit;
            sigma_px = e.sigma_px;
            diameter = 2.0 * (e.semi_axes[0] * e.semi_axes[1]).sqrt();
        }
    }
    let sigma_px = with_floor(sigma_px, opts.sigma_floor_px);
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
            sigma_col_px: sigma_px,
            sigma_row_px: sigma_px,
            aspect: c.aspect(),
            method,
        })
}
