//! The minimum detectable displacement (MDD) of the single-point test in
//! `super::displacement`: the smallest true displacement that the test `d'ᵀ Σ⁻¹ d' > c` detects
//! with a stated probability (the power, e.g. 80 %), at the site's confidence.
//!
//! Under a true displacement δ·u (u a unit vector) the statistic is non-central χ² with `h` degrees
//! of freedom and non-centrality λ = δ² uᵀ Σ⁻¹ u (Baarda's reliability theory; Niemeier 2008
//! §12.5, Caspary 1987 §6.3). With λ₀ the non-centrality at which
//! P(χ'²(h, λ₀) > c) equals the power:
//! - along a direction u: δ_u = √(λ₀ / uᵀ Σ⁻¹ u);
//! - in 3-D, the worst direction (the largest eigenvalue of Σ): δ_3D = √(λ₀ · λ_max(Σ)).
//!
//! The non-central χ² and its λ₀ live in [`super::stats`], cached per (critical value, dof,
//! power), since every point of a page asks for the same λ₀.
//!
//! "No alert" then reads as "no movement above δ". With a finite variance-factor dof the test's
//! critical value is `h·F(h, f)` while this power uses the χ' distribution (Σ taken as known): the
//! MDD is then slightly optimistic, by the same small margin as the F against the χ² quantile.

use nalgebra::{Matrix3, SymmetricEigen, Vector3};
use serde::{Deserialize, Serialize};

use super::stats::noncentrality_for_power;

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
