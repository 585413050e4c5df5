//! Velocity and acceleration of a point by weighted least squares over a window of epochs.
//!
//! The displacement magnitude `d_mm` of the window's epochs is fitted by a straight line (velocity) and by
//! a parabola (acceleration, over the longer failure window), weights 1/σ², time in days relative to the
//! current epoch. σ of the
//! parameters from the inverted normal matrix, scaled by the a-posteriori variance factor when it exceeds 1
//! (model misfit). The reported velocity is the parabola's slope at the current epoch when the acceleration
//! is significant (a straight line lags behind an accelerating point), else the line's slope.

use chrono::{DateTime, Utc};
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

use super::epoch::Window;

/// One sample of a displacement series: time in days relative to the current epoch (≤ 0), value in mm and
/// its σ in mm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    /// Days relative to the current epoch.
    pub t_days: f64,
    /// Displacement in mm.
    pub d_mm: f64,
    /// σ of the displacement in mm.
    pub sigma_mm: f64,
}

/// A weighted polynomial fit: coefficients (constant first) and their covariance.
#[derive(Debug, Clone)]
pub struct PolyFit {
    /// Coefficients c0 + c1 t + c2 t² (mm, mm/day, mm/day²).
    pub coef: DVector<f64>,
    /// Covariance of the coefficients, scaled by the a-posteriori variance factor vᵀPv / (n − u)
    /// when that exceeds 1.
    pub cov: DMatrix<f64>,
}

/// Weighted least-squares polynomial of `degree` through the samples; `None` when underdetermined.
pub fn fit_polynomial(samples: &[Sample], degree: usize) -> Option<PolyFit> {
    let u = degree + 1;
    let n = samples.len();
    if n < u {
        return None;
    }
    let mut nm = DMatrix::<f64>::zeros(u, u);
    let mut rhs = DVector::<f64>::zeros(u);
    for s in samples {
        let w = 1.0 / s.sigma_mm.max(1e-9).powi(2);
        let row: Vec<f64> = (0..u).map(|k| s.t_days.powi(k as i32)).collect();
        for a in 0..u {
            rhs[a] += w * row[a] * s.d_mm;
            for b in 0..u {
                nm[(a, b)] += w * row[a] * row[b];
            }
        }
    }
    let ch = nm.cholesky()?;
    let coef = ch.solve(&rhs);
    let mut cov = ch.inverse();
    let mut vtpv = 0.0;
    for s in samples {
        let y: f64 = (0..u).map(|k| coef[k] * s.t_days.powi(k as i32)).sum();
        vtpv += ((s.d_mm - y) / s.sigma_mm.max(1e-9)).powi(2);
    }
    let variance_factor = if n > u { vtpv / (n - u) as f64 } else { 1.0 };
    if variance_factor > 1.0 {
        cov *= variance_factor;
    }
    if !coef.iter().chain(cov.iter()).all(|v| v.is_finite()) {
        return None;
    }
    Some(PolyFit { coef, cov })
}

/// Velocity and acceleration of one point at the current epoch.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Kinematics {
    /// Rate of `d_mm` in mm/day.
    pub velocity_mm_per_day: f64,
    /// σ of the velocity in mm/day.
    pub sigma_velocity_mm_per_day: f64,
    /// Acceleration in mm/day² (None with fewer than 3 epochs in the window).
    pub acceleration_mm_per_day2: Option<f64>,
    /// σ of the acceleration in mm/day².
    pub sigma_acceleration_mm_per_day2: Option<f64>,
    /// |v| / σ_v exceeds the two-sided normal quantile at the analysis confidence.
    pub velocity_significant: bool,
    /// The acceleration is positive at the configured one-sided confidence, and the velocity positive.
    pub accelerating: bool,
    /// Epochs in the window.
    pub epochs: usize,
}

/// Selects the samples of the window (samples oldest first, the last one the current epoch).
pub fn window_slice(samples: &[Sample], window: Window) -> &[Sample] {
    match window {
        Window::Epochs(n) => &samples[samples.len().saturating_sub(n)..],
        Window::Days(days) => {
            let start = samples.partition_point(|s| s.t_days < -days - 1e-9);
            &samples[start..]
        }
    }
}

/// Velocity over `window` and acceleration over `acceleration_window` (usually longer: an acceleration needs
/// a longer baseline than a velocity); `None` with fewer than 2 epochs. `z` is the two-sided normal quantile of
/// the velocity test, `z_acc` the one-sided one of the acceleration test (computed once per epoch).
pub fn kinematics_z(
    samples: &[Sample],
    window: Window,
    acceleration_window: Window,
    z: f64,
    z_acc: f64,
) -> Option<Kinematics> {
    let s = window_slice(samples, window);
    let line = fit_polynomial(s, 1)?;
    let sa = window_slice(samples, acceleration_window);
    let parabola = if sa.len() >= 4 {
        fit_polynomial(sa, 2)
    } else {
        None
    };
    let (acc, sacc) = match &parabola {
        Some(p) => (
            Some(2.0 * p.coef[2]),
            Some(2.0 * p.cov[(2, 2)].max(0.0).sqrt()),
        ),
        None => (None, None),
    };
    let acc_sig = matches!((acc, sacc), (Some(a), Some(sa)) if a > z_acc * sa && sa.is_finite());
    let (v, sv) = match (&parabola, acc_sig) {
        (Some(p), true) => (p.coef[1], p.cov[(1, 1)].max(0.0).sqrt()),
        _ => (line.coef[1], line.cov[(1, 1)].max(0.0).sqrt()),
    };
    Some(Kinematics {
        velocity_mm_per_day: v,
        sigma_velocity_mm_per_day: sv,
        acceleration_mm_per_day2: acc,
        sigma_acceleration_mm_per_day2: sacc,
        velocity_significant: v.abs() > z * sv,
        accelerating: acc_sig && v > 0.0,
        epochs: s.len(),
    })
}

/// Days from `from` to `to` (fractional).
pub fn days_between(from: DateTime<Utc>, to: DateTime<Utc>) -> f64 {
    (to - from).num_milliseconds() as f64 / 86_400_000.0
}
