//! Congruence test of the stable points and localisation of the moving ones.
//!
//! Global test (Pelzer 1971; Caspary 1987 §6; Niemeier 2008 §12.4): after the S-transformation onto the
//! stable points, `Ω = d'ᵀ Q_d'⁺ d'` (equal to vᵀ Σ⁻¹ v of the weighted Helmert fit) with `h = 3m − u`
//! degrees of freedom; the stable points are congruent when `Ω / (h s0²) ≤ F(h, f; 1 − α)` (s0 = 1: the
//! covariances are already scaled by the a-posteriori variance factor; f = ∞ unless configured).
//! Localisation (Niemeier's stepwise exclusion): drop the point whose removal lowers Ω most, re-fit, and
//! repeat until the test passes or too few points are left.

use serde::{Deserialize, Serialize};

use super::datum::{fit_weighted, DatumFit, Differences};
use super::epoch::DatumTransformation;
use super::error::AnalysisError;
use super::stats::f_quantile;

/// One global congruence test.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CongruenceTest {
    /// Stable points taking part.
    pub points: Vec<String>,
    /// Ω = d'ᵀQ⁺d' (dimensionless, σ0 = 1).
    pub omega: f64,
    /// Degrees of freedom h = 3m − u.
    pub dof: usize,
    /// Test statistic Ω / h.
    pub statistic: f64,
    /// Critical value F(h, f; confidence).
    pub critical: f64,
    /// Whether the points are congruent (statistic ≤ critical).
    pub passed: bool,
}

pub(crate) fn test_of(
    diffs: &Differences,
    fit: &DatumFit,
    confidence: f64,
    variance_dof: Option<f64>,
) -> Option<CongruenceTest> {
    if fit.redundancy == 0 {
        return None;
    }
    let h = fit.redundancy as f64;
    let statistic = fit.omega / h;
    let critical = f_quantile(confidence, h, variance_dof.unwrap_or(f64::INFINITY));
    Some(CongruenceTest {
        points: fit.datum.iter().map(|&i| diffs.names[i].clone()).collect(),
        omega: fit.omega,
        dof: fit.redundancy,
        statistic,
        critical,
        passed: statistic <= critical,
    })
}

/// Result of testing and localising: the final fit, the tests in order, the excluded points.
pub(crate) struct Congruence {
    pub fit: DatumFit,
    pub tests: Vec<CongruenceTest>,
    pub excluded: Vec<usize>,
}

pub(crate) fn test_and_localise(
    diffs: &Differences,
    stable: &[usize],
    kind: DatumTransformation,
    confidence: f64,
    variance_dof: Option<f64>,
) -> Result<Congruence, AnalysisError> {
    let mut datum = stable.to_vec();
    let mut fit = fit_weighted(diffs, &datum, kind)?;
    let mut tests = vec![];
    let mut excluded = vec![];
    while let Some(t) = test_of(diffs, &fit, confidence, variance_dof) {
        let passed = t.passed;
        tests.push(t);
        if passed || datum.len() <= kind.min_points() {
            break;
        }
        // Candidate whose exclusion reduces Ω most.
        let mut best: Option<(f64, usize, DatumFit)> = None;
        for k in 0..datum.len() {
            let rest: Vec<usize> = datum
                .iter()
                .enumerate()
                .filter(|&(j, _)| j != k)
                .map(|(_, &i)| i)
                .collect();
            let Ok(f) = fit_weighted(diffs, &rest, kind) else {
                continue;
            };
            let gain = fit.omega - f.omega;
            if best.as_ref().is_none_or(|b| gain > b.0) {
                best = Some((gain, k, f));
            }
        }
        let Some((_, k, f)) = best else { break };
        excluded.push(datum.remove(k));
        fit = f;
    }
    Ok(Congruence {
        fit,
        tests,
        excluded,
    })
}
