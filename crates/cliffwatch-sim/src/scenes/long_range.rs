//! The long-range cliff (5 m × 3 m face, 5 stations about 105 m away, 400 mm lens), the nearly
//! flat face, and the label-swap blunder.

use std::collections::BTreeMap;

use rand::Rng;

use super::builder::*;
use cliffwatch_core::photogrammetry::input::epoch::{EpochInput, ImageInput, ObservationInput};

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
    long_range_epoch(
        params,
        &EpochVariation {
            noise_seed: params.seed,
            displaced: Vec::new(),
        },
    )
}

/// What differs between repeated epochs of one long-range scene ([`long_range_epoch`]): the image
/// noise and the targets' displacements; the geometry, the start errors and c stay the scene's.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct EpochVariation {
    /// Seed of the image noise alone ([`long_range`] uses the scene's seed).
    pub noise_seed: u64,
    /// Targets displaced before they are photographed: (index of the target, 0-based;
    /// displacement in m, site frame). The truth gives the displaced positions.
    pub displaced: Vec<(usize, [f64; 3])>,
}

/// One epoch of the long-range scene of `params` (same targets, stations and camera as
/// [`long_range`]) with the image noise of `variation.noise_seed` and the targets of
/// `variation.displaced` moved: repeated epochs of one network, e.g. to check a campaign plan's
/// predicted precision against simulation. A displaced index beyond the targets is an error.
pub fn long_range_epoch(
    params: &LongRangeParams,
    variation: &EpochVariation,
) -> Result<(EpochInput, Truth), SceneError> {
    let p = params;
    p.check()?;
    let mut geo = stream(p.seed, GEOMETRY);
    let names: Vec<String> = (0..p.n_points).map(|i| format!("T{}", 101 + i)).collect();
    let mut points = face_targets(p, &mut geo);
    let stations = long_range_stations(p, &mut geo);
    let (rot, origin) = site_frame(p.frame);
    let rot_t = transpose(&rot);
    for (k, d) in &variation.displaced {
        let x = points
            .get_mut(*k)
            .ok_or_else(|| bad("displaced", "target index out of range"))?;
        let local = mat_vec(&rot_t, *d);
        for i in 0..3 {
            x[i] += local[i];
        }
    }
    let images = photograph(p, variation.noise_seed, &stations, &names, &points);
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
    let to_site = |x: V3| -> V3 {
        let v = mat_vec(&rot, x);
        [v[0] + origin[0], v[1] + origin[1], v[2] + origin[2]]
    };
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
/// `noise_px` from `noise_seed`, as pixels or mm as the parameters ask.
fn photograph(
    p: &LongRangeParams,
    noise_seed: u64,
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
    let mut noise = stream(noise_seed, NOISE);
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
                    sigma_mm: None,
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
