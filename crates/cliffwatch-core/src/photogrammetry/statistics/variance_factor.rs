//! The global test on the variance factor (χ², two-sided, 0.1 % in each tail) and the variance the data
//! snooping's statistics rest on: Baarda's w with the a-priori σ when the test accepts it, Pope's
//! τ test with the a-posteriori σ̂0 when it rejects it.

use serde::Serialize;

use crate::photogrammetry::adjust::report::VarianceModel;
use crate::photogrammetry::model::bundle::Bundle;

/// Standard normal quantile of each bound of the global test on the variance factor (0.999: 0.1 %
/// in each tail).
pub(crate) const GLOBAL_TEST_Z: f64 = 3.09;

/// Confidence of the global test, two-sided: 0.1 % in each tail (`GLOBAL_TEST_Z`).
pub const GLOBAL_TEST_CONFIDENCE: f64 = 0.998;

/// The global test of an adjustment: is the variance factor σ̂0²/σ² consistent with the a-priori
/// σ? Two-sided at [`GLOBAL_TEST_CONFIDENCE`], the bounds being χ²(r)/r quantiles (r = the degrees
/// of freedom, at least 2, as the snooping's `variance_model` takes them).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct GlobalTest {
    /// Whether the variance factor lies within the bounds.
    pub accepted: bool,
    /// The variance factor σ̂0²/σ² (dimensionless).
    pub variance_factor: f64,
    /// Lower bound of the variance factor (dimensionless).
    pub lower: f64,
    /// Upper bound of the variance factor (dimensionless).
    pub upper: f64,
    /// Two-sided confidence of the test (0.998: 0.1 % in each tail).
    pub confidence: f64,
}

impl GlobalTest {
    /// The test of a variance factor with `dof` degrees of freedom.
    pub fn of(dof: i64, variance_factor: f64) -> GlobalTest {
        let r = dof.max(2) as f64;
        let lower = chi2_lower(r, GLOBAL_TEST_Z) / r;
        let upper = chi2_upper(r, GLOBAL_TEST_Z) / r;
        GlobalTest {
            accepted: (lower..=upper).contains(&variance_factor),
            variance_factor,
            lower,
            upper,
            confidence: GLOBAL_TEST_CONFIDENCE,
        }
    }
}

/// Upper quantile of χ²(ν) for the standard normal quantile z (Wilson–Hilferty).
pub(crate) fn chi2_upper(nu: f64, z: f64) -> f64 {
    let a = 2.0 / (9.0 * nu);
    nu * (1.0 - a + z * a.sqrt()).powi(3)
}

/// Lower quantile of χ²(ν) for the standard normal quantile z (Wilson–Hilferty).
pub(crate) fn chi2_lower(nu: f64, z: f64) -> f64 {
    chi2_upper(nu, -z)
}

/// Critical value of Pope's τ statistic with `r` degrees of freedom at the level whose normal
/// critical value is `z`: τ = t √r / √(r − 1 + t²) with t the Student quantile of r − 1 degrees of
/// freedom (Pope 1976, eq 17), t from z by the Cornish–Fisher expansion.
pub(crate) fn tau_critical(z: f64, r: f64) -> f64 {
    let nu = (r - 1.0).max(1.0);
    let (z3, z5) = (z.powi(3), z.powi(5));
    let t = z + (z3 + z) / (4.0 * nu) + (5.0 * z5 + 16.0 * z3 + 3.0 * z) / (96.0 * nu * nu);
    let tau = t * (r / (r - 1.0 + t * t)).sqrt();
    // τ is bounded by √r; with almost no redundancy the test degenerates to that bound.
    tau.min(r.sqrt())
}

/// Variance factor beyond which the snooping keeps the a-priori σ although the global test rejects
/// it: an a-priori σ off by more than a factor 2 is taken for a wrong basin or many gross errors,
/// which the capped snooping and the retry from the affine bundle must see, not for a misstated σ.
pub(crate) const MAX_TAU_VARIANCE_FACTOR: f64 = 4.0;

/// The snooping's variance model for the bundle's current solution: a-priori when the global test
/// ([`GlobalTest`]) accepts the variance factor or it exceeds [`MAX_TAU_VARIANCE_FACTOR`], else
/// Pope's τ test with σ̂0. Returns the model and
/// the factor √(variance factor) · τ_crit / `critical_w` by which the critical |w| (formed with the
/// a-priori σ) is widened, and √(variance factor) by which reported w are divided.
pub(crate) fn variance_model(b: &Bundle, dof: i64, critical_w: f64) -> (VarianceModel, f64, f64) {
    let r = dof.max(2) as f64;
    let vf = b.cost() / r;
    if GlobalTest::of(dof, vf).accepted || !(vf > 0.0 && vf <= MAX_TAU_VARIANCE_FACTOR) {
        (VarianceModel::APriori, 1.0, 1.0)
    } else {
        let s = vf.sqrt();
        (
            VarianceModel::APosteriori,
            s * tau_critical(critical_w, r) / critical_w,
            s,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Pope's τ critical value against the Student-t table: t(0.9995; 99) = 3.392 gives
    /// τ = 3.392 √(100 / (99 + 3.392²)) = 3.227 for r = 100; it tends to z for large r and never
    /// exceeds √r.
    /// The bounds against χ² tables: χ²(0.001; 100) = 61.92 and χ²(0.999; 100) = 149.45, so the
    /// variance factor must lie in [0.619, 1.494] at r = 100; they narrow as r grows.
    #[test]
    fn global_test_bounds_match_the_table() {
        let t = GlobalTest::of(100, 1.0);
        assert!(t.accepted);
        assert!((t.lower - 0.619).abs() < 0.005, "{t:?}");
        assert!((t.upper - 1.495).abs() < 0.005, "{t:?}");
        assert!(!GlobalTest::of(100, 1.6).accepted);
        assert!(!GlobalTest::of(100, 0.55).accepted);
        let wide = GlobalTest::of(10_000, 1.0);
        assert!(wide.upper < 1.05 && wide.lower > 0.95, "{wide:?}");
    }

    #[test]
    fn tau_critical_matches_the_table() {
        assert!((tau_critical(3.2905, 100.0) - 3.227).abs() < 0.01);
        assert!((tau_critical(3.2905, 1e6) - 3.2905).abs() < 1e-3);
        assert!(tau_critical(3.2905, 3.0) <= 3f64.sqrt());
        assert!(tau_critical(3.2905, 170.0) < 3.2905);
    }

    /// The global test's two bounds bracket 1 and tighten with the redundancy.
    #[test]
    fn global_test_bounds_bracket_one() {
        for r in [20.0, 170.0, 2000.0] {
            let (lo, hi) = (
                chi2_lower(r, GLOBAL_TEST_Z) / r,
                chi2_upper(r, GLOBAL_TEST_Z) / r,
            );
            assert!(lo < 1.0 && hi > 1.0 && lo > 0.0, "r = {r}: {lo} {hi}");
        }
        let w170 =
            chi2_upper(170.0, GLOBAL_TEST_Z) / 170.0 - chi2_lower(170.0, GLOBAL_TEST_Z) / 170.0;
        let w2000 =
            chi2_upper(2000.0, GLOBAL_TEST_Z) / 2000.0 - chi2_lower(2000.0, GLOBAL_TEST_Z) / 2000.0;
        assert!(w2000 < w170);
    }
}
