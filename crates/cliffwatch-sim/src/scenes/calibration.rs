//! A wide-angle convergent calibration network of a flat target plate, for the central model
//! with full self-calibration.

use std::collections::BTreeMap;

use rand::Rng;

use super::builder::*;
use cliffwatch_core::photogrammetry::input::epoch::{ControlInput, EpochInput};

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
        add_image(
            &mut truth,
            &mut images,
            &id,
            TruthCamera { xo: *xo, r: *r },
            observations,
        );
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
