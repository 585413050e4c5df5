//! Displacements of the points: vector, covariance, magnitude, component along a direction of interest and
//! the significance test `d'ᵀ Σ_d'⁻¹ d' ≤ χ²(3; 1 − α)` (F(3, f)·3 with a finite variance dof) — the
//! single-point test of Niemeier 2008 §12.5 / Caspary 1987 §6.3. Not significant = not alertable.

use chrono::{DateTime, Utc};
use nalgebra::{DMatrix, Matrix3, Vector3};
use serde::{Deserialize, Serialize};

use super::epoch::PointRole;
use super::failure::FailureForecast;
use super::linalg::sym_inverse;
use super::stats::f_quantile;
use super::velocity::Kinematics;

/// One row of a point's displacement time series: the contract's fields, the point name and the
/// off-diagonal terms of the covariance.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DisplacementRecord {
    /// Point name.
    pub point: String,
    /// Epoch id.
    pub epoch: i64,
    /// When the epoch was observed.
    pub observed_at: DateTime<Utc>,
    /// Displacement along X in mm (site frame, reference datum).
    pub dx_mm: f64,
    /// Displacement along Y in mm.
    pub dy_mm: f64,
    /// Displacement along Z in mm.
    pub dz_mm: f64,
    /// 3-D length of the displacement in mm.
    pub d_mm: f64,
    /// σ of dx in mm.
    pub sigma_dx_mm: f64,
    /// σ of dy in mm.
    pub sigma_dy_mm: f64,
    /// σ of dz in mm.
    pub sigma_dz_mm: f64,
    /// σ of `d_mm` in mm (linearised; √(trace/3) when d ≈ 0).
    pub sigma_mm: f64,
    /// Covariance of dx and dy in mm² (with the σ it completes the 3 × 3 covariance of the
    /// displacement; None for rows stored before it was kept).
    #[serde(default)]
    pub cov_dxdy_mm2: Option<f64>,
    /// Covariance of dx and dz in mm².
    #[serde(default)]
    pub cov_dxdz_mm2: Option<f64>,
    /// Covariance of dy and dz in mm².
    #[serde(default)]
    pub cov_dydz_mm2: Option<f64>,
    /// Component along the point's direction of interest in mm (None when no direction is set).
    pub d_along_mm: Option<f64>,
    /// Whether the displacement is significant at the configured confidence.
    pub significant: bool,
    /// Rate of `d_mm` in mm/day (None with fewer than 2 epochs).
    pub velocity_mm_per_day: Option<f64>,
    /// Forecast time to failure in hours (None unless the point accelerates).
    pub time_to_failure_hours: Option<f64>,
    /// σ of `time_to_failure_hours` in hours.
    #[serde(default)]
    pub time_to_failure_sigma_hours: Option<f64>,
    /// The Kalman-filtered state at this epoch (None for rows stored before it was kept, or when
    /// the filter had no estimate).
    #[serde(default, flatten)]
    pub filtered: Option<FilteredValues>,
}

/// Kalman-filtered displacement, velocity and acceleration of a point at one epoch (the causal
/// filter's estimate with what was known then; see [`super::kalman`]), with their σ.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FilteredValues {
    /// Filtered displacement along X in mm.
    pub f_dx_mm: f64,
    /// Filtered displacement along Y in mm.
    pub f_dy_mm: f64,
    /// Filtered displacement along Z in mm.
    pub f_dz_mm: f64,
    /// 3-D length of the filtered displacement in mm.
    pub f_d_mm: f64,
    /// σ of `f_dx_mm` in mm.
    pub sigma_f_dx_mm: f64,
    /// σ of `f_dy_mm` in mm.
    pub sigma_f_dy_mm: f64,
    /// σ of `f_dz_mm` in mm.
    pub sigma_f_dz_mm: f64,
    /// σ of `f_d_mm` in mm.
    pub sigma_f_d_mm: f64,
    /// Filtered rate of the displacement's length in mm/day (the velocity vector along the
    /// direction of the filtered motion since the reference, or since the filter window's first
    /// epoch when that lies before a reference moved later; along the direction of interest when
    /// one is set).
    pub f_velocity_mm_per_day: f64,
    /// σ of `f_velocity_mm_per_day` in mm/day.
    pub sigma_f_velocity_mm_per_day: f64,
    /// Filtered acceleration along the same direction in mm/day² (None for a constant-velocity
    /// model).
    pub f_acceleration_mm_per_day2: Option<f64>,
    /// σ of `f_acceleration_mm_per_day2` in mm/day².
    pub sigma_f_acceleration_mm_per_day2: Option<f64>,
    /// Time to failure in hours from the inverse-velocity fit over the smoothed velocities
    /// (None unless the point moves and the fit holds).
    #[serde(default)]
    pub f_time_to_failure_hours: Option<f64>,
    /// σ of `f_time_to_failure_hours` in hours.
    #[serde(default)]
    pub sigma_f_time_to_failure_hours: Option<f64>,
}

/// Everything the analysis found for one point in one epoch.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PointAnalysis {
    /// The time-series row (stored).
    pub record: DisplacementRecord,
    /// Role of the point at analysis time.
    pub role: PointRole,
    /// Group of the point.
    pub group: Option<String>,
    /// Whether the point defined the datum of this epoch.
    pub in_datum: bool,
    /// Covariance of (dx, dy, dz) in mm², propagated from both epochs and the datum transformation.
    pub covariance_mm2: [[f64; 3]; 3],
    /// σ of `d_along_mm` in mm.
    pub sigma_along_mm: Option<f64>,
    /// Test statistic d'ᵀΣ⁺d' (χ² distributed with `test_dof` degrees of freedom when the point is stable).
    pub test_statistic: f64,
    /// Rank of the displacement covariance (3 unless degenerate).
    pub test_dof: usize,
    /// Critical value of the test statistic.
    pub critical_value: f64,
    /// Velocity and acceleration (None with fewer than 2 epochs).
    pub kinematics: Option<Kinematics>,
    /// Time-to-failure forecast from the raw series (None unless accelerating).
    pub failure: Option<FailureForecast>,
    /// Filtered displacement along the direction of interest and its σ, mm (None without a
    /// direction or a filtered state).
    #[serde(default)]
    pub filtered_along_mm: Option<(f64, f64)>,
    /// Time-to-failure forecast from the filtered velocities (None unless accelerating).
    #[serde(default)]
    pub filtered_failure: Option<FailureForecast>,
    /// The targets whose mean series gave `filtered_failure` with this one (not declared as a
    /// block, they move together: `super::pooling`); empty for the point's own forecast.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub pooled_with: Vec<String>,
}

/// Result of the single-point test.
pub(crate) struct PointTest {
    pub statistic: f64,
    pub dof: usize,
    pub critical: f64,
    pub significant: bool,
}

/// `critical3` is the critical value for a regular covariance, 3·F(3, f; confidence), computed once per epoch.
pub(crate) fn point_test(
    d: &Vector3<f64>,
    cov: &Matrix3<f64>,
    confidence: f64,
    variance_dof: Option<f64>,
    critical3: f64,
) -> PointTest {
    // Fast path: a regular 3 × 3 covariance.
    if let Some(ch) = cov.cholesky() {
        let statistic = (d.transpose() * ch.inverse() * d)[(0, 0)];
        return PointTest {
            statistic,
            dof: 3,
            critical: critical3,
            significant: statistic > critical3,
        };
    }
    let m = DMatrix::from_fn(3, 3, |r, c| cov[(r, c)]);
    let Some((inv, rank)) = sym_inverse(&m) else {
        return PointTest {
            statistic: f64::INFINITY,
            dof: 0,
            critical: f64::INFINITY,
            significant: false,
        };
    };
    if rank == 0 {
        return PointTest {
            statistic: 0.0,
            dof: 0,
            critical: f64::INFINITY,
            significant: false,
        };
    }
    let dv = DMatrix::from_fn(3, 1, |r, _| d[r]);
    let statistic = (dv.transpose() * inv * &dv)[(0, 0)];
    let h = rank as f64;
    let critical = h * f_quantile(confidence, h, variance_dof.unwrap_or(f64::INFINITY));
    PointTest {
        statistic,
        dof: rank,
        critical,
        significant: statistic > critical,
    }
}

/// The unit vector of a direction of interest; `None` when it is not [`is_usable_direction`]
/// (every reader of a direction goes through here, so a stored one that the API would now refuse
/// reads as no direction).
pub fn unit_direction(d: [f64; 3]) -> Option<Vector3<f64>> {
    is_usable_direction(d).then(|| {
        let v = Vector3::from(d);
        v / v.norm()
    })
}

/// Why a direction was refused: the API's message for one that fails [`is_usable_direction`].
pub const UNUSABLE_DIRECTION: &str = "direction: three finite numbers, not all zero, whose squares add up to a finite non-zero number (a unit vector such as [0, -0.5, 0.866] is safest)";

/// Whether `d` can serve as a direction of interest: three finite numbers whose length is finite
/// and not zero (nor so small that it underflows), so that `d / |d|` is a unit vector.
pub fn is_usable_direction(d: [f64; 3]) -> bool {
    let length = d.iter().map(|v| v * v).sum::<f64>().sqrt();
    d.iter().all(|v| v.is_finite()) && length.is_finite() && length >= f64::MIN_POSITIVE
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_direction_is_read_as_its_unit_vector_or_not_at_all() {
        let u = unit_direction([0.0, -3.0, 4.0]).unwrap();
        assert!((u - Vector3::new(0.0, -0.6, 0.8)).norm() < 1e-15);
        // tiny but representable: still a direction
        let u = unit_direction([1e-150, 0.0, 0.0]).unwrap();
        assert!((u.x - 1.0).abs() < 1e-15, "{u}");
        for bad in [
            [0.0, 0.0, 0.0],
            [f64::NAN, 1.0, 0.0],
            [f64::INFINITY, 0.0, 0.0],
            [1e308, 1e308, 0.0],
            [1e-170, 0.0, 0.0],
        ] {
            assert_eq!(unit_direction(bad), None, "{bad:?}");
            assert!(!is_usable_direction(bad), "{bad:?}");
        }
    }
}
