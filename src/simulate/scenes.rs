//! Simulated epochs with known truth, deterministic by seed (`rand_chacha::ChaCha8Rng`).
//!
//! Every generator returns the epoch in the upload form ([`EpochInput`]) and its [`Truth`] (the form
//! of `shared/data/*.truth.json`). Conventions are those of `docs/orthogonal-projection.md`: object
//! coordinates in m, image coordinates in mm (x right, y up) or pixels, camera coordinates
//! `R (X − Xo)`, the camera looks along −r3, measured = `brown_distort(projected)`.
//!
//! Random draws come from separate ChaCha streams of one seed — geometry, image noise, start
//! errors — so changing the noise level leaves the geometry and the start errors as they were.
//!
//! Scenes:
//! - [`paper_table1`]: Ono & Hattori's Table 1 scene, cases 1–3 (the same geometry as the shared
//!   truth files; noise 0.001 mm; start errors σ 10 mm).
//! - [`long_range`]: a 5 m × 3 m cliff face 100–110 m from 5 stations along a 60 m base, 400 mm lens,
//!   in a frame with Z toward the cameras or in East-North-Up with UTM-sized coordinates; with
//!   [`LongRangeParams::flat`] the nearly flat face (5 cm relief).
//! - [`calibration`]: a wide-angle convergent network of a flat 7 × 7 target plate with strong
//!   distortion, four control points, for the central model with full self-calibration.
//! - [`large`]: big networks for benchmarks (20 × 500, 100 × 10 000).
//! - [`swap_labels`]: a blunder, two targets' labels swapped in one image.

use std::collections::BTreeMap;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::photogrammetry::adjust::result::AdjustedPoint;
use crate::photogrammetry::input::epoch::{
    ApproxInput, CameraInput, ControlInput, EpochInput, ImageInput, ObservationInput,
};
use crate::photogrammetry::model::camera::brown_distort;
use crate::photogrammetry::statistics::quality::{index3_rmse_mm, index4_rmse_mm, QualityError};

/// The true scene behind a simulated epoch (form of `shared/data/*.truth.json`).
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

fn bad(name: &'static str, reason: impl Into<String>) -> SceneError {
    SceneError::BadParameter {
        name,
        reason: reason.into(),
    }
}

fn positive(name: &'static str, v: f64) -> Result<(), SceneError> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(bad(name, format!("must be a positive number, got {v}")))
    }
}

fn non_negative(name: &'static str, v: f64) -> Result<(), SceneError> {
    if v.is_finite() && v >= 0.0 {
        Ok(())
    } else {
        Err(bad(name, format!("must be a non-negative number, got {v}")))
    }
}

// ---------------------------------------------------------------------------------------------
// Geometry helpers

type V3 = [f64; 3];
type M3 = [[f64; 3]; 3];

fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn cross(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
fn normalize(a: V3) -> V3 {
    let n = dot(a, a).sqrt();
    [a[0] / n, a[1] / n, a[2] / n]
}
fn mat_vec(m: &M3, v: V3) -> V3 {
    [dot(m[0], v), dot(m[1], v), dot(m[2], v)]
}
fn mat_mul(a: &M3, b: &M3) -> M3 {
    let mut out = [[0.0; 3]; 3];
    for (i, row) in out.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = (0..3).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    out
}
fn transpose(a: &M3) -> M3 {
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
fn roll(r: &M3, angle_rad: f64) -> M3 {
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

fn stream(seed: u64, purpose: u64) -> ChaCha8Rng {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(purpose);
    rng
}
const GEOMETRY: u64 = 1;
const NOISE: u64 = 2;
const START: u64 = 3;

fn gauss(rng: &mut ChaCha8Rng) -> f64 {
    rng.sample::<f64, _>(StandardNormal)
}

fn timestamp(base_year: i32, seed: u64) -> String {
    use chrono::{Duration, TimeZone, Utc};
    let base = Utc
        .with_ymd_and_hms(base_year, 1, 1, 0, 0, 0)
        .single()
        .unwrap_or_default();
    (base + Duration::hours((seed % 1_000_000) as i64))
        .to_rfc3339_opts(chrono::SecondsFormat::Secs, true)
}

fn mm_observation(point: &str, xy: [f64; 2]) -> ObservationInput {
    ObservationInput {
        point: point.to_string(),
        x_mm: Some(xy[0]),
        y_mm: Some(xy[1]),
        col: None,
        row: None,
    }
}

fn approx_list(
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

fn plain_camera(id: &str, c_mm: f64, calibrate_c: bool, sigma_mm: Option<f64>) -> CameraInput {
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

// ---------------------------------------------------------------------------------------------
// (a) The paper's Table 1 scene

/// Which of the paper's simulation cases (Table 1, §4).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PaperCase {
    /// Images A, B; c = 300 mm fixed.
    Case1,
    /// Images A, B, C; c = 300 mm fixed.
    #[default]
    Case2,
    /// Images A, B, C; c given as 290 mm and self-calibrated.
    Case3,
}

/// Parameters of [`paper_table1`].
#[derive(Debug, Clone, PartialEq)]
pub struct PaperParams {
    /// The case (images and c).
    pub case: PaperCase,
    /// Seed of the noise and start-error draws.
    pub seed: u64,
    /// σ of the image noise per coordinate in mm (paper: 0.001).
    pub noise_mm: f64,
    /// σ of the start errors of the approximate coordinates per coordinate in m (paper: 0.010).
    pub approx_sigma_m: f64,
    /// A-priori σ written into the camera (`sigma_mm`); None leaves the form's default (0.002 mm),
    /// as in the shared epochs.
    pub sigma_mm: Option<f64>,
}

impl Default for PaperParams {
    fn default() -> Self {
        PaperParams {
            case: PaperCase::Case2,
            seed: 101,
            noise_mm: 0.001,
            approx_sigma_m: 0.010,
            sigma_mm: None,
        }
    }
}

impl PaperParams {
    /// Default parameters for one case and seed.
    pub fn case(case: PaperCase, seed: u64) -> Self {
        PaperParams {
            case,
            seed,
            ..PaperParams::default()
        }
    }
}

/// True principal distance of the paper's scene in mm.
pub const PAPER_C_MM: f64 = 300.0;

/// The 12 points of the paper's Table 1 in m (X, Y, Z; Z toward the cameras).
pub const PAPER_POINTS: [[f64; 3]; 12] = [
    [-0.2, 0.8, 0.0],
    [-0.2, 0.5, 0.0],
    [-0.3, 0.1, 0.0],
    [-0.1, 0.7, 0.2],
    [-0.15, 0.35, 0.3],
    [0.1, 0.7, 0.0],
    [0.05, 0.45, 0.0],
    [0.25, 0.8, 0.35],
    [0.3, 0.55, 0.0],
    [0.25, 0.25, 0.25],
    [0.4, 0.8, 0.0],
    [0.4, 0.15, 0.0],
];

/// The paper's stations A, B, C in m; each looks at the centroid of the points with +Y up.
pub const PAPER_STATIONS: [(&str, [f64; 3]); 3] = [
    ("A", [-3.0, 0.5, 10.0]),
    ("B", [3.0, 0.4, 10.0]),
    ("C", [0.0, 0.4, 11.0]),
];

/// The paper's Table 1 scene (m): points 1–12, stations A, B (and C), c = 300 mm, image noise and
/// start errors per [`PaperParams`]. Observations in mm; every point gets an approximation.
pub fn paper_table1(params: &PaperParams) -> Result<(EpochInput, Truth), SceneError> {
    non_negative("noise_mm", params.noise_mm)?;
    non_negative("approx_sigma_m", params.approx_sigma_m)?;
    if let Some(s) = params.sigma_mm {
        positive("sigma_mm", s)?;
    }
    let names: Vec<String> = (1..=12).map(|i| i.to_string()).collect();
    let points: Vec<V3> = PAPER_POINTS.to_vec();
    let n = points.len() as f64;
    let centroid = [0, 1, 2].map(|k| points.iter().map(|p| p[k]).sum::<f64>() / n);
    let stations: &[(&str, V3)] = match params.case {
        PaperCase::Case1 => &PAPER_STATIONS[..2],
        _ => &PAPER_STATIONS[..],
    };
    let (c_given, calibrate) = match params.case {
        PaperCase::Case3 => (290.0, true),
        _ => (PAPER_C_MM, false),
    };
    let interior = [PAPER_C_MM, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];
    let mut noise = stream(params.seed, NOISE);
    let mut truth = Truth {
        points: names.iter().cloned().zip(points.iter().copied()).collect(),
        cameras: BTreeMap::new(),
        c_mm: PAPER_C_MM,
        interior: None,
    };
    let mut images = Vec::new();
    for (id, xo) in stations {
        let r = look_at(*xo, centroid, [0.0, 1.0, 0.0]);
        let mut observations = Vec::new();
        for (name, p) in names.iter().zip(&points) {
            let xy = project(&r, *xo, &interior, *p)
                .ok_or_else(|| bad("case", "a point behind a camera"))?;
            let e = [gauss(&mut noise), gauss(&mut noise)];
            observations.push(mm_observation(
                name,
                [
                    xy[0] + params.noise_mm * e[0],
                    xy[1] + params.noise_mm * e[1],
                ],
            ));
        }
        truth
            .cameras
            .insert(id.to_string(), TruthCamera { xo: *xo, r });
        images.push(ImageInput {
            id: id.to_string(),
            camera: "cam".into(),
            station: Some(id.to_string()),
            observations,
        });
    }
    let mut start = stream(params.seed, START);
    let approx = approx_list(
        &names,
        &points,
        &vec![false; names.len()],
        params.approx_sigma_m,
        &mut start,
    );
    let input = EpochInput {
        observed_at: timestamp(2000, params.seed),
        label: Some(format!(
            "paper Table 1 {:?} seed {}",
            params.case, params.seed
        )),
        cameras: vec![plain_camera("cam", c_given, calibrate, params.sigma_mm)],
        images,
        control: Vec::new(),
        approx,
    };
    Ok((input, truth))
}

// ---------------------------------------------------------------------------------------------
// (b, c) The long-range cliff and the nearly flat face

/// The frame the long-range scene is written in.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum SiteFrame {
    /// X along the face (right), Y up, Z out of the face toward the cameras; face near Z = 0.
    #[default]
    TowardCameras,
    /// East-North-Up with UTM-sized coordinates (E ≈ 500 000 m, N ≈ 3 900 000 m, U ≈ 200 m); the
    /// face normal points to the given azimuth (degrees from north, clockwise) and the cameras look
    /// horizontally. The image data are identical to the `TowardCameras` frame: only the object
    /// frame differs (a rigid motion), start errors included.
    Enu {
        /// Azimuth of the face normal (toward the cameras), degrees clockwise from north.
        azimuth_deg: f64,
    },
}

/// Two targets' labels swapped in one image (a blunder).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LabelSwap {
    /// Index of the image (0-based).
    pub image: usize,
    /// Index of the first target (0-based).
    pub a: usize,
    /// Index of the second target (0-based).
    pub b: usize,
}

impl Default for LabelSwap {
    /// Image 3 (S3), targets T101 and T121: about 4 m apart on the face, ≈ 1500 px in the image.
    fn default() -> Self {
        LabelSwap {
            image: 2,
            a: 0,
            b: 20,
        }
    }
}

/// Parameters of [`long_range`] (defaults: the long-range cliff of the spec).
#[derive(Debug, Clone, PartialEq)]
pub struct LongRangeParams {
    /// Seed of geometry, noise and start errors.
    pub seed: u64,
    /// Number of targets (laid out on a jittered grid).
    pub n_points: usize,
    /// Width of the face in m.
    pub face_width_m: f64,
    /// Height of the face in m.
    pub face_height_m: f64,
    /// Relief (range of depth toward the cameras) in m.
    pub relief_m: f64,
    /// Number of stations (one image each).
    pub n_stations: usize,
    /// Nearest station distance from the face in m.
    pub distance_min_m: f64,
    /// Farthest station distance from the face in m.
    pub distance_max_m: f64,
    /// Length of the base along which the stations stand, m.
    pub base_m: f64,
    /// True principal distance in mm.
    pub c_mm: f64,
    /// Relative error of the given c (c_given = c · (1 + c_error)).
    pub c_error: f64,
    /// Self-calibrate c.
    pub calibrate_c: bool,
    /// Pixel size in mm.
    pub pixel_size_mm: f64,
    /// Sensor width in pixels.
    pub width_px: u32,
    /// Sensor height in pixels.
    pub height_px: u32,
    /// σ of the image noise per coordinate in pixels.
    pub noise_px: f64,
    /// σ of the start errors per coordinate in m.
    pub approx_sigma_m: f64,
    /// The object frame.
    pub frame: SiteFrame,
    /// Write observations as pixels (`col`, `row`) rather than mm.
    pub pixel_observations: bool,
    /// An optional blunder.
    pub swap: Option<LabelSwap>,
}

impl Default for LongRangeParams {
    fn default() -> Self {
        LongRangeParams {
            seed: 1,
            n_points: 28,
            face_width_m: 5.0,
            face_height_m: 3.0,
            relief_m: 1.0,
            n_stations: 5,
            distance_min_m: 100.0,
            distance_max_m: 110.0,
            base_m: 60.0,
            c_mm: 400.0,
            c_error: 0.01,
            calibrate_c: true,
            pixel_size_mm: 0.0105,
            width_px: 2160,
            height_px: 1440,
            noise_px: 0.25,
            approx_sigma_m: 0.5,
            frame: SiteFrame::TowardCameras,
            pixel_observations: true,
            swap: None,
        }
    }
}

impl LongRangeParams {
    /// The same cliff in an East-North-Up frame with UTM-sized coordinates (face normal azimuth 35°).
    pub fn enu() -> Self {
        LongRangeParams {
            frame: SiteFrame::Enu { azimuth_deg: 35.0 },
            ..LongRangeParams::default()
        }
    }

    /// The nearly flat face: relief 5 cm over 5 m, otherwise the long-range defaults.
    pub fn flat() -> Self {
        LongRangeParams {
            relief_m: 0.05,
            ..LongRangeParams::default()
        }
    }

    /// The default scene with a blunder ([`LabelSwap::default`]).
    pub fn with_blunder() -> Self {
        LongRangeParams {
            swap: Some(LabelSwap::default()),
            ..LongRangeParams::default()
        }
    }
}

/// Origin of the ENU frame of the long-range scene (E, N, U in m).
pub const ENU_ORIGIN: [f64; 3] = [500_123.4, 3_900_456.7, 212.3];

/// The long-range cliff (and, with other parameters, the flat face): targets `T101…` on a
/// jittered grid over the face, relief uniform in `[0, relief]`, stations `S1…` evenly along the
/// base at random distances in `[min, max]` and heights within ±1 m of the face bottom, each
/// aimed at the face centre (±0.2 m) with +Y up. Targets outside a sensor are not observed.
/// Every target gets an approximation with start error σ `approx_sigma_m`.
pub fn long_range(params: &LongRangeParams) -> Result<(EpochInput, Truth), SceneError> {
    let p = params;
    p.check()?;
    let mut geo = stream(p.seed, GEOMETRY);
    let names: Vec<String> = (0..p.n_points).map(|i| format!("T{}", 101 + i)).collect();
    let points = face_targets(p, &mut geo);
    let stations = long_range_stations(p, &mut geo);
    let images = photograph(p, &stations, &names, &points);
    let mut start = stream(p.seed, START);
    let mut approx = approx_list(
        &names,
        &points,
        &vec![false; names.len()],
        p.approx_sigma_m,
        &mut start,
    );
    let mut camera = plain_camera(
        "cam",
        p.c_mm * (1.0 + p.c_error),
        p.calibrate_c,
        Some(p.noise_px.max(0.01) * p.pixel_size_mm),
    );
    camera.pixel_size_mm = Some(p.pixel_size_mm);
    camera.width_px = Some(p.width_px);
    camera.height_px = Some(p.height_px);

    // The object frame: a rigid motion of the local one (image data unchanged).
    let (rot, origin) = site_frame(p.frame);
    let to_site = |x: V3| -> V3 {
        let v = mat_vec(&rot, x);
        [v[0] + origin[0], v[1] + origin[1], v[2] + origin[2]]
    };
    let rot_t = transpose(&rot);
    for a in &mut approx {
        let v = to_site([a.X, a.Y, a.Z]);
        (a.X, a.Y, a.Z) = (v[0], v[1], v[2]);
    }
    let mut truth = Truth {
        points: names
            .iter()
            .cloned()
            .zip(points.iter().map(|x| to_site(*x)))
            .collect(),
        cameras: BTreeMap::new(),
        c_mm: p.c_mm,
        interior: None,
    };
    for (i, (xo, r)) in stations.iter().enumerate() {
        truth.cameras.insert(
            format!("S{}", i + 1),
            TruthCamera {
                xo: to_site(*xo),
                r: mat_mul(r, &rot_t),
            },
        );
    }
    let mut input = EpochInput {
        observed_at: timestamp(2026, p.seed),
        label: Some(format!("long-range cliff seed {}", p.seed)),
        cameras: vec![camera],
        images,
        control: Vec::new(),
        approx,
    };
    if let Some(s) = p.swap {
        let image = input.images[s.image].id.clone();
        swap_labels(&mut input, &image, &names[s.a], &names[s.b])?;
    }
    Ok((input, truth))
}

impl LongRangeParams {
    /// Checks every parameter; the error names the one at fault.
    fn check(&self) -> Result<(), SceneError> {
        let p = self;
        if p.n_points < 4 {
            return Err(bad("n_points", "at least 4"));
        }
        if p.n_stations < 2 {
            return Err(bad("n_stations", "at least 2"));
        }
        positive("face_width_m", p.face_width_m)?;
        positive("face_height_m", p.face_height_m)?;
        non_negative("relief_m", p.relief_m)?;
        positive("distance_min_m", p.distance_min_m)?;
        if p.distance_max_m.is_nan() || p.distance_max_m < p.distance_min_m {
            return Err(bad("distance_max_m", "must be ≥ distance_min_m"));
        }
        non_negative("base_m", p.base_m)?;
        positive("c_mm", p.c_mm)?;
        if !(p.c_error.is_finite() && p.c_error > -0.5 && p.c_error < 0.5) {
            return Err(bad("c_error", "must be within ±0.5"));
        }
        positive("pixel_size_mm", p.pixel_size_mm)?;
        if p.width_px == 0 || p.height_px == 0 {
            return Err(bad("width_px/height_px", "must be positive"));
        }
        non_negative("noise_px", p.noise_px)?;
        non_negative("approx_sigma_m", p.approx_sigma_m)?;
        if let SiteFrame::Enu { azimuth_deg } = p.frame {
            if !azimuth_deg.is_finite() {
                return Err(bad("azimuth_deg", "must be finite"));
            }
        }
        if let Some(s) = p.swap {
            if s.image >= p.n_stations || s.a >= p.n_points || s.b >= p.n_points || s.a == s.b {
                return Err(bad("swap", "image or targets out of range (or a == b)"));
            }
        }
        Ok(())
    }
}

/// The targets in the scene's local frame (m): a jittered grid with about the face's aspect
/// ratio, relief uniform in `[0, relief]`.
fn face_targets(p: &LongRangeParams, geo: &mut impl Rng) -> Vec<V3> {
    let cols = ((p.n_points as f64 * p.face_width_m / p.face_height_m)
        .sqrt()
        .ceil() as usize)
        .clamp(1, p.n_points);
    let rows = p.n_points.div_ceil(cols);
    let (dx, dy) = (p.face_width_m / cols as f64, p.face_height_m / rows as f64);
    (0..p.n_points)
        .map(|i| {
            let (c, r) = (i % cols, i / cols);
            let jx: f64 = geo.gen_range(-0.3..0.3);
            let jy: f64 = geo.gen_range(-0.3..0.3);
            let z: f64 = geo.gen_range(0.0..=1.0);
            [
                (c as f64 + 0.5 + jx) * dx - p.face_width_m / 2.0,
                (r as f64 + 0.5 + jy) * dy,
                z * p.relief_m,
            ]
        })
        .collect()
}

/// The stations (projection centre in m, rotation) evenly along the base at random distances,
/// heights within ±1 m of the face bottom, each aimed at the face centre (±0.2 m) with +Y up.
fn long_range_stations(p: &LongRangeParams, geo: &mut impl Rng) -> Vec<(V3, M3)> {
    let centre = [0.0, p.face_height_m / 2.0, p.relief_m / 2.0];
    (0..p.n_stations)
        .map(|i| {
            let x = -p.base_m / 2.0 + p.base_m * i as f64 / (p.n_stations - 1) as f64;
            let d: f64 = geo.gen_range(p.distance_min_m..=p.distance_max_m);
            let y: f64 = geo.gen_range(-1.0..=1.0);
            let aim = [
                centre[0] + geo.gen_range(-0.2..=0.2),
                centre[1] + geo.gen_range(-0.2..=0.2),
                centre[2],
            ];
            let xo = [x, y, d];
            (xo, look_at(xo, aim, [0.0, 1.0, 0.0]))
        })
        .collect()
}

/// One image per station (`S1…`): every target inside the sensor, with Gaussian noise of
/// `noise_px`, as pixels or mm as the parameters ask.
fn photograph(
    p: &LongRangeParams,
    stations: &[(V3, M3)],
    names: &[String],
    points: &[V3],
) -> Vec<ImageInput> {
    let interior = [p.c_mm, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];
    let half_w = p.width_px as f64 * p.pixel_size_mm / 2.0;
    let half_h = p.height_px as f64 * p.pixel_size_mm / 2.0;
    let (mid_col, mid_row) = (
        (p.width_px as f64 - 1.0) / 2.0,
        (p.height_px as f64 - 1.0) / 2.0,
    );
    let mut noise = stream(p.seed, NOISE);
    let mut images = Vec::new();
    for (i, (xo, r)) in stations.iter().enumerate() {
        let id = format!("S{}", i + 1);
        let mut observations = Vec::new();
        for (name, x) in names.iter().zip(points) {
            // Drawn for every target, seen or not, so that the noise does not depend on the view.
            let e = [gauss(&mut noise), gauss(&mut noise)];
            let Some(xy) = project(r, *xo, &interior, *x) else {
                continue;
            };
            if xy[0].abs() > half_w || xy[1].abs() > half_h {
                continue;
            }
            let col = xy[0] / p.pixel_size_mm + mid_col + p.noise_px * e[0];
            let row = mid_row - xy[1] / p.pixel_size_mm + p.noise_px * e[1];
            observations.push(if p.pixel_observations {
                ObservationInput {
                    point: name.clone(),
                    x_mm: None,
                    y_mm: None,
                    col: Some(col),
                    row: Some(row),
                }
            } else {
                mm_observation(
                    name,
                    [
                        (col - mid_col) * p.pixel_size_mm,
                        (mid_row - row) * p.pixel_size_mm,
                    ],
                )
            });
        }
        images.push(ImageInput {
            id: id.clone(),
            camera: "cam".into(),
            station: Some(id),
            observations,
        });
    }
    images
}

/// The rotation and origin taking the scene's local frame to the site frame:
/// `X_site = origin + R X_local`.
fn site_frame(frame: SiteFrame) -> (M3, V3) {
    match frame {
        SiteFrame::TowardCameras => (
            [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            [0.0; 3],
        ),
        SiteFrame::Enu { azimuth_deg } => {
            let (s, c) = azimuth_deg.to_radians().sin_cos();
            let n = [s, c, 0.0]; // face normal, horizontal
            let u = [0.0, 0.0, 1.0];
            let r = cross(u, n); // along the face, to the right seen from the cameras
                                 // Columns r, u, n: X_enu = origin + M X_local.
            (transpose(&[r, u, n]), ENU_ORIGIN)
        }
    }
}

/// Swaps the labels of two targets in one image (a blunder: each observation now carries the other
/// target's name).
pub fn swap_labels(
    input: &mut EpochInput,
    image: &str,
    a: &str,
    b: &str,
) -> Result<(), SceneError> {
    let im = input
        .images
        .iter_mut()
        .find(|i| i.id == image)
        .ok_or_else(|| SceneError::UnknownImage(image.to_string()))?;
    let find = |name: &str, im: &ImageInput| {
        im.observations
            .iter()
            .position(|o| o.point == name)
            .ok_or_else(|| SceneError::UnknownPoint {
                image: image.to_string(),
                point: name.to_string(),
            })
    };
    let ia = find(a, im)?;
    let ib = find(b, im)?;
    im.observations[ia].point = b.to_string();
    im.observations[ib].point = a.to_string();
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// (d) Wide-angle calibration network

/// Parameters of [`calibration`] (defaults: 20 convergent images of a 7 × 7 plate, 24 mm lens on a
/// 36 × 24 mm sensor, ≈ 0.3 mm radial distortion at the corner).
#[derive(Debug, Clone, PartialEq)]
pub struct CalibrationParams {
    /// Seed of geometry, noise and start errors.
    pub seed: u64,
    /// Targets per side of the square grid.
    pub grid: usize,
    /// Side of the plate in m (plate in the X-Y plane, Z = 0 up toward the cameras).
    pub plate_m: f64,
    /// Random depth of the targets in `[0, relief]` m (0: flat plate).
    pub relief_m: f64,
    /// Number of images.
    pub n_images: usize,
    /// Mean camera distance from the plate centre in m (±10 %).
    pub distance_m: f64,
    /// True interior `[c, x0, y0, k1, k2, k3, p1, p2]` (units of the upload form).
    pub interior: [f64; 8],
    /// The given principal distance in mm (start; x0 … p2 start at 0).
    pub c_given_mm: f64,
    /// Pixel size in mm (for the sensor bounds).
    pub pixel_size_mm: f64,
    /// Sensor size in mm (width, height).
    pub sensor_mm: [f64; 2],
    /// σ of the image noise per coordinate in mm.
    pub noise_mm: f64,
    /// σ of the start errors of the approximate coordinates in m.
    pub approx_sigma_m: f64,
    /// σ of the four control points (the plate's corners) per coordinate in m; the given control
    /// coordinates carry noise of that σ.
    pub control_sigma_m: f64,
}

/// k1 (mm⁻²) that gives `corner_mm` of radial correction at radius `r_mm`: k1 = corner / r³.
pub fn k1_for_corner(corner_mm: f64, r_mm: f64) -> f64 {
    corner_mm / (r_mm * r_mm * r_mm)
}

impl Default for CalibrationParams {
    fn default() -> Self {
        let r_corner = (18.0f64 * 18.0 + 12.0 * 12.0).sqrt();
        CalibrationParams {
            seed: 1,
            grid: 7,
            plate_m: 1.0,
            relief_m: 0.0,
            n_images: 20,
            distance_m: 1.4,
            interior: [
                24.3,
                0.06,
                -0.04,
                k1_for_corner(0.3, r_corner),
                0.0,
                0.0,
                2.0e-5,
                -1.5e-5,
            ],
            c_given_mm: 24.0,
            pixel_size_mm: 0.006,
            sensor_mm: [36.0, 24.0],
            noise_mm: 0.0006,
            approx_sigma_m: 0.02,
            control_sigma_m: 0.0001,
        }
    }
}

/// The wide-angle calibration network: targets `P01…` on a grid over a plate, cameras `I01…` on a
/// ring at 45° and 60° elevation (every fifth near vertical), aimed at the plate centre (±0.1 m),
/// every second image rolled by ±90°; measured coordinates carry the true Brown distortion. The four
/// corner targets are `control` (σ `control_sigma_m`), the others `approx` (± `approx_sigma_m`). The
/// camera gives `c_given_mm`, zero distortion, and asks to calibrate all eight parameters. Targets
/// outside the sensor are not observed.
pub fn calibration(params: &CalibrationParams) -> Result<(EpochInput, Truth), SceneError> {
    let p = params;
    if p.grid < 2 {
        return Err(bad("grid", "at least 2"));
    }
    if p.n_images < 2 {
        return Err(bad("n_images", "at least 2"));
    }
    positive("plate_m", p.plate_m)?;
    non_negative("relief_m", p.relief_m)?;
    positive("distance_m", p.distance_m)?;
    positive("c", p.interior[0])?;
    if !p.interior.iter().all(|v| v.is_finite()) {
        return Err(bad("interior", "must be finite"));
    }
    positive("c_given_mm", p.c_given_mm)?;
    positive("pixel_size_mm", p.pixel_size_mm)?;
    positive("sensor width", p.sensor_mm[0])?;
    positive("sensor height", p.sensor_mm[1])?;
    non_negative("noise_mm", p.noise_mm)?;
    non_negative("approx_sigma_m", p.approx_sigma_m)?;
    positive("control_sigma_m", p.control_sigma_m)?;

    let mut geo = stream(p.seed, GEOMETRY);
    let g = p.grid;
    let names: Vec<String> = (0..g * g).map(|i| format!("P{:02}", i + 1)).collect();
    let step = p.plate_m / (g - 1) as f64;
    let points: Vec<V3> = (0..g * g)
        .map(|i| {
            let z: f64 = geo.gen_range(0.0..=1.0);
            [
                (i % g) as f64 * step - p.plate_m / 2.0,
                (i / g) as f64 * step - p.plate_m / 2.0,
                z * p.relief_m,
            ]
        })
        .collect();
    let corners = [0, g - 1, g * (g - 1), g * g - 1];
    let stations: Vec<(V3, M3)> = (0..p.n_images)
        .map(|i| {
            let az =
                std::f64::consts::TAU * i as f64 / p.n_images as f64 + geo.gen_range(-0.1..0.1);
            let elev: f64 = if i % 5 == 4 {
                80.0
            } else if i % 2 == 0 {
                45.0
            } else {
                60.0
            };
            let elev = elev.to_radians();
            let d = p.distance_m * geo.gen_range(0.9..=1.1);
            let xo = [
                d * elev.cos() * az.cos(),
                d * elev.cos() * az.sin(),
                d * elev.sin(),
            ];
            let aim = [geo.gen_range(-0.1..=0.1), geo.gen_range(-0.1..=0.1), 0.0];
            let r = look_at(xo, aim, [0.0, 0.0, 1.0]);
            let r = match i % 4 {
                1 => roll(&r, std::f64::consts::FRAC_PI_2),
                3 => roll(&r, -std::f64::consts::FRAC_PI_2),
                _ => r,
            };
            (xo, r)
        })
        .collect();
    let mut noise = stream(p.seed, NOISE);
    let mut images = Vec::new();
    let mut truth = Truth {
        points: names.iter().cloned().zip(points.iter().copied()).collect(),
        cameras: BTreeMap::new(),
        c_mm: p.interior[0],
        interior: Some(p.interior),
    };
    for (i, (xo, r)) in stations.iter().enumerate() {
        let id = format!("I{:02}", i + 1);
        let mut observations = Vec::new();
        for (name, x) in names.iter().zip(&points) {
            let e = [gauss(&mut noise), gauss(&mut noise)];
            let Some(xy) = project(r, *xo, &p.interior, *x) else {
                continue;
            };
            if xy[0].abs() > p.sensor_mm[0] / 2.0 || xy[1].abs() > p.sensor_mm[1] / 2.0 {
                continue;
            }
            observations.push(mm_observation(
                name,
                [xy[0] + p.noise_mm * e[0], xy[1] + p.noise_mm * e[1]],
            ));
        }
        truth
            .cameras
            .insert(id.clone(), TruthCamera { xo: *xo, r: *r });
        images.push(ImageInput {
            id: id.clone(),
            camera: "cam".into(),
            station: Some(id),
            observations,
        });
    }
    let mut start = stream(p.seed, START);
    let is_control: Vec<bool> = (0..g * g).map(|i| corners.contains(&i)).collect();
    let approx = approx_list(&names, &points, &is_control, p.approx_sigma_m, &mut start);
    let control = corners
        .iter()
        .map(|&i| {
            let e = [gauss(&mut start), gauss(&mut start), gauss(&mut start)];
            ControlInput {
                point: names[i].clone(),
                X: points[i][0] + p.control_sigma_m * e[0],
                Y: points[i][1] + p.control_sigma_m * e[1],
                Z: points[i][2] + p.control_sigma_m * e[2],
                sigma_m: Some(p.control_sigma_m),
            }
        })
        .collect();
    let mut camera = plain_camera("cam", p.c_given_mm, true, Some(p.noise_mm.max(1e-5)));
    camera.calibrate = Some(
        ["c", "x0", "y0", "k1", "k2", "k3", "p1", "p2"]
            .iter()
            .map(|s| s.to_string())
            .collect(),
    );
    camera.pixel_size_mm = Some(p.pixel_size_mm);
    camera.width_px = Some((p.sensor_mm[0] / p.pixel_size_mm).round() as u32);
    camera.height_px = Some((p.sensor_mm[1] / p.pixel_size_mm).round() as u32);
    let input = EpochInput {
        observed_at: timestamp(2026, p.seed),
        label: Some(format!("calibration network seed {}", p.seed)),
        cameras: vec![camera],
        images,
        control,
        approx,
    };
    Ok((input, truth))
}

// ---------------------------------------------------------------------------------------------
// Large networks for benchmarks

/// Parameters of [`large`]: a long wall photographed from a line of stations, each point seen in
/// `images_per_point` consecutive images (defaults: 20 images × 500 points, each in 10 images).
#[derive(Debug, Clone, PartialEq)]
pub struct LargeParams {
    /// Seed of geometry, noise and start errors.
    pub seed: u64,
    /// Number of images (stations along a line parallel to the wall).
    pub n_images: usize,
    /// Number of points.
    pub n_points: usize,
    /// Images that see each point (consecutive stations nearest to it).
    pub images_per_point: usize,
    /// Station spacing along the wall in m.
    pub spacing_m: f64,
    /// Distance of the stations from the wall in m.
    pub distance_m: f64,
    /// Height of the wall in m.
    pub wall_height_m: f64,
    /// Relief of the wall toward the cameras in m.
    pub relief_m: f64,
    /// True principal distance in mm (given exactly).
    pub c_mm: f64,
    /// Self-calibrate c.
    pub calibrate_c: bool,
    /// σ of the image noise per coordinate in mm.
    pub noise_mm: f64,
    /// σ of the start errors per coordinate in m.
    pub approx_sigma_m: f64,
}

impl Default for LargeParams {
    fn default() -> Self {
        LargeParams {
            seed: 1,
            n_images: 20,
            n_points: 500,
            images_per_point: 10,
            spacing_m: 1.5,
            distance_m: 50.0,
            wall_height_m: 10.0,
            relief_m: 3.0,
            c_mm: 100.0,
            calibrate_c: true,
            noise_mm: 0.001,
            approx_sigma_m: 0.05,
        }
    }
}

impl LargeParams {
    /// The big benchmark: 100 images × 10 000 points, each in 10 images.
    pub fn huge() -> Self {
        LargeParams {
            n_images: 100,
            n_points: 10_000,
            ..LargeParams::default()
        }
    }
}

/// A large network for benchmarks: points `Q00001…` on a wall (X along, Y up, Z toward the
/// cameras), stations `L001…` on a line at Z ≈ `distance_m` looking at the wall in front of them;
/// each point is observed (mm, no sensor bounds) by the `images_per_point` stations nearest to it.
pub fn large(params: &LargeParams) -> Result<(EpochInput, Truth), SceneError> {
    let p = params;
    if p.n_images < 2 {
        return Err(bad("n_images", "at least 2"));
    }
    if p.images_per_point < 2 || p.images_per_point > p.n_images {
        return Err(bad("images_per_point", "between 2 and n_images"));
    }
    if p.n_points < 4 {
        return Err(bad("n_points", "at least 4"));
    }
    positive("spacing_m", p.spacing_m)?;
    positive("distance_m", p.distance_m)?;
    positive("wall_height_m", p.wall_height_m)?;
    non_negative("relief_m", p.relief_m)?;
    positive("c_mm", p.c_mm)?;
    non_negative("noise_mm", p.noise_mm)?;
    non_negative("approx_sigma_m", p.approx_sigma_m)?;
    let mut geo = stream(p.seed, GEOMETRY);
    let length = (p.n_images - 1) as f64 * p.spacing_m;
    let names: Vec<String> = (0..p.n_points).map(|i| format!("Q{:05}", i + 1)).collect();
    let points: Vec<V3> = (0..p.n_points)
        .map(|_| {
            [
                geo.gen_range(0.0..=length),
                geo.gen_range(0.0..=p.wall_height_m),
                geo.gen_range(0.0..=p.relief_m),
            ]
        })
        .collect();
    let stations: Vec<(V3, M3)> = (0..p.n_images)
        .map(|i| {
            let x = i as f64 * p.spacing_m;
            let xo = [
                x + geo.gen_range(-0.2..=0.2),
                p.wall_height_m / 2.0 + geo.gen_range(-1.0..=1.0),
                p.distance_m + geo.gen_range(-2.0..=2.0),
            ];
            let aim = [
                x + geo.gen_range(-0.5..=0.5),
                p.wall_height_m / 2.0,
                p.relief_m / 2.0,
            ];
            (xo, look_at(xo, aim, [0.0, 1.0, 0.0]))
        })
        .collect();
    let interior = [p.c_mm, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];
    let mut obs: Vec<Vec<ObservationInput>> = vec![Vec::new(); p.n_images];
    let mut noise = stream(p.seed, NOISE);
    let k = p.images_per_point;
    for (name, x) in names.iter().zip(&points) {
        let nearest = (x[0] / p.spacing_m).round() as isize;
        let first = (nearest - (k / 2) as isize).clamp(0, (p.n_images - k) as isize) as usize;
        for (i, o) in obs.iter_mut().enumerate().skip(first).take(k) {
            let (xo, r) = &stations[i];
            let e = [gauss(&mut noise), gauss(&mut noise)];
            if let Some(xy) = project(r, *xo, &interior, *x) {
                o.push(mm_observation(
                    name,
                    [xy[0] + p.noise_mm * e[0], xy[1] + p.noise_mm * e[1]],
                ));
            }
        }
    }
    let mut truth = Truth {
        points: names.iter().cloned().zip(points.iter().copied()).collect(),
        cameras: BTreeMap::new(),
        c_mm: p.c_mm,
        interior: None,
    };
    let mut images = Vec::new();
    for (i, ((xo, r), observations)) in stations.iter().zip(obs).enumerate() {
        let id = format!("L{:03}", i + 1);
        truth
            .cameras
            .insert(id.clone(), TruthCamera { xo: *xo, r: *r });
        images.push(ImageInput {
            id: id.clone(),
            camera: "cam".into(),
            station: Some(id),
            observations,
        });
    }
    let mut start = stream(p.seed, START);
    let approx = approx_list(
        &names,
        &points,
        &vec![false; names.len()],
        p.approx_sigma_m,
        &mut start,
    );
    let input = EpochInput {
        observed_at: timestamp(2026, p.seed),
        label: Some(format!(
            "large network {} images × {} points seed {}",
            p.n_images, p.n_points, p.seed
        )),
        cameras: vec![plain_camera(
            "cam",
            p.c_mm,
            p.calibrate_c,
            Some(p.noise_mm.max(1e-5)),
        )],
        images,
        control: Vec::new(),
        approx,
    };
    Ok((input, truth))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shared(name: &str) -> Option<String> {
        std::fs::read_to_string(format!(
            concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/data/{}"),
            name
        ))
        .ok()
    }

    #[test]
    fn paper_geometry_matches_the_shared_truth_files() {
        for (case, file, n) in [
            (PaperCase::Case1, "paper-case1-seed101.truth.json", 2),
            (PaperCase::Case2, "paper-case2-seed101.truth.json", 3),
            (PaperCase::Case3, "paper-case3-seed101.truth.json", 3),
        ] {
            let (input, truth) = paper_table1(&PaperParams::case(case, 101)).unwrap();
            assert_eq!(input.images.len(), n);
            let Some(text) = shared(file) else {
                eprintln!("shared data not available; skipping the comparison");
                return;
            };
            let theirs: Truth = serde_json::from_str(&text).unwrap();
            assert_eq!(theirs.points, truth.points);
            assert_eq!(theirs.c_mm, truth.c_mm);
            assert_eq!(theirs.cameras.len(), truth.cameras.len());
            for (id, cam) in &theirs.cameras {
                let mine = &truth.cameras[id];
                assert_eq!(cam.xo, mine.xo);
                for i in 0..3 {
                    for j in 0..3 {
                        assert!((cam.r[i][j] - mine.r[i][j]).abs() < 1e-12, "{id}");
                    }
                }
            }
        }
    }

    #[test]
    fn paper_epoch_has_the_form_of_the_shared_epochs() {
        let Some(text) = shared("paper-case3-seed101.epoch.json") else {
            return;
        };
        let theirs: EpochInput = serde_json::from_str(&text).unwrap();
        let (mine, truth) = paper_table1(&PaperParams::case(PaperCase::Case3, 7)).unwrap();
        assert_eq!(mine.cameras[0].c_mm, theirs.cameras[0].c_mm);
        assert_eq!(mine.cameras[0].calibrate_c, theirs.cameras[0].calibrate_c);
        assert_eq!(mine.images.len(), theirs.images.len());
        assert_eq!(mine.approx.len(), theirs.approx.len());
        // The observations agree with the shared ones to a few noise σ.
        for (a, b) in mine.images.iter().zip(&theirs.images) {
            for (o, q) in a.observations.iter().zip(&b.observations) {
                assert_eq!(o.point, q.point);
                assert!((o.x_mm.unwrap() - q.x_mm.unwrap()).abs() < 0.01);
                assert!((o.y_mm.unwrap() - q.y_mm.unwrap()).abs() < 0.01);
            }
        }
        mine.validate().unwrap();
        // Start errors of about 10 mm.
        let rms = (mine
            .approx
            .iter()
            .map(|a| {
                let t = truth.points[&a.point];
                (a.X - t[0]).powi(2) + (a.Y - t[1]).powi(2) + (a.Z - t[2]).powi(2)
            })
            .sum::<f64>()
            / (3.0 * mine.approx.len() as f64))
            .sqrt();
        assert!(rms > 0.004 && rms < 0.02, "{rms}");
    }

    #[test]
    fn deterministic_by_seed() {
        let a = long_range(&LongRangeParams::default()).unwrap();
        let b = long_range(&LongRangeParams::default()).unwrap();
        assert_eq!(a, b);
        let c = long_range(&LongRangeParams {
            seed: 2,
            ..LongRangeParams::default()
        })
        .unwrap();
        assert_ne!(a.0, c.0);
    }

    fn noise_free_residuals(input: &EpochInput, truth: &Truth) -> f64 {
        // Re-project the truth with the true interior and compare with the (noise-free) observations.
        let problem = input.validate().unwrap();
        let interior = truth
            .interior
            .unwrap_or([truth.c_mm, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
        let mut max: f64 = 0.0;
        for im in &problem.images {
            let cam = &truth.cameras[&im.id];
            for o in &im.observations {
                let x = truth.points[&problem.points[o.point]];
                let xy = project(&cam.r, cam.xo, &interior, x).unwrap();
                max = max
                    .max((xy[0] - o.xy[0]).abs())
                    .max((xy[1] - o.xy[1]).abs());
            }
        }
        max
    }

    #[test]
    fn long_range_is_consistent_in_both_frames() {
        for params in [LongRangeParams::default(), LongRangeParams::enu()] {
            let (input, truth) = long_range(&LongRangeParams {
                noise_px: 0.0,
                ..params.clone()
            })
            .unwrap();
            input.validate().unwrap();
            assert_eq!(input.images.len(), 5);
            for im in &input.images {
                assert_eq!(im.observations.len(), 28, "image {} misses targets", im.id);
            }
            let worst = noise_free_residuals(&input, &truth);
            // UTM-sized coordinates round at ~4e-10 m: ~1e-9 mm in the image.
            assert!(worst < 1e-7, "{:?}: {worst} mm", params.frame);
            if params.frame != SiteFrame::TowardCameras {
                // Cameras look horizontally: r3 has no vertical component to speak of.
                for cam in truth.cameras.values() {
                    assert!(cam.r[2][2].abs() < 0.03, "{:?}", cam.r);
                    assert!(cam.xo[0] > 499_000.0 && cam.xo[1] > 3_899_000.0);
                }
            }
        }
        // The two frames differ by a rigid motion only: same distances between all points.
        let (a_in, a) = long_range(&LongRangeParams::default()).unwrap();
        let (b_in, b) = long_range(&LongRangeParams::enu()).unwrap();
        assert_eq!(a_in.images, b_in.images);
        let pa: Vec<_> = a.points.values().collect();
        let pb: Vec<_> = b.points.values().collect();
        for i in 0..pa.len() {
            for j in 0..i {
                let da = dot(sub(*pa[i], *pa[j]), sub(*pa[i], *pa[j])).sqrt();
                let db = dot(sub(*pb[i], *pb[j]), sub(*pb[i], *pb[j])).sqrt();
                assert!((da - db).abs() < 1e-8);
            }
        }
    }

    #[test]
    fn calibration_network_sees_the_plate() {
        let params = CalibrationParams::default();
        let (input, truth) = calibration(&CalibrationParams {
            noise_mm: 0.0,
            ..params.clone()
        })
        .unwrap();
        input.validate().unwrap();
        assert_eq!(input.images.len(), 20);
        assert_eq!(input.control.len(), 4);
        assert!(noise_free_residuals(&input, &truth) < 1e-9);
        let mut max_r: f64 = 0.0;
        for im in &input.images {
            assert!(
                im.observations.len() >= 20,
                "{} sees {}",
                im.id,
                im.observations.len()
            );
            for o in &im.observations {
                max_r = max_r.max(o.x_mm.unwrap().hypot(o.y_mm.unwrap()));
            }
        }
        // The targets reach well into the field where the distortion is large.
        assert!(max_r > 14.0, "max radius {max_r} mm");
        let k1 = params.interior[3];
        let corner = (18.0f64).hypot(12.0);
        assert!((k1 * corner.powi(3) - 0.3).abs() < 1e-12);
    }

    #[test]
    fn large_network_shapes() {
        let (input, _) = large(&LargeParams::default()).unwrap();
        let n: usize = input.images.iter().map(|i| i.observations.len()).sum();
        assert_eq!(n, 500 * 10);
        input.validate().unwrap();
        for im in &input.images {
            for o in &im.observations {
                assert!(o.x_mm.unwrap().abs() < 40.0 && o.y_mm.unwrap().abs() < 40.0);
            }
        }
    }

    #[test]
    fn blunder_swaps_two_labels() {
        let (clean, _) = long_range(&LongRangeParams::default()).unwrap();
        let (dirty, _) = long_range(&LongRangeParams::with_blunder()).unwrap();
        let differing: Vec<_> = clean.images[2]
            .observations
            .iter()
            .zip(&dirty.images[2].observations)
            .filter(|(a, b)| a.point != b.point)
            .map(|(a, _)| a.point.clone())
            .collect();
        assert_eq!(differing, vec!["T101".to_string(), "T121".to_string()]);
        for i in [0, 1, 3, 4] {
            assert_eq!(clean.images[i], dirty.images[i]);
        }
        let mut e = clean.clone();
        assert!(matches!(
            swap_labels(&mut e, "nope", "T101", "T102"),
            Err(SceneError::UnknownImage(_))
        ));
        assert!(matches!(
            swap_labels(&mut e, "S1", "T101", "X"),
            Err(SceneError::UnknownPoint { .. })
        ));
    }

    #[test]
    fn bad_parameters_are_typed_errors() {
        assert!(long_range(&LongRangeParams {
            n_stations: 1,
            ..LongRangeParams::default()
        })
        .is_err());
        assert!(long_range(&LongRangeParams {
            noise_px: f64::NAN,
            ..LongRangeParams::default()
        })
        .is_err());
        assert!(large(&LargeParams {
            images_per_point: 30,
            ..LargeParams::default()
        })
        .is_err());
        assert!(calibration(&CalibrationParams {
            grid: 1,
            ..CalibrationParams::default()
        })
        .is_err());
        assert!(paper_table1(&PaperParams {
            noise_mm: -1.0,
            ..PaperParams::default()
        })
        .is_err());
    }

    #[test]
    fn truth_round_trips_and_gives_indexes() {
        let (_, truth) = paper_table1(&PaperParams::default()).unwrap();
        let text = serde_json::to_string(&truth).unwrap();
        assert!(text.contains("\"Xo\"") && text.contains("\"R\"") && !text.contains("interior"));
        let back: Truth = serde_json::from_str(&text).unwrap();
        assert_eq!(back.points, truth.points);
        for (id, cam) in &truth.cameras {
            let b = &back.cameras[id];
            assert_eq!(b.xo, cam.xo);
            for i in 0..3 {
                for j in 0..3 {
                    assert!((b.r[i][j] - cam.r[i][j]).abs() < 1e-15);
                }
            }
        }
        let pts: Vec<AdjustedPoint> = truth
            .points
            .iter()
            .map(|(n, p)| AdjustedPoint {
                name: n.clone(),
                xyz: [p[0] + 1.0, p[1], p[2]],
                covariance_m2: [[0.0; 3]; 3],
            })
            .collect();
        assert!(truth.index3_rmse_mm(&pts).unwrap()[3] < 1e-9);
        assert!(truth.index4_rmse_mm(&pts).unwrap()[3] < 1e-9);
    }
}
