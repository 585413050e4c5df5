//! Time to failure by the inverse-velocity method (Fukuzono 1985, "A new method for predicting the
//! failure time of a slope"; Voight 1988; Rose & Hungr 2007, *Int. J. Rock Mech. Min. Sci.* 44).
//!
//! In the tertiary creep before failure the velocity grows like `v ∝ 1/(t_f − t)`, so `1/v` falls linearly
//! to zero at the failure time `t_f`. Velocities are smoothed (least-squares slope over a few consecutive
//! epochs, placed at their mean time), `1/v` is fitted by a straight line over the window, and `t_f` is
//! where the line reaches zero. A forecast is made only while the point accelerates (see
//! [`super::velocity::Kinematics::accelerating`]) and the line falls.

use serde::{Deserialize, Serialize};

use super::epoch::FailureConfig;
use super::velocity::{fit_polynomial, window_slice, Sample};

/// A failure-time forecast.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FailureForecast {
    /// Hours from the current epoch to the predicted failure (≥ 0).
    pub time_to_failure_hours: f64,
    /// σ of the forecast in hours (propagated from the line's parameters).
    pub sigma_hours: f64,
    /// Coefficient of determination R² of the 1/v line.
    pub r2: f64,
    /// Smoothed velocities used.
    pub velocities: usize,
}

/// Forecast from the displacement samples (oldest first, the current epoch last, t = 0).
pub fn forecast(samples: &[Sample], config: &FailureConfig) -> Option<FailureForecast> {
    let k = config.smoothing_epochs.max(2);
    // Velocities need k − 1 earlier epochs before the window's first.
    let win = window_slice(samples, config.window);
    let first = samples.len() - win.len();
    let start = first.saturating_sub(k - 1);
    let s = &samples[start..];
    let mut t = vec![];
    let mut inv = vec![];
    for j in (k - 1)..s.len() {
        let seg = &s[j + 1 - k..=j];
        let line = fit_polynomial(seg, 1)?;
        let v = line.coef[1];
        if v > 0.0 {
            t.push(seg.iter().map(|x| x.t_days).sum::<f64>() / k as f64);
            inv.push(1.0 / v);
        }
    }
    let n = t.len();
    if n < 3 {
        return None;
    }
    // Weighted line y = a + b t with weights v² (residuals in velocity terms: v (a + b t) − 1), so the
    // noisy 1/v of slow epochs does not dominate the fast, well-determined ones.
    let w: Vec<f64> = inv.iter().map(|y| 1.0 / (y * y)).collect();
    let sw: f64 = w.iter().sum();
    let tm = t.iter().zip(&w).map(|(x, w)| w * x).sum::<f64>() / sw;
    let ym = inv.iter().zip(&w).map(|(y, w)| w * y).sum::<f64>() / sw;
    let stt: f64 = t.iter().zip(&w).map(|(x, w)| w * (x - tm).powi(2)).sum();
    let sty: f64 = t
        .iter()
        .zip(&inv)
        .zip(&w)
        .map(|((x, y), w)| w * (x - tm) * (y - ym))
        .sum();
    let syy: f64 = inv.iter().zip(&w).map(|(y, w)| w * (y - ym).powi(2)).sum();
    if !(stt > 0.0) || !(syy > 0.0) {
        return None;
    }
    let b = sty / stt;
    let a = ym - b * tm;
    if !(b < 0.0) {
        return None;
    }
    let r2 = sty * sty / (stt * syy);
    if r2 < config.min_r2 {
        return None;
    }
    let tf_days = -a / b;
    // σ: weighted residual variance of the line, propagated to t_f = −a/b.
    let nf = n as f64;
    let s2 = (syy - b * sty).max(0.0) / (nf - 2.0) * nf / sw;
    let var_b = s2 / (stt / sw * nf);
    let var_a = s2 * (1.0 / nf + tm * tm / (stt / sw * nf));
    let cov_ab = -s2 * tm / (stt / sw * nf);
    let (da, db) = (-1.0 / b, a / (b * b));
    let var_tf = da * da * var_a + db * db * var_b + 2.0 * da * db * cov_ab;
    let out = FailureForecast {
        time_to_failure_hours: (tf_days * 24.0).max(0.0),
        sigma_hours: var_tf.max(0.0).sqrt() * 24.0,
        r2,
        velocities: n,
    };
    out.time_to_failure_hours.is_finite().then_some(out)
}
