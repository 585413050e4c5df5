//! Small bundles for the core's unit tests.

use nalgebra::Vector3;

use crate::photogrammetry::model::bundle::{Bundle, ImageState, Obs};
use crate::photogrammetry::model::orthogonal::OrthoImage;
use crate::photogrammetry::model::rotation::rodrigues;
use crate::photogrammetry::model::Model;

/// A small orthogonal-model bundle: `nimg` images around the Z axis looking at `np` points, c
/// free, point p in the `per_point` images from p mod `nimg` on, one observation inactive.
pub fn bundle(nimg: usize, np: usize, per_point: usize) -> Bundle {
    let c = 300.0;
    let points: Vec<Vector3<f64>> = (0..np)
        .map(|k| {
            let t = k as f64;
            Vector3::new((t * 1.7).sin(), (t * 0.9).cos(), 0.3 * (t * 2.3).sin())
        })
        .collect();
    let mut images = Vec::new();
    let mut obs = Vec::new();
    let mut point_obs = vec![Vec::new(); np];
    for j in 0..nimg {
        let angle = -0.3 + 0.6 * j as f64 / (nimg - 1) as f64;
        let r = rodrigues(Vector3::new(0.02 * j as f64, angle, 0.01));
        let centre = r.transpose() * Vector3::new(0.0, 0.0, 20.0);
        let o = OrthoImage::from_center(r, centre, c, 0.0);
        images.push(ImageState {
            rotation: r,
            p: [o.m, o.a4, o.a8],
        });
        for p in 0..np {
            if (j + nimg - p % nimg) % nimg >= per_point {
                continue;
            }
            point_obs[p].push(obs.len());
            obs.push(Obs {
                image: j,
                point: p,
                meas: [0.01 * (p + j) as f64, -0.02 * p as f64],
                active: !(j == 1 && p == 2),
                weight: 1.0,
                prior_weight: 1.0,
            });
        }
    }
    let mut free = [false; 8];
    free[0] = true;
    let mut prior = [None; 8];
    prior[0] = Some((c, 0.1 * c));
    let mut b = Bundle {
        model: Model::Orthogonal,
        zbar: 0.0,
        images,
        image_camera: vec![0; nimg],
        interior: vec![[c, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]],
        free: vec![free],
        sigma: vec![0.003],
        points,
        obs,
        point_obs,
        control: vec![None; np],
        gauge: 0.0,
        interior_prior: vec![prior],
        cancel: Default::default(),
    };
    b.gauge = 1e-6 * b.point_block_trace() / (3 * np) as f64;
    b
}
