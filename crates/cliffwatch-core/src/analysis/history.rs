//! A point's past: the [`History`] of stored displacement records, and what one epoch's analysis
//! reads from it (the samples of the velocity fits, the Kalman filter's input, a record's
//! covariance), with the raw kinematics and forecast over the samples.

use std::collections::HashMap;

use chrono::{DateTime, Utc};
use nalgebra::{Matrix3, Vector3};

use super::displacement::DisplacementRecord;
use super::epoch::AnalysisConfig;
use super::failure::{forecast, FailureForecast};
use super::tracking::Observed;
use super::velocity::{days_between, kinematics_z, Kinematics, Sample};

/// Past displacement records per point name, each list oldest first (records at or after the current
/// epoch's `observed_at` are ignored, so re-analysing an epoch is idempotent). Only the windows are read:
/// the store may pass just the last [`AnalysisConfig::history_epochs`] records or
/// [`AnalysisConfig::history_days`] days per point.
pub type History = HashMap<String, Vec<DisplacementRecord>>;

pub(super) fn samples_of(
    history: Option<&Vec<DisplacementRecord>>,
    now: DateTime<Utc>,
    config: &AnalysisConfig,
) -> Vec<Sample> {
    let Some(h) = history else { return vec![] };
    let end = h.partition_point(|r| r.observed_at < now);
    let past = &h[..end];
    let keep_days = config.history_days();
    let start_days = match keep_days {
        Some(d) => {
            let cutoff = now - chrono::Duration::milliseconds((d * 86_400_000.0).ceil() as i64 + 1);
            past.partition_point(|r| r.observed_at < cutoff)
        }
        None => past.len(),
    };
    let start_epochs = past.len().saturating_sub(config.history_epochs());
    let start = start_days.min(start_epochs);
    past[start..]
        .iter()
        .filter(|r| r.d_mm.is_finite() && r.sigma_mm.is_finite())
        .map(|r| Sample {
            t_days: days_between(now, r.observed_at),
            d_mm: r.d_mm,
            // The reference epoch's own row (0 ± 0: the datum, exact by definition) weighs as
            // the current epoch's sample does: a σ of 0 made the fits' normal equations
            // singular in rounding, and every raw velocity null until it left the window.
            sigma_mm: r.sigma_mm.max(1e-6),
        })
        .collect()
}

/// The 3 × 3 covariance of a stored record (mm²); `None` when it is not positive definite (the
/// reference epoch's own zero row).
pub(super) fn record_covariance(r: &DisplacementRecord) -> Option<Matrix3<f64>> {
    let (xy, xz, yz) = (
        r.cov_dxdy_mm2.unwrap_or(0.0),
        r.cov_dxdz_mm2.unwrap_or(0.0),
        r.cov_dydz_mm2.unwrap_or(0.0),
    );
    let c = Matrix3::new(
        r.sigma_dx_mm.powi(2),
        xy,
        xz,
        xy,
        r.sigma_dy_mm.powi(2),
        yz,
        xz,
        yz,
        r.sigma_dz_mm.powi(2),
    );
    (c.iter().all(|v| v.is_finite()) && c.cholesky().is_some()).then_some(c)
}

/// Index of the first of `past` (a subject's records before `now`, oldest first) that the filter
/// reads: the last [`AnalysisConfig::filter_epochs`] − 1, or those of its forecast bins
/// ([`AnalysisConfig::filter_start`]).
pub(super) fn past_start(
    past: &[DisplacementRecord],
    now: DateTime<Utc>,
    config: &AnalysisConfig,
) -> usize {
    config.filter_start(past.len(), config.filter_epochs.saturating_sub(1), |k| {
        -days_between(now, past[k].observed_at)
    })
}

/// The filter's input from a point's past records (before `now`, those [`past_start`] keeps;
/// rows without a usable covariance are skipped).
pub(super) fn observed_of(
    history: Option<&Vec<DisplacementRecord>>,
    now: DateTime<Utc>,
    config: &AnalysisConfig,
) -> Vec<Observed> {
    let Some(h) = history else { return vec![] };
    let end = h.partition_point(|r| r.observed_at < now);
    let start = past_start(&h[..end], now, config);
    h[start..end]
        .iter()
        .filter_map(|r| {
            let cov = record_covariance(r)?;
            let d = Vector3::new(r.dx_mm, r.dy_mm, r.dz_mm);
            d.iter().all(|v| v.is_finite()).then_some(Observed {
                t_days: days_between(now, r.observed_at),
                d_mm: d,
                cov_mm2: cov,
            })
        })
        .collect()
}

/// Velocity and acceleration of a subject's length series over `config.velocity_window`, and the
/// inverse-velocity forecast while the subject moves `significant`ly and accelerates (the raw
/// kinematics of a point or a block; `z_vel`, `z_acc`: the tests' normal quantiles).
pub(super) fn raw_kinematics(
    samples: &[Sample],
    significant: bool,
    config: &AnalysisConfig,
    z_vel: f64,
    z_acc: f64,
) -> (Option<Kinematics>, Option<FailureForecast>) {
    let kin = kinematics_z(
        samples,
        config.velocity_window,
        config.failure.window,
        z_vel,
        z_acc,
    );
    let failure = match kin {
        Some(k) if k.accelerating && significant => forecast(samples, &config.failure),
        _ => None,
    };
    (kin, failure)
}
