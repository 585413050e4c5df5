//! Large networks for benchmarks: a long wall seen from a line of stations.

use std::collections::BTreeMap;

use rand::Rng;

use super::builder::*;
use cliffwatch_core::photogrammetry::input::epoch::{EpochInput, ObservationInput};

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
        add_image(
            &mut truth,
            &mut images,
            &id,
            TruthCamera { xo: *xo, r: *r },
            observations,
        );
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
