//! The minimum detectable displacement of a stored displacement row, for the pages: the row's
//! 3 × 3 covariance under the single-point test at the site's confidence (χ²(3) critical value),
//! at [`DEFAULT_POWER`] (see [`cliffwatch_core::analysis::sensitivity`]).

use nalgebra::Matrix3;

use crate::store::displacements::Displacement;
use cliffwatch_core::analysis::sensitivity::{
    minimum_detectable, MinimumDetectable, DEFAULT_POWER,
};
use cliffwatch_core::analysis::stats::chi2_quantile;
use cliffwatch_core::analysis::unit_direction;

/// The MDD of row `d` (mm) along `direction` (any length; None: 3-D only) at `confidence`
/// (0–1); None for rows stored without their covariance, or a degenerate one.
pub fn of(
    d: &Displacement,
    direction: Option<[f64; 3]>,
    confidence: f64,
) -> Option<MinimumDetectable> {
    let cov = Matrix3::new(
        d.sigma_dx_mm.powi(2),
        d.cov_dxdy_mm2?,
        d.cov_dxdz_mm2?,
        d.cov_dxdy_mm2?,
        d.sigma_dy_mm.powi(2),
        d.cov_dydz_mm2?,
        d.cov_dxdz_mm2?,
        d.cov_dydz_mm2?,
        d.sigma_dz_mm.powi(2),
    );
    let critical = chi2_quantile(confidence, 3.0);
    let u = direction.and_then(unit_direction);
    minimum_detectable(&cov, critical, 3, DEFAULT_POWER, u.as_ref())
}
