//! Shared helpers of the identification tests on the long-range scene: the scene with its true and
//! uploaded cameras, the true orientations, the 4 corner targets a user would seed, and
//! approximations off by a map's error.
#![allow(dead_code)]

use std::collections::BTreeMap;

use cliffwatch_core::photogrammetry::{Camera, ImageOrientation};
use cliffwatch_sim::scenes::{long_range, LongRangeParams, Truth};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

/// The long-range scene of one seed.
pub struct Scene {
    /// The truth.
    pub truth: Truth,
    /// Camera with the true c (to render observations).
    pub cam_true: Camera,
    /// Camera as uploaded (c 1 % off).
    pub cam: Camera,
}

/// The default long-range scene with this seed.
pub fn scene(seed: u64) -> Scene {
    let (epoch, truth) = long_range(&LongRangeParams {
        seed,
        ..LongRangeParams::default()
    })
    .unwrap();
    let cam = Camera::from_input(&epoch.cameras[0]).unwrap();
    let mut cam_true = cam.clone();
    cam_true.params[0] = truth.c_mm;
    Scene {
        truth,
        cam_true,
        cam,
    }
}

/// The true orientation of a station.
pub fn true_orientation(s: &Scene, station: &str) -> ImageOrientation {
    let t = &s.truth.cameras[station];
    ImageOrientation {
        image: station.into(),
        station: station.into(),
        camera: s.cam.id.clone(),
        rotation: t.r,
        center: t.xo,
    }
}

/// The 4 targets nearest the face's corners (the scene's frame: X along the face, Y up).
pub fn corner_targets(truth: &Truth) -> Vec<String> {
    let mut chosen: Vec<String> = Vec::new();
    for (sx, sy) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
        let best = truth
            .points
            .iter()
            .filter(|(n, _)| !chosen.contains(n))
            .max_by(|a, b| (sx * a.1[0] + sy * a.1[1]).total_cmp(&(sx * b.1[0] + sy * b.1[1])))
            .unwrap();
        chosen.push(best.0.clone());
    }
    chosen
}

/// A common offset (σ `shift`) and turn (σ `turn_deg` about the vertical) plus σ `each` per point.
pub fn approximations(
    truth: &Truth,
    shift: f64,
    turn_deg: f64,
    each: f64,
    seed: u64,
) -> BTreeMap<String, [f64; 3]> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut g = || -> f64 { rng.sample(StandardNormal) };
    let off = [shift * g(), shift * g(), shift * g()];
    let (s, c) = (turn_deg * g()).to_radians().sin_cos();
    let n = truth.points.len() as f64;
    let centre = truth.points.values().fold([0.0; 3], |a, x| {
        [a[0] + x[0] / n, a[1] + x[1] / n, a[2] + x[2] / n]
    });
    truth
        .points
        .iter()
        .map(|(name, x)| {
            let d = [x[0] - centre[0], x[1] - centre[1], x[2] - centre[2]];
            let r = [c * d[0] + s * d[2], d[1], -s * d[0] + c * d[2]];
            let e = [each * g(), each * g(), each * g()];
            let p = [
                centre[0] + r[0] + off[0] + e[0],
                centre[1] + r[1] + off[1] + e[1],
                centre[2] + r[2] + off[2] + e[2],
            ];
            (name.clone(), p)
        })
        .collect()
}
