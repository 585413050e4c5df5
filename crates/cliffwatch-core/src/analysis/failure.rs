//! Time to failure by the inverse-velocity method (Fukuzono 1985, "A new method for predicting the
//! failure time of a slope"; Voight 1988; Rose & Hungr 2007, *Int. J. Rock Mech. Min. Sci.* 44).
//!
//! In the tertiary creep before failure the velocity grows like `v ∝ 1/(t_f − t)`, so `1/v` falls linearly
//! to zero at the failure time `t_f`. Velocities are smoothed (least-squares slope over a few consecutive
//! epochs, placed at their mean time), `1/v` is fitted by a straight line over the window, and `t_f` is
//! where the line reaches zero. A forecast is made only while the point accelerates (see
//! [`super::velocity::Kinematics::accelerating`]) and the line falls.

use nalgebra::{Matrix3, Matrix6, Vector3, Vector6};
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
    /// Lower end of the 90 % interval of the failure time, hours from the current epoch (≥ 0).
    #[serde(default)]
    pub lower_hours: Option<f64>,
    /// Upper end of the 90 % interval of the failure time, hours from the current epoch.
    #[serde(default)]
    pub upper_hours: Option<f64>,
}

/// Δχ² by which the inverse-velocity law must fit the displacements better than a straight line
/// (χ²(1) at 99.9 %): on still points a chance curvature of the last epochs must not make a
/// forecast (the detection benchmark found one false alarm in 20 still series at 99 %).
const LAW_AGAINST_LINE: f64 = 10.83;

/// Two-sided 90 % normal quantile of the forecast interval.
const INTERVAL_Z: f64 = 1.6449;

/// One-sided confidence of the failure-time bound: the default of time-to-failure rules
/// (`alerts::FORECAST_CONFIDENCE`) and the bound the pages state ("failure likely before …").
pub const BOUND_CONFIDENCE: f64 = 0.95;

/// Hours beyond which a forecast's upper bound tells staff nothing they can act on: the pages
/// say "no forecast yet" (a week; the default time-to-failure rule alarms below 96 h).
pub const NO_FORECAST_BEYOND_HOURS: f64 = 168.0;

/// The one-sided upper confidence bound of a time to failure of `hours` with σ `sigma_hours` at
/// `confidence` in (0.5, 1): `hours + z·σ` hours from the epoch (z the normal quantile), the
/// answer to "is failure likely within the next N hours?". A wide interval whose upper bound is
/// near is still near: 26 ± 35 h is failure likely within 84 h at 95 %. None for non-finite
/// input, a negative σ or a confidence out of range.
pub fn upper_bound_hours(hours: f64, sigma_hours: f64, confidence: f64) -> Option<f64> {
    let ok = hours.is_finite()
        && sigma_hours.is_finite()
        && sigma_hours >= 0.0
        && confidence > 0.5
        && confidence < 1.0;
    ok.then(|| hours + super::stats::normal_quantile(confidence) * sigma_hours)
}

/// Whether the pages state a forecast of `hours` with σ `sigma_hours`: its upper bound at
/// [`BOUND_CONFIDENCE`] exists and lies within [`NO_FORECAST_BEYOND_HOURS`]; otherwise "no
/// forecast yet". The pages' choice only: rules read every forecast through its bound.
pub fn stated(hours: f64, sigma_hours: f64) -> bool {
    upper_bound_hours(hours, sigma_hours, BOUND_CONFIDENCE)
        .is_some_and(|u| u <= NO_FORECAST_BEYOND_HOURS)
}

impl FailureForecast {
    pub(super) fn with_interval(mut self) -> Self {
        self.lower_hours =
            Some((self.time_to_failure_hours - INTERVAL_Z * self.sigma_hours).max(0.0));
        self.upper_hours = Some(self.time_to_failure_hours + INTERVAL_Z * self.sigma_hours);
        self
    }
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
        lower_hours: None,
        upper_hours: None,
    }
    .with_interval();
    out.time_to_failure_hours.is_finite().then_some(out)
}

/// Forecast from filtered or smoothed velocities (Fukuzono 1985 on the Kalman smoother's
/// velocities, [`super::kalman`]): `t_days` ≤ 0 relative to the current epoch (oldest first),
/// velocities in mm/day along the direction of motion with their σ.
///
/// `1/v` is fitted by a straight line `a + b t`, weighted by `1/σ(1/v)²` with `σ(1/v) = σ_v/v²`;
/// the failure time is where the line reaches zero, `t_f = −a/b`, its σ propagated from the
/// line's covariance, scaled by the a-posteriori variance factor when that exceeds 1 (smoothed
/// velocities are correlated, so the factor is a floor, not an estimate). The forecast is
/// refused (None) while the fit is poor: fewer than 4 velocities significantly positive (v > 2σ)
/// in the window, a line that does not fall significantly (b + 2σ_b ≥ 0), or R² below
/// `config.min_r2`.
pub fn forecast_from_velocities(
    t_days: &[f64],
    v_mm_per_day: &[f64],
    sigma_v: &[f64],
    config: &FailureConfig,
) -> Option<FailureForecast> {
    let mut rows = vec![];
    for ((&t, &v), &s) in t_days.iter().zip(v_mm_per_day).zip(sigma_v) {
        if !(t.is_finite() && v.is_finite() && s > 0.0 && s.is_finite() && v > 2.0 * s) {
            continue;
        }
        let y = 1.0 / v;
        let sy = s / (v * v);
        rows.push((t, y, 1.0 / (sy * sy)));
    }
    let n = rows.len();
    if n < 4 {
        return None;
    }
    let sw: f64 = rows.iter().map(|r| r.2).sum();
    let tm = rows.iter().map(|r| r.2 * r.0).sum::<f64>() / sw;
    let ym = rows.iter().map(|r| r.2 * r.1).sum::<f64>() / sw;
    let stt: f64 = rows.iter().map(|r| r.2 * (r.0 - tm).powi(2)).sum();
    let sty: f64 = rows.iter().map(|r| r.2 * (r.0 - tm) * (r.1 - ym)).sum();
    let syy: f64 = rows.iter().map(|r| r.2 * (r.1 - ym).powi(2)).sum();
    if !(stt > 0.0) || !(syy > 0.0) {
        return None;
    }
    let b = sty / stt;
    let a = ym - b * tm;
    // Weighted residuals and the variance factor (≥ 1).
    let vtpv: f64 = rows.iter().map(|r| r.2 * (r.1 - a - b * r.0).powi(2)).sum();
    let factor = (vtpv / (n as f64 - 2.0)).max(1.0);
    // Covariance of (a, b) about the weighted mean time: var(b) = f/stt, var(ā) = f/sw.
    let var_b = factor / stt;
    let var_a = factor * (1.0 / sw + tm * tm / stt);
    let cov_ab = -factor * tm / stt;
    if !(b + 2.0 * var_b.sqrt() < 0.0) {
        return None;
    }
    let r2 = sty * sty / (stt * syy);
    if r2 < config.min_r2 {
        return None;
    }
    let tf_days = -a / b;
    let (da, db) = (-1.0 / b, a / (b * b));
    let var_tf = da * da * var_a + db * db * var_b + 2.0 * da * db * cov_ab;
    let out = FailureForecast {
        time_to_failure_hours: (tf_days * 24.0).max(0.0),
        sigma_hours: var_tf.max(0.0).sqrt() * 24.0,
        r2,
        velocities: n,
        lower_hours: None,
        upper_hours: None,
    }
    .with_interval();
    (out.time_to_failure_hours.is_finite() && out.sigma_hours.is_finite()).then_some(out)
}

/// Weighted least squares of `d = a − B ln(t_f − t)` for a fixed failure time `tf` (days, after every
/// sample): returns (χ², a, B).
fn log_fit(t: &[f64], d: &[f64], w: &[f64], tf: f64) -> Option<(f64, f64, f64)> {
    let x: Vec<f64> = t.iter().map(|&ti| -(tf - ti).ln()).collect();
    line_fit(&x, d, w)
}

/// Weighted straight line `d = a + B x`: (χ², a, B).
pub(super) fn line_fit(x: &[f64], d: &[f64], w: &[f64]) -> Option<(f64, f64, f64)> {
    let sw: f64 = w.iter().sum();
    let xm = x.iter().zip(w).map(|(x, w)| w * x).sum::<f64>() / sw;
    let dm = d.iter().zip(w).map(|(d, w)| w * d).sum::<f64>() / sw;
    let sxx: f64 = x.iter().zip(w).map(|(x, w)| w * (x - xm).powi(2)).sum();
    let sxd: f64 = x
        .iter()
        .zip(d)
        .zip(w)
        .map(|((x, d), w)| w * (x - xm) * (d - dm))
        .sum();
    if !(sxx > 0.0) {
        return None;
    }
    let b = sxd / sxx;
    let a = dm - b * xm;
    let chi2 = x
        .iter()
        .zip(d)
        .zip(w)
        .map(|((x, d), w)| w * (d - a - b * x).powi(2))
        .sum();
    Some((chi2, a, b))
}

/// The inverse-velocity law fitted to the displacements, and how much better it fits than a
/// straight line.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LawFit {
    /// The forecast of the fit.
    pub forecast: FailureForecast,
    /// χ² of the straight line minus χ² of the law (≥ 0 up to rounding; dimensionless).
    pub gain_over_line: f64,
}

/// Forecast from the displacements themselves (the inverse-velocity law integrated, Fukuzono
/// 1985; Voight 1988), refused unless the law fits the window significantly better than a
/// straight line (constant velocity; Δχ² > 10.83, 99.9 % with one degree of freedom). See
/// [`fit_law_to_displacements`] for the fit.
pub fn forecast_from_displacements(
    t_days: &[f64],
    d_mm: &[f64],
    sigma_mm: &[f64],
) -> Option<FailureForecast> {
    fit_law_to_displacements(t_days, d_mm, sigma_mm)
        .filter(|f| f.gain_over_line > LAW_AGAINST_LINE)
        .map(|f| f.forecast)
}

/// First failure time the scans consider, in days after the last sample (1 hour).
const SCAN_START_DAYS: f64 = 1.0 / 24.0;
/// Last failure time the scans consider, in days after the last sample.
const SCAN_END_DAYS: f64 = 1000.0;

/// The failure time, in days after the last sample, that minimises `chi2`: a scan of `nodes + 1`
/// log-spaced values from [`SCAN_START_DAYS`] to [`SCAN_END_DAYS`], then `iterations`
/// golden-section steps in ln t_f between the best node's neighbours. None when no node gives a
/// finite χ². Shared by the law's fit and the onset test ([`super::onset`]).
pub(super) fn min_over_failure_time(
    nodes: usize,
    iterations: usize,
    mut chi2: impl FnMut(f64) -> f64,
) -> Option<f64> {
    let ratio = SCAN_END_DAYS / SCAN_START_DAYS;
    let grid: Vec<f64> = (0..=nodes)
        .map(|k| SCAN_START_DAYS * ratio.powf(k as f64 / nodes as f64))
        .collect();
    let (kbest, best) = grid
        .iter()
        .enumerate()
        .map(|(k, &g)| (k, chi2(g)))
        .min_by(|a, b| a.1.total_cmp(&b.1))?;
    if !best.is_finite() {
        return None;
    }
    let (mut lo, mut hi) = (
        grid[kbest.saturating_sub(1)].ln(),
        grid[(kbest + 1).min(nodes)].ln(),
    );
    let g = 0.618_033_988_75;
    for _ in 0..iterations {
        let (m1, m2) = (hi - g * (hi - lo), lo + g * (hi - lo));
        if chi2(m1.exp()) < chi2(m2.exp()) {
            hi = m2;
        } else {
            lo = m1;
        }
    }
    Some((0.5 * (lo + hi)).exp())
}

/// The inverse-velocity law integrated and fitted to the displacements: with `v = B/(t_f − t)`
/// the displacement along the direction of motion is `d(t) = a − B ln(t_f − t)`. `t_days` ≤ 0
/// relative to the current epoch (oldest first), `d_mm` along the direction of motion with σ
/// `sigma_mm`.
///
/// For each trial failure time the model is linear in (a, B), so t_f is found by minimising the
/// weighted χ² over t_f (a log-spaced scan from 1 hour to 1000 days, then golden-section
/// refinement). The fit does not differentiate noisy data, so it neither lags nor needs smoothing.
/// Its σ comes from the χ² profile (Δχ² = 1, scaled by the variance factor when that exceeds 1),
/// the 90 % interval from Δχ² = 2.71. None for fewer than 5 epochs, B not positive, a line that
/// does not advance, or a failure time at either end of the scan (1 hour, 1000 days). Whether the law is shown at all is the
/// caller's test: [`LawFit::gain_over_line`] here, or the onset of acceleration over a longer
/// window (`super::onset`).
pub fn fit_law_to_displacements(t_days: &[f64], d_mm: &[f64], sigma_mm: &[f64]) -> Option<LawFit> {
    let mut t = vec![];
    let mut d = vec![];
    let mut w = vec![];
    for ((&ti, &di), &si) in t_days.iter().zip(d_mm).zip(sigma_mm) {
        if ti.is_finite() && di.is_finite() && si.is_finite() && si > 0.0 {
            t.push(ti);
            d.push(di);
            w.push(1.0 / (si * si));
        }
    }
    let n = t.len();
    if n < 5 {
        return None;
    }
    let t_last = t.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let (chi2_line, _, v_line) = line_fit(&t, &d, &w)?;
    if !(v_line > 0.0) {
        return None;
    }
    let chi = |tf: f64| log_fit(&t, &d, &w, t_last + tf).map_or(f64::INFINITY, |f| f.0);
    // d = a − B ln(t_f − t) is fitted as d = a + B x with x = −ln(t_f − t): B = slope > 0.
    let advances = |tf: f64| log_fit(&t, &d, &w, t_last + tf).is_some_and(|f| f.2 > 0.0);
    let misfit = |tf: f64| chi(tf) / (n - 3) as f64;
    profile_law(t_last, chi2_line, n, chi, advances, misfit)
}

/// The law's failure time from its χ² profile `chi` (a function of the failure time in days
/// after the last sample, `t_last` days): the minimum, its σ from Δχ² = 1 and the 90 % interval
/// from Δχ² = 2.71, both scaled by the variance factor `misfit(t_f)` at the minimum when that
/// exceeds 1. `advances` says whether the law's amplitude at a failure time points forward;
/// `chi2_line` is the straight line's χ², `epochs` the number of epochs fitted. Shared by the fit
/// along one direction ([`fit_law_to_displacements`]) and the fit in three dimensions
/// ([`fit_law_to_displacements_3d`]).
pub(super) fn profile_law(
    t_last: f64,
    chi2_line: f64,
    epochs: usize,
    chi: impl Fn(f64) -> f64,
    advances: impl Fn(f64) -> bool,
    misfit: impl Fn(f64) -> f64,
) -> Option<LawFit> {
    let tf = min_over_failure_time(120, 60, &chi)?;
    let chi2 = chi(tf);
    let factor = misfit(tf);
    // A minimum at either end of the scan is no fit: at the far end the law is a straight line;
    // at the near end χ² keeps falling as the failure time reaches the last epoch, whose own
    // offset the law's singular term then absorbs (a target knocked forward, a cycle's fast day:
    // "failure in 1 h" at every epoch for days, ttf_benchmark's step and cyclic series).
    let at_an_end = tf >= SCAN_END_DAYS * 0.999 || tf <= SCAN_START_DAYS * 1.001;
    if !chi2.is_finite() || !advances(tf) || at_an_end || !factor.is_finite() {
        return None;
    }
    // A variance factor estimated from the fit's own residuals (over `epochs − 3` degrees of
    // freedom along the motion) is itself uncertain: the interval then takes Student's t
    // instead of the normal quantile, (t₀.₉₇₅/z₀.₉₇₅)² on the Δχ² (1.28 at 9 degrees of freedom).
    let t_widening = if factor > 1.0 {
        let nu = epochs.saturating_sub(3).max(1) as f64;
        (student_t_975(nu) / 1.959_964).powi(2)
    } else {
        1.0
    };
    let factor = factor.max(1.0) * t_widening;
    // Profile interval: where χ² rises by Δ·factor on either side of the minimum.
    let bound = |delta: f64, up: bool| -> f64 {
        let target = chi2 + delta * factor;
        let (mut a, mut b) = if up {
            (tf.ln(), (tf * 1e3).ln())
        } else {
            ((1e-4f64).ln(), tf.ln())
        };
        // Bisection on the side where χ² crosses the target (monotone there).
        let f = |x: f64| chi(x.exp()) - target;
        if up && f(b) < 0.0 {
            return b.exp();
        }
        if !up && f(a) < 0.0 {
            return a.exp();
        }
        for _ in 0..60 {
            let m = 0.5 * (a + b);
            let inside = f(m) < 0.0;
            if inside == up {
                a = m;
            } else {
                b = m;
            }
        }
        (0.5 * (a + b)).exp()
    };
    let (s_lo, s_hi) = (bound(1.0, false), bound(1.0, true));
    let (i_lo, i_hi) = (bound(2.706, false), bound(2.706, true));
    let hours = |days: f64| (days + t_last) * 24.0;
    // The share of the straight line's misfit the law explains.
    let r2 = 1.0 - chi2 / chi2_line.max(1e-300);
    let out = FailureForecast {
        time_to_failure_hours: hours(tf).max(0.0),
        sigma_hours: 0.5 * (s_hi - s_lo) * 24.0,
        r2,
        velocities: epochs,
        lower_hours: Some(hours(i_lo).max(0.0)),
        upper_hours: Some(hours(i_hi)),
    };
    (out.time_to_failure_hours.is_finite() && out.sigma_hours.is_finite()).then_some(LawFit {
        forecast: out,
        gain_over_line: chi2_line - chi2,
    })
}

/// The 97.5 % quantile of Student's t with `nu` degrees of freedom (from the F quantile:
/// t² = F(1, ν)).
fn student_t_975(nu: f64) -> f64 {
    super::stats::f_quantile(0.95, 1.0, nu).max(0.0).sqrt()
}

/// Weighted least squares of the displacement vectors `d = a + b x` (a, b in mm, x
/// dimensionless or days), each epoch weighted by the inverse of its 3 × 3 covariance `w`:
/// (χ², a, b). x is centred before the solve, so the normal equations stay well conditioned.
fn line_fit_3d(
    x: &[f64],
    d: &[Vector3<f64>],
    w: &[Matrix3<f64>],
) -> Option<(f64, Vector3<f64>, Vector3<f64>)> {
    let xm = x.iter().sum::<f64>() / x.len().max(1) as f64;
    let mut n = Matrix6::<f64>::zeros();
    let mut r = Vector6::<f64>::zeros();
    for ((&xi, di), wi) in x.iter().zip(d).zip(w) {
        let xc = xi - xm;
        let wd = wi * di;
        let mut top = n.fixed_view_mut::<3, 3>(0, 0);
        top += wi;
        let mut off = n.fixed_view_mut::<3, 3>(0, 3);
        off += wi * xc;
        let mut low = n.fixed_view_mut::<3, 3>(3, 3);
        low += wi * (xc * xc);
        let mut r_top = r.fixed_rows_mut::<3>(0);
        r_top += wd;
        let mut r_low = r.fixed_rows_mut::<3>(3);
        r_low += wd * xc;
    }
    let upper = n.fixed_view::<3, 3>(0, 3).into_owned();
    n.fixed_view_mut::<3, 3>(3, 0).copy_from(&upper.transpose());
    let sol = n.cholesky()?.solve(&r);
    let b: Vector3<f64> = sol.fixed_rows::<3>(3).into_owned();
    let a_c: Vector3<f64> = sol.fixed_rows::<3>(0).into_owned();
    let chi2 = x
        .iter()
        .zip(d)
        .zip(w)
        .map(|((&xi, di), wi)| {
            let e = di - a_c - b * (xi - xm);
            (e.transpose() * wi * e)[(0, 0)]
        })
        .sum();
    Some((chi2, a_c - b * xm, b))
}

/// The inverse-velocity law fitted to the displacement vectors themselves: `d(t) = a − b ln(t_f −
/// t)` with a, b in three dimensions, each epoch weighted by the inverse of its covariance
/// `cov_mm2` (mm²). `t_days` ≤ 0 relative to the current epoch (oldest first).
///
/// The law's failure time does not depend on the direction of the motion, and the direction
/// need not be known: b is fitted. Along a single direction the depth's σ (several times that
/// across the line of sight at long range) swamps a motion that is mostly in depth, while the
/// small part of it across the line of sight is measured well; the fit in three dimensions
/// weighs each component by its precision and keeps both. `forward`: the direction of motion
/// (need not be normalised); the law's amplitude b and the straight line's velocity must point
/// along it. σ and interval as in [`fit_law_to_displacements`] (Δχ² = 1 and 2.71 of the profile),
/// scaled by the largest of three variance factors: the fit's over its 3n − 7 degrees of freedom;
/// that of its residuals along `forward` over n − 3 (a motion that scatters along its direction
/// shows there, diluted in the three-dimensional one by the two components that fit); and
/// `history_factor`, the scatter of the subject's own longer history (the onset test's, over 40
/// epochs: the law's 12 epochs alone estimate it poorly). None for fewer than 5 epochs, a singular
/// covariance, or the refusals of the fit along one direction.
pub fn fit_law_to_displacements_3d(
    t_days: &[f64],
    d_mm: &[Vector3<f64>],
    cov_mm2: &[Matrix3<f64>],
    forward: Vector3<f64>,
    history_factor: f64,
) -> Option<LawFit> {
    let mut t = vec![];
    let mut d = vec![];
    let mut w = vec![];
    for ((&ti, di), ci) in t_days.iter().zip(d_mm).zip(cov_mm2) {
        if ti.is_finite() && di.iter().all(|v| v.is_finite()) {
            let wi = ci
                .try_inverse()
                .filter(|m| m.iter().all(|v| v.is_finite()))?;
            t.push(ti);
            d.push(*di);
            w.push(wi);
        }
    }
    let n = t.len();
    if n < 5 {
        return None;
    }
    let t_last = t.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let (chi2_line, _, v_line) = line_fit_3d(&t, &d, &w)?;
    if !(v_line.dot(&forward) > 0.0) {
        return None;
    }
    let fit = |tf: f64| {
        let x: Vec<f64> = t.iter().map(|&ti| -(t_last + tf - ti).ln()).collect();
        line_fit_3d(&x, &d, &w)
    };
    let chi = |tf: f64| fit(tf).map_or(f64::INFINITY, |f| f.0);
    let advances = |tf: f64| fit(tf).is_some_and(|f| f.2.dot(&forward) > 0.0);
    let u = forward.try_normalize(1e-12)?;
    let misfit = |tf: f64| {
        let Some((chi2, a, b)) = fit(tf) else {
            return f64::NAN;
        };
        let along: f64 = t
            .iter()
            .zip(&d)
            .zip(&w)
            .map(|((&ti, di), wi)| {
                let x = -(t_last + tf - ti).ln();
                let r = u.dot(&(di - a - b * x));
                // σ² along u of the epoch: uᵀ C u with C = w⁻¹
                let var = wi
                    .try_inverse()
                    .map_or(f64::NAN, |c| (u.transpose() * c * u)[(0, 0)]);
                r * r / var
            })
            .sum();
        (chi2 / (3 * n - 7) as f64)
            .max(along / (n - 3) as f64)
            .max(history_factor)
    };
    profile_law(t_last, chi2_line, n, chi, advances, misfit)
}
