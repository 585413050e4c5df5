//! Interior orientation: pixel ↔ mm conversion and Brown distortion corrections (contract conventions).

use serde::{Deserialize, Serialize};

use crate::photogrammetry::error::EpochError;

/// A camera (interior orientation) of the upload form. Only `c_mm` is required.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields)]
pub struct CameraInput {
    /// Camera identifier referenced by images.
    #[cfg_attr(feature = "openapi", schema(pattern = "^[A-Za-z0-9._-]{1,64}$"))]
    pub id: String,
    /// Principal distance c in mm.
    #[cfg_attr(
        feature = "openapi",
        schema(exclusive_minimum = 0.0, maximum = 100_000.0)
    )]
    pub c_mm: f64,
    /// Estimate c (shorthand for `calibrate: ["c"]`).
    #[serde(default)]
    pub calibrate_c: bool,
    /// Names of the parameters to estimate: any of c, x0, y0, k1, k2, k3, p1, p2.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "openapi", schema(inline, value_type = Option<Vec<InteriorName>>))]
    pub calibrate: Option<Vec<String>>,
    /// Pixel size in mm (needed for pixel observations), at least [`MIN_PIXEL_SIZE_MM`].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "openapi", schema(minimum = 1e-4, maximum = 1.0))]
    pub pixel_size_mm: Option<f64>,
    /// Image width in pixels.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "openapi", schema(minimum = 1))]
    pub width_px: Option<u32>,
    /// Image height in pixels.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "openapi", schema(minimum = 1))]
    pub height_px: Option<u32>,
    /// Principal point offset x0 in mm.
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = -1000.0, maximum = 1000.0))]
    pub x0_mm: f64,
    /// Principal point offset y0 in mm.
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = -1000.0, maximum = 1000.0))]
    pub y0_mm: f64,
    /// Radial distortion k1 (mm⁻²).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = -1000.0, maximum = 1000.0))]
    pub k1: f64,
    /// Radial distortion k2 (mm⁻⁴).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = -1000.0, maximum = 1000.0))]
    pub k2: f64,
    /// Radial distortion k3 (mm⁻⁶).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = -1000.0, maximum = 1000.0))]
    pub k3: f64,
    /// Decentring distortion p1 (mm⁻¹).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = -1000.0, maximum = 1000.0))]
    pub p1: f64,
    /// Decentring distortion p2 (mm⁻¹).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = -1000.0, maximum = 1000.0))]
    pub p2: f64,
    /// A-priori standard deviation of one image coordinate in mm
    /// (default 0.5 px when the pixel size is known, else 0.002 mm), at least
    /// [`MIN_SIGMA_MM`].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "openapi", schema(minimum = 1e-6, maximum = 1000.0))]
    pub sigma_mm: Option<f64>,
}

/// The names `calibrate` accepts (documentation of the upload form's schema).
#[cfg(feature = "openapi")]
#[derive(utoipa::ToSchema)]
#[allow(dead_code, non_camel_case_types)]
enum InteriorName {
    c,
    x0,
    y0,
    k1,
    k2,
    k3,
    p1,
    p2,
}

/// Names of the interior parameters, in the order of [`Camera::params`].
pub const INTERIOR_NAMES: [&str; 8] = ["c", "x0", "y0", "k1", "k2", "k3", "p1", "p2"];
/// Index of c in [`Camera::params`].
pub const C: usize = 0;

/// A validated camera: interior parameters, which of them to estimate, pixel geometry, a-priori σ.
#[derive(Debug, Clone, PartialEq)]
pub struct Camera {
    /// Camera identifier.
    pub id: String,
    /// Interior parameters `[c, x0, y0, k1, k2, k3, p1, p2]`: c, x0, y0 in mm; k1 mm⁻², k2 mm⁻⁴,
    /// k3 mm⁻⁶, p1 and p2 mm⁻¹.
    pub params: [f64; 8],
    /// Which of `params` are estimated (self-calibration).
    pub calibrate: [bool; 8],
    /// Pixel size in mm, if known.
    pub pixel_size_mm: Option<f64>,
    /// Image size in pixels (width, height), if known.
    pub size_px: Option<(u32, u32)>,
    /// A-priori σ of one image coordinate in mm.
    pub sigma_mm: f64,
}

/// Smallest a-priori σ of an image coordinate in mm (1 nm, a thousandth of the smallest pixels'
/// centring precision): below it the weights (σ⁻²) leave the range the normal equations can be
/// solved in, and the adjustment failed with a misleading "singular" or did not converge.
pub const MIN_SIGMA_MM: f64 = 1e-6;

/// Smallest pixel size in mm (0.1 µm, a fifth of the smallest sensor pixels made): its default σ
/// (half a pixel) stays above [`MIN_SIGMA_MM`].
pub const MIN_PIXEL_SIZE_MM: f64 = 1e-4;

/// Default a-priori σ in mm when neither `sigma_mm` nor the pixel size is given.
pub const DEFAULT_SIGMA_MM: f64 = 0.002;

impl Camera {
    /// Validates a camera of the upload form.
    pub fn from_input(c: &CameraInput) -> Result<Self, EpochError> {
        let item = format!("camera '{}'", crate::contract::truncate_for_message(&c.id));
        let params = [c.c_mm, c.x0_mm, c.y0_mm, c.k1, c.k2, c.k3, c.p1, c.p2];
        for (v, name) in params.iter().zip(INTERIOR_NAMES) {
            if !v.is_finite() {
                return Err(EpochError::NotFinite {
                    item: item.clone(),
                    field: name.to_string(),
                });
            }
        }
        if !(c.c_mm > 0.0 && c.c_mm <= 1e5) {
            return Err(EpochError::OutOfRange {
                item,
                field: "c_mm".into(),
                reason: "must be positive and at most 100 m".into(),
            });
        }
        if params[1..].iter().any(|v| v.abs() > 1e3) {
            return Err(EpochError::OutOfRange {
                item,
                field: "x0_mm..p2".into(),
                reason: "principal point and distortion terms must be within ±1000".into(),
            });
        }
        let mut calibrate = [false; 8];
        calibrate[C] = c.calibrate_c;
        if let Some(list) = &c.calibrate {
            for name in list {
                let k = INTERIOR_NAMES
                    .iter()
                    .position(|n| n == name)
                    .ok_or_else(|| EpochError::OutOfRange {
                        item: item.clone(),
                        field: "calibrate".into(),
                        reason: format!(
                            "unknown parameter '{}' (c, x0, y0, k1, k2, k3, p1, p2)",
                            crate::contract::truncate_for_message(name)
                        ),
                    })?;
                calibrate[k] = true;
            }
        }
        let pixel_size_mm = match c.pixel_size_mm {
            Some(p) if !(p.is_finite() && (MIN_PIXEL_SIZE_MM..=1.0).contains(&p)) => {
                return Err(EpochError::OutOfRange {
                    item,
                    field: "pixel_size_mm".into(),
                    reason: format!("must be from {MIN_PIXEL_SIZE_MM} to 1 mm"),
                })
            }
            p => p,
        };
        let size_px = match (c.width_px, c.height_px) {
            (Some(w), Some(h)) if w > 0 && h > 0 => Some((w, h)),
            (None, None) => None,
            _ => {
                return Err(EpochError::OutOfRange {
                    item,
                    field: "width_px/height_px".into(),
                    reason: "give both, positive".into(),
                })
            }
        };
        let sigma_mm = match c.sigma_mm {
            Some(s) if !(s.is_finite() && (MIN_SIGMA_MM..=1e3).contains(&s)) => {
                return Err(EpochError::OutOfRange {
                    item,
                    field: "sigma_mm".into(),
                    reason: format!("must be from {MIN_SIGMA_MM} to 1000 mm"),
                })
            }
            Some(s) => s,
            None => pixel_size_mm.map_or(DEFAULT_SIGMA_MM, |p| 0.5 * p),
        };
        Ok(Camera {
            id: c.id.clone(),
            params,
            calibrate,
            pixel_size_mm,
            size_px,
            sigma_mm,
        })
    }

    /// Principal distance c in mm.
    pub fn c(&self) -> f64 {
        self.params[C]
    }

    /// Converts a pixel position (col, row; top-left pixel centre (0, 0), row down) to image mm
    /// (x right, y up, origin at the principal point): `x = (col − (w−1)/2)·px − x0`,
    /// `y = ((h−1)/2 − row)·px − y0`. None without pixel size and image size.
    ///
    /// The principal point offset is applied here only for the *fixed* x0, y0 of the upload form; the
    /// returned coordinates are relative to the image centre when x0, y0 are 0.
    pub fn pixel_to_mm(&self, col: f64, row: f64) -> Option<[f64; 2]> {
        let px = self.pixel_size_mm?;
        let (w, h) = self.size_px?;
        Some([
            (col - (w as f64 - 1.0) / 2.0) * px,
            ((h as f64 - 1.0) / 2.0 - row) * px,
        ])
    }

    /// Half the sensor's width and height in mm, when the camera gives its pixel size and image
    /// size.
    pub fn half_sensor_mm(&self) -> Option<[f64; 2]> {
        let px = self.pixel_size_mm?;
        let (w, h) = self.size_px?;
        Some([0.5 * w as f64 * px, 0.5 * h as f64 * px])
    }

    /// Inverse of [`Camera::pixel_to_mm`]: image mm (relative to the image centre) to (col, row).
    pub fn mm_to_pixel(&self, xy: [f64; 2]) -> Option<[f64; 2]> {
        let px = self.pixel_size_mm?;
        let (w, h) = self.size_px?;
        Some([
            xy[0] / px + (w as f64 - 1.0) / 2.0,
            (h as f64 - 1.0) / 2.0 - xy[1] / px,
        ])
    }
}

/// Brown correction of a measured image point (contract and Australis convention): with
/// x̄ = x − x0, ȳ = y − y0, r² = x̄² + ȳ²,
/// `x_c = x̄ + x̄(k1 r² + k2 r⁴ + k3 r⁶) + p1(r² + 2x̄²) + 2 p2 x̄ ȳ`,
/// `y_c = ȳ + ȳ(k1 r² + k2 r⁴ + k3 r⁶) + p2(r² + 2ȳ²) + 2 p1 x̄ ȳ`.
/// `params` is `[c, x0, y0, k1, k2, k3, p1, p2]`; input and output in mm. Generic so that the
/// adjustment can differentiate it.
pub fn brown_correct<T>(xy: [T; 2], params: &[T; 8]) -> [T; 2]
where
    T: Copy
        + std::ops::Add<Output = T>
        + std::ops::Sub<Output = T>
        + std::ops::Mul<Output = T>
        + From<f64>,
{
    let two = T::from(2.0);
    let xb = xy[0] - params[1];
    let yb = xy[1] - params[2];
    let r2 = xb * xb + yb * yb;
    let radial = params[3] * r2 + params[4] * r2 * r2 + params[5] * r2 * r2 * r2;
    [
        xb + xb * radial + params[6] * (r2 + two * xb * xb) + two * params[7] * xb * yb,
        yb + yb * radial + params[7] * (r2 + two * yb * yb) + two * params[6] * xb * yb,
    ]
}

/// Inverse of [`brown_correct`] by fixed-point iteration: the measured point whose corrected
/// position is `xy_c` (mm). Used to predict measurements from the projection equations.
pub fn brown_distort(xy_c: [f64; 2], params: &[f64; 8]) -> [f64; 2] {
    let mut xy = [xy_c[0] + params[1], xy_c[1] + params[2]];
    for _ in 0..50 {
        let c = brown_correct(xy, params);
        let dx = xy_c[0] - c[0];
        let dy = xy_c[1] - c[1];
        xy[0] += dx;
        xy[1] += dy;
        if dx.abs() + dy.abs() < 1e-13 {
            break;
        }
    }
    xy
}
