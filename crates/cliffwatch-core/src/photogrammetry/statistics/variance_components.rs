//! Variance components per camera (Förstner's estimate): each camera's share of vᵀPv and of the
//! redundancy, `r_k = Σ (1 − (A Q Aᵀ)_ii p_i)` over its active image coordinates, so that
//! `σ̂_k² = σ_k² · vᵀP v_k / r_k` estimates the σ of one image coordinate of camera k; and the
//! pooled estimate of a window of epochs, `σ̂_k² = Σ σ_k² vᵀPv_k / Σ r_k`, which a site applies as
//! its cameras' a-priori σ when the global test keeps failing (issue 61, item 8).

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::precision::Cofactors;
use crate::photogrammetry::model::bundle::Bundle;
use crate::photogrammetry::solve::normal_equations::PARALLEL_MIN_OBSERVATIONS;

/// One camera's variance component in one adjustment.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct VarianceComponent {
    /// Camera id.
    pub camera: String,
    /// The camera's a-priori σ of an image coordinate the adjustment used, mm.
    pub sigma_mm: f64,
    /// Active image coordinates (two per observation).
    pub coordinates: usize,
    /// Its share of the redundancy (dimensionless; the shares of all cameras and of the control
    /// points add up to the degrees of freedom).
    pub redundancy: f64,
    /// Its share of vᵀPv, weights relative to `sigma_mm` (dimensionless).
    pub vtpv: f64,
}

impl VarianceComponent {
    /// The estimate of this camera's σ from this adjustment alone, mm (`None` without
    /// redundancy).
    pub fn sigma_hat_mm(&self) -> Option<f64> {
        (self.redundancy > 0.0).then(|| self.sigma_mm * (self.vtpv / self.redundancy).sqrt())
    }
}

/// The per-camera components of a solution over the observations weighted by their camera's σ:
/// `cameras` names the bundle's cameras in order.
pub fn per_camera(b: &Bundle, q: &Cofactors, cameras: &[String]) -> Vec<VarianceComponent> {
    let one = |k: usize| -> (usize, usize, f64, f64) {
        let o = &b.obs[k];
        // Only the observations weighted by their camera's σ (not by one of their own).
        if !o.active || o.prior_weight != 1.0 {
            return (0, 0, 0.0, 0.0);
        }
        let cam = b.image_camera[o.image];
        let s2 = b.sigma[cam] * b.sigma[cam] / o.prior_weight;
        let e = b.residual_of(o);
        let aqa = q.predicted_cofactor(b, o);
        let r = (0..2).map(|c| 1.0 - aqa[(c, c)] / s2).sum::<f64>();
        // s2 carries the observation's own weight: e²/s2 is its term of vᵀPv.
        let vtpv = (e[0] * e[0] + e[1] * e[1]) / s2;
        (cam, 2, r, vtpv)
    };
    let add = |mut acc: Vec<(usize, f64, f64)>, (cam, n, r, v): (usize, usize, f64, f64)| {
        if n > 0 {
            acc[cam].0 += n;
            acc[cam].1 += r;
            acc[cam].2 += v;
        }
        acc
    };
    let zero = || vec![(0usize, 0.0f64, 0.0f64); cameras.len()];
    let sums = if b.obs.len() < PARALLEL_MIN_OBSERVATIONS {
        (0..b.obs.len()).map(one).fold(zero(), add)
    } else {
        (0..b.obs.len())
            .into_par_iter()
            .map(one)
            .fold(zero, add)
            .reduce(zero, |mut a, c| {
                for (x, y) in a.iter_mut().zip(c) {
                    x.0 += y.0;
                    x.1 += y.1;
                    x.2 += y.2;
                }
                a
            })
    };
    cameras
        .iter()
        .zip(sums)
        .enumerate()
        .filter(|(_, (_, (n, _, _)))| *n > 0)
        .map(|(k, (id, (n, r, v)))| VarianceComponent {
            camera: id.clone(),
            sigma_mm: b.sigma[k],
            coordinates: n,
            redundancy: r,
            vtpv: v,
        })
        .collect()
}

/// A camera's σ estimated from a window of epochs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct PooledSigma {
    /// Camera id.
    pub camera: String,
    /// The estimated σ of one image coordinate, mm.
    pub sigma_mm: f64,
    /// Its relative standard deviation (dimensionless, ≈ 1 / √(2 Σ r)).
    pub relative_sigma: f64,
    /// Epochs it was estimated from.
    pub epochs: usize,
    /// The total redundancy it rests on.
    pub redundancy: f64,
}

/// The pooled estimate per camera of the epochs' components (each epoch's list as its
/// adjustment reported it): `σ̂² = Σ σ² vᵀPv / Σ r` over the epochs that saw the camera, in the
/// order the cameras first appear.
pub fn pooled(epochs: &[&[VarianceComponent]]) -> Vec<PooledSigma> {
    let mut out: Vec<(String, f64, f64, usize)> = Vec::new();
    for comps in epochs {
        for c in comps.iter() {
            if !(c.redundancy > 0.0 && c.vtpv.is_finite() && c.sigma_mm > 0.0) {
                continue;
            }
            let i = match out.iter().position(|(id, ..)| *id == c.camera) {
                Some(i) => i,
                None => {
                    out.push((c.camera.clone(), 0.0, 0.0, 0));
                    out.len() - 1
                }
            };
            out[i].1 += c.sigma_mm * c.sigma_mm * c.vtpv;
            out[i].2 += c.redundancy;
            out[i].3 += 1;
        }
    }
    out.into_iter()
        .map(|(camera, s, r, n)| PooledSigma {
            camera,
            sigma_mm: (s / r).sqrt(),
            relative_sigma: 1.0 / (2.0 * r).sqrt(),
            epochs: n,
            redundancy: r,
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pooling_weighs_by_redundancy_and_rescales_by_the_sigma_used() {
        // Epoch 1 used σ 0.002 and saw a variance factor of 2.25 (σ̂ = 0.003); epoch 2 used
        // 0.003 and saw 1: both say 0.003.
        let e1 = [VarianceComponent {
            camera: "a".into(),
            sigma_mm: 0.002,
            coordinates: 100,
            redundancy: 40.0,
            vtpv: 90.0,
        }];
        let e2 = [VarianceComponent {
            camera: "a".into(),
            sigma_mm: 0.003,
            coordinates: 100,
            redundancy: 60.0,
            vtpv: 60.0,
        }];
        let p = pooled(&[&e1, &e2]);
        assert_eq!(p.len(), 1);
        assert!((p[0].sigma_mm - 0.003).abs() < 1e-12, "{p:?}");
        assert_eq!(p[0].epochs, 2);
        assert!((p[0].relative_sigma - 1.0 / 200f64.sqrt()).abs() < 1e-12);
        assert!((e1[0].sigma_hat_mm().unwrap() - 0.003).abs() < 1e-12);
    }
}
