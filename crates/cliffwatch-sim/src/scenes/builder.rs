//! What every scene generator is built from: the truth, the scene errors and the parameter
//! checks, vector geometry, camera placement and projection, the seeded random streams, and the
//! upload form's pieces (observations, approximations, cameras, images).

use std::collections::BTreeMap;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use serde::{Deserialize, Serialize};
use thiserror::Error;

use cliffwatch_core::photogrammetry::adjust::result::AdjustedPoint;
use cliffwatch_core::photogrammetry::input::epoch::{
    ApproxInput, CameraInput, EpochInput, ImageInput, ObservationInput,
};
use cliffwatch_core::photogrammetry::model::camera::brown_distort;
use cliffwatch_core::photogrammetry::statistics::quality::{
    index3_rmse_mm, index4_rmse_mm, QualityError,
};

/// The true scene behind a simulated epoch (the form of the `*.truth.json` files `cliffwatch
/// simulate` writes).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Truth {
    /// True object coordinates in m (site frame), by point name.
    pub points: BTreeMap<String, [f64; 3]>,
    /// True exterior orientation by image id.
    pub cameras: BTreeMap<String, TruthCamera>,
    /// True principal distance in mm.
    pub c_mm: f64,
    /// True interior parameters `[c, x0, y0, k1, k2, k3, p1, p2]` (units of the upload form) when
    /// the scene has more than c (the calibration network).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub interior: Option<[f64; 8]>,
}

/// True exterior orientation of one image.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TruthCamera {
    /// Projection centre in m (site frame).
    #[serde(rename = "Xo")]
    pub xo: [f64; 3],
    /// Rotation (rows r1, r2, r3): camera coordinates are `R (X − Xo)`.
    #[serde(rename = "R")]
    pub r: [[f64; 3]; 3],
}

impl Truth {
    /// Adjusted and true coordinates (m) of the points present in both, in the order of `points`.
    pub fn pairs(&self, points: &[AdjustedPoint]) -> (Vec<[f64; 3]>, Vec<[f64; 3]>) {
        points
            .iter()
            .filter_map(|p| self.points.get(&p.name).map(|t| (p.xyz, *t)))
            .unzip()
    }

    /// Index 3 (mm, `[x, y, z, xyz]`) of adjusted points against this truth (similarity fit).
    pub fn index3_rmse_mm(&self, points: &[AdjustedPoint]) -> Result<[f64; 4], QualityError> {
        let (a, t) = self.pairs(points);
        index3_rmse_mm(&a, &t)
    }

    /// Index 4 (mm, `[x, y, z, xyz]`) of adjusted points against this truth (affine fit).
    pub fn index4_rmse_mm(&self, points: &[AdjustedPoint]) -> Result<[f64; 4], QualityError> {
        let (a, t) = self.pairs(points);
        index4_rmse_mm(&a, &t)
    }

    /// The true coordinates in the form of the upload's `approx` list.
    pub fn as_approx(&self) -> Vec<ApproxInput> {
        self.points
            .iter()
            .map(|(name, p)| ApproxInput {
                point: name.clone(),
                X: p[0],
                Y: p[1],
                Z: p[2],
            })
            .collect()
    }
}

/// The same epoch with the true coordinates as approximations (the start of the rigorous optimum).
/// Control points are kept as they are.
pub fn with_true_approx(input: &EpochInput, truth: &Truth) -> EpochInput {
    let mut out = input.clone();
    out.approx = truth.as_approx();
    out
}

/// A scene could not be generated or modified.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum SceneError {
    /// A parameter is out of its range.
    #[error("scene parameter {name}: {reason}")]
    BadParameter {
        /// Parameter name.
        name: &'static str,
        /// What is wrong.
        reason: String,
    },
    /// No image of that id.
    #[error("no image '{0}' in the epoch")]
    UnknownImage(String),
    /// The image does not observe that point.
    #[error("image '{image}' does not observe point '{point}'")]
    UnknownPoint {
        /// Image id.
        image: String,
        /// Point name.
        point: String,
    },
}

pub(super) fn bad(name: &'static str, reason: impl Into<String>) -> SceneError {
    SceneError::BadParameter {
        name,
        reason: reason.into(),
    }
}

pub(super) fn positive(name: &'static str, v: f64) -> Result<(), SceneError> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(bad(name, format!("must be a positive number, got {v}")))
    }
}

pub(super) fn non_negative(name: &'static str, v: f64) -> Result<(), SceneError> {
    if v.is_finite() && v >= 0.0 {
        Ok(())
    } else {
        Err(bad(name, format!("must be a non-negative number, got {v}")))
    }
}

// ---------------------------------------------------------------------------------------------
// Geometry helpers

pub(super) type V3 = [f64; 3];
pub(super) type M3 = [[f64; 3]; 3];

pub(super) fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
pub(super) fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
pub(super) fn cross(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
pub(super) fn normalize(a: V3) -> V3 {
    let n = dot(a, a).sqrt();
    [a[0] / n, a[1] / n, a[2] / n]
}
pub(super) fn mat_vec(m: &M3, v: V3) -> V3 {
    [dot(m[0], v), dot(m[1], v), dot(m[2], v)]
}
pub(super) fn mat_mul(a: &M3, b: &M3) -> M3 {
    let mut out = [[0.0; 3]; 3];
    for (i, row) in out.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = (0..3).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    out
}
pub(super) fn transpose(a: &M3) -> M3 {
    let mut out = [[0.0; 3]; 3];
    for (i, row) in out.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = a[j][i];
        }
    }
    out
}

/// Rotation of a camera at `xo` looking at `target`, image x axis perpendicular to `up`, image y
/// axis toward `up`: `r3 = (xo − target)/|…|`, `r1 = up × r3 /|…|`, `r2 = r3 × r1` (the shared
/// truth files use `up` = +Y).
pub fn look_at(xo: [f64; 3], target: [f64; 3], up: [f64; 3]) -> [[f64; 3]; 3] {
    let r3 = normalize(sub(xo, target));
    let r1 = normalize(cross(up, r3));
    let r2 = cross(r3, r1);
    [r1, r2, r3]
}

/// Rolls a camera about its axis by `angle_rad` (the image turns by −angle).
pub(super) fn roll(r: &M3, angle_rad: f64) -> M3 {
    let (s, c) = angle_rad.sin_cos();
    mat_mul(&[[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]], r)
}

/// Collinearity (eq 2) then Brown distortion: the measured image point (mm) of `x` for a camera at
/// `xo` with rotation `r` and interior `[c, x0, y0, k1, k2, k3, p1, p2]`. None behind the camera.
pub fn project(
    r: &[[f64; 3]; 3],
    xo: [f64; 3],
    interior: &[f64; 8],
    x: [f64; 3],
) -> Option<[f64; 2]> {
    let d = mat_vec(r, sub(x, xo));
    if d[2].is_nan() || d[2] >= 0.0 {
        return None;
    }
    let c = interior[0];
    let xc = [-c * d[0] / d[2], -c * d[1] / d[2]];
    Some(brown_distort(xc, interior))
}

pub(super) fn stream(seed: u64, purpose: u64) -> ChaCha8Rng {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(purpose);
    rng
}
pub(super) const GEOMETRY: u64 = 1;
pub(super) const NOISE: u64 = 2;
pub(super) const START: u64 = 3;

pub(super) fn gauss(rng: &mut ChaCha8Rng) -> f64 {
    rng.sample::<f64, _>(StandardNormal)
}

pub(super) fn timestamp(base_year: i32, seed: u64) -> String {
    use chrono::{Duration, TimeZone, Utc};
    let base = Utc
        .with_ymd_and_hms(base_year, 1, 1, 0, 0, 0)
        .single()
        .unwrap_or_default();
    (base + Duration::hours((seed % 1_000_000) as i64))
        .to_rfc3339_opts(chrono::SecondsFormat::Secs, true)
}

pub(super) fn mm_observation(point: &str, xy: [f64; 2]) -> ObservationInput {
    ObservationInput {
        point: point.to_string(),
        x_mm: Some(xy[0]),
        y_mm: Some(xy[1]),
        col: None,
        row: None,
        sigma_mm: None,
    }
}

pub(super) fn approx_list(
    names: &[String],
    truth: &[V3],
    skip: &[bool],
    sigma_m: f64,
    rng: &mut ChaCha8Rng,
) -> Vec<ApproxInput> {
    let mut out = Vec::new();
    for ((name, p), skip) in names.iter().zip(truth).zip(skip) {
        // Draw for every point, so that the stream does not depend on which points are skipped.
        let e = [gauss(rng), gauss(rng), gauss(rng)];
        if *skip {
            continue;
        }
        out.push(ApproxInput {
            point: name.clone(),
            X: p[0] + sigma_m * e[0],
            Y: p[1] + sigma_m * e[1],
            Z: p[2] + sigma_m * e[2],
        });
    }
    out
}

pub(super) fn plain_camera(
    id: &str,
    c_mm: f64,
    calibrate_c: bool,
    sigma_mm: Option<f64>,
) -> CameraInput {
    CameraInput {
        id: id.to_string(),
        c_mm,
        calibrate_c,
        calibrate: None,
        pixel_size_mm: None,
        width_px: None,
        height_px: None,
        x0_mm: 0.0,
        y0_mm: 0.0,
        k1: 0.0,
        k2: 0.0,
        k3: 0.0,
        p1: 0.0,
        p2: 0.0,
        sigma_mm,
    }
}

/// Adds image `id` (a station of its own, camera `cam`) with its observations to `images`, and its
/// true orientation to `truth`.
pub(super) fn add_image(
    truth: &mut Truth,
    images: &mut Vec<ImageInput>,
    id: &str,
    camera: TruthCamera,
    observations: Vec<ObservationInput>,
) {
    truth.cameras.insert(id.to_string(), camera);
    images.push(ImageInput {
        id: id.to_string(),
        camera: "cam".into(),
        station: Some(id.to_string()),
        observations,
    });
}
