//! The minimum detectable displacement (MDD) of the single-point test in
//! [`super::displacement`]: the smallest true displacement that the test `d'ᵀ Σ⁻¹ d' > c` detects
//! with a stated probability (the power, e.g. 80 %), at the site's confidence.
//!
//! Under a true displacement δ·u (u a unit vector) the statistic is non-central χ² with `h` degrees
//! of freedom and non-centrality λ = δ² uᵀ Σ⁻¹ u (Baarda's reliability theory; Niemeier 2008
//! §12.5, Caspary 1987 §6.3). With λ₀ the non-centrality at which
//! P(χ'²(h, λ₀) > c) equals the power:
//! - along a direction u: δ_u = √(λ₀ / uᵀ Σ⁻¹ u);
//! - in 3-D, the worst direction (the largest eigenvalue of Σ): δ_3D = √(λ₀ · λ_max(Σ)).
//!
//! "No alert" then reads as "no movement above δ". With a finite variance-factor dof the test's
//! critical value is `h·F(h, f)` while this power uses the χ' distribution (Σ taken as known): the
//! MDD is then slightly optimistic, by the same small margin as the F against the χ² quantile.

use nalgebra::{Matrix3, SymmetricEigen, Vector3};
use serde::{Deserialize, Serialize};

use super::stats::chi2_cdf;

/// The power the dashboard and the report state the MDD at: 80 %.
pub const DEFAULT_POWER: f64 = 0.8;

/// The minimum detectable displacement of one point in one epoch.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MinimumDetectable {
    /// Smallest displacement along the point's direction of interest, in mm, detected with
    /// probability `power` (None without a direction).
    pub along_mm: Option<f64>,
    /// Smallest displacement in the worst direction, in mm, detected with probability `power`.
    pub worst_mm: f64,
    /// The detection probability the MDD is stated at (0–1).
    pub power: f64,
}

/// CDF of the non-central χ²(k, λ) at x: the Poisson(λ/2) mixture of central χ²(k + 2j).
pub fn noncentral_chi2_cdf(x: f64, k: f64, lambda: f64) -> f64 {
    if x <= 0.0 {
        return 0.0;
    }
    if lambda <= 0.0 {
        return chi2_cdf(x, k);
    }
    let half = 0.5 * lambda;
    // Sum outwards from the Poisson mode so that the weights never underflow before they matter.
    let mode = half.floor();
    let ln_weight = |j: f64| -half + j * half.ln() - ln_factorial(j);
    let mut total = 0.0;
    let mut mass = 0.0;
    let mut j = mode;
    loop {
        let w = ln_weight(j).exp();
        total += w * chi2_cdf(x, k + 2.0 * j);
        mass += w;
        if (w < 1e-14 && j > mode) || j > mode + 10_000.0 {
            break;
        }
        j += 1.0;
    }
    let mut j = mode - 1.0;
    while j >= 0.0 {
        let w = ln_weight(j).exp();
        total += w * chi2_cdf(x, k + 2.0 * j);
        mass += w;
        if w < 1e-14 {
            break;
        }
        j -= 1.0;
    }
    (total / mass.max(f64::MIN_POSITIVE)).clamp(0.0, 1.0)
}

fn ln_factorial(j: f64) -> f64 {
    (1..=j as u64).map(|i| (i as f64).ln()).sum()
}

/// The non-centrality λ₀ at which a test with `dof` degrees of freedom and critical value
/// `critical` detects with probability `power`: P(χ'²(dof, λ₀) > critical) = power.
pub fn noncentrality_for_power(critical: f64, dof: f64, power: f64) -> f64 {
    let miss = |lambda: f64| noncentral_chi2_cdf(critical, dof, lambda);
    let target = 1.0 - power;
    let mut hi = 1.0;
    while miss(hi) > target && hi < 1e6 {
        hi *= 2.0;
    }
    let mut lo = 0.0;
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if miss(mid) > target {
            lo = mid;
        } else {
            hi = mid;
        }
        if hi - lo < 1e-10 * hi {
            break;
        }
    }
    0.5 * (lo + hi)
}

/// The MDD of a displacement with covariance `cov_mm2` (mm²) under the single-point test with
/// `dof` degrees of freedom and critical value `critical`, at detection probability `power`;
/// `direction` is the unit direction of interest. None when the covariance is not positive
/// definite (a degenerate point has no 3-D test to be sensitive with).
pub fn minimum_detectable(
    cov_mm2: &Matrix3<f64>,
    critical: f64,
    dof: usize,
    power: f64,
    direction: Option<&Vector3<f64>>,
) -> Option<MinimumDetectable> {
    if dof == 0 || !critical.is_finite() || !(0.0..1.0).contains(&power) {
        return None;
    }
    let inverse = cov_mm2.cholesky()?.inverse();
    let lambda0 = noncentrality_for_power(critical, dof as f64, power);
    let largest = SymmetricEigen::new(*cov_mm2).eigenvalues.max();
    let along_mm = direction.and_then(|u| {
        let info = (u.transpose() * inverse * u)[(0, 0)];
        (info > 0.0).then(|| (lambda0 / info).sqrt())
    });
    Some(MinimumDetectable {
        along_mm,
        worst_mm: (lambda0 * largest).sqrt(),
        power,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::stats::chi2_quantile;

    #[test]
    fn noncentral_cdf_is_the_central_one_at_zero_and_falls_with_lambda() {
        for x in [1.0, 5.0, 11.34] {
            assert!((noncentral_chi2_cdf(x, 3.0, 0.0) - chi2_cdf(x, 3.0)).abs() < 1e-12);
            assert!(noncentral_chi2_cdf(x, 3.0, 4.0) < chi2_cdf(x, 3.0));
        }
        // Tabulated: P(χ'²(1, λ=(z_α/2 + z_β)²) > 3.8415) = 0.80 for α = 5 %, β = 20 %
        // (1.95996 + 0.84162)² = 7.8489.
        let lambda = noncentrality_for_power(chi2_quantile(0.95, 1.0), 1.0, 0.8);
        assert!((lambda - 7.849).abs() < 0.01, "{lambda}");
    }
}
