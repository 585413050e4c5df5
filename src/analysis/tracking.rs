//! Filtered kinematics of one subject (a point or a block) at the current epoch: the Kalman filter
//! ([`super::kalman`]) over the subject's displacement series up to the current epoch, and the
//! inverse-velocity forecast once the series shows an onset of acceleration ([`super::onset`],
//! [`super::failure`]).
//!
//! The filter runs again over the last [`AnalysisConfig::filter_epochs`] epochs at every analysis
//! (no filter state is stored): a recompute or a replay gives bit-identical values, and the
//! filter's memory (a few tens of epochs with the default process noise) is shorter than the
//! window, so the truncation does not show.

use nalgebra::{Matrix3, Vector3};

use super::displacement::FilteredValues;
use super::epoch::AnalysisConfig;
use super::epoch::ForecastMethod;
use super::failure::{fit_law_to_displacements, forecast_from_velocities, FailureForecast};
use super::kalman::{filter, smooth, KalmanConfig, Measurement};
use super::onset::accelerating;
use super::stats::normal_quantile;
use super::velocity::{window_slice, Sample};

/// Smallest share of an epoch's variance taken as its own error (an epoch observed with fewer
/// stations than the current one can have a covariance below the shared part).
const OWN_SHARE_FLOOR: f64 = 0.25;

/// One epoch of a subject's displacement series: days relative to the current epoch (≤ 0),
/// displacement in mm and its covariance in mm².
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Observed {
    /// Days relative to the current epoch.
    pub t_days: f64,
    /// Displacement (mm).
    pub d_mm: Vector3<f64>,
    /// Its covariance (mm²).
    pub cov_mm2: Matrix3<f64>,
}

/// What the filter gives for a subject at the current epoch.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tracked {
    /// Filtered values (stored with the record).
    pub values: FilteredValues,
    /// Filtered displacement along the direction of interest and its σ (mm), when one is set.
    pub along_mm: Option<(f64, f64)>,
    /// Inverse-velocity forecast from the smoothed velocities, when the subject accelerates.
    pub failure: Option<FailureForecast>,
}

/// Runs the filter over `series` (oldest first, the current epoch last) with process noise
/// `process_noise` (None: the configuration's). `direction`: the direction of interest (need not
/// be normalised); the velocity is taken along it, else along the filtered displacement.
/// `shared_mm2`: the share of every epoch's covariance that all epochs have in common (the
/// reference epoch's errors, mm²): the law's fit for the forecast has a free intercept, which
/// absorbs a common error, so it weighs each epoch by the rest, its own error.
/// `None` when the series is empty or the filter refuses it (non-finite or singular input).
pub fn track(
    series: &[Observed],
    direction: Option<Vector3<f64>>,
    process_noise: Option<f64>,
    shared_mm2: Option<Matrix3<f64>>,
    config: &AnalysisConfig,
) -> Option<Tracked> {
    let start = series.len().saturating_sub(config.filter_epochs.max(2));
    let series = &series[start..];
    let meas: Vec<Measurement> = series
        .iter()
        .map(|o| Measurement {
            t_days: o.t_days,
            d_mm: o.d_mm.into(),
            cov_mm2: o.cov_mm2.into(),
        })
        .collect();
    let mut kc = config.kalman.clone();
    if let Some(q) = process_noise {
        kc.process_noise = q;
    }
    let states = filter(&meas, &kc).ok()?;
    let now = states.last()?;
    let p = Vector3::from(now.position_mm());
    let pc = Matrix3::from(now.position_covariance_mm2());
    let (f_d, s_d) = now.length();
    let dir = direction
        .filter(|v| v.norm() > 0.0 && v.iter().all(|x| x.is_finite()))
        .map(|v| v / v.norm());
    let u = dir.or_else(|| (p.norm() > 1e-9).then(|| p / p.norm()))?;
    let along = now.along(u.into());
    let sd = |k: usize| pc[(k, k)].max(0.0).sqrt();
    let values = FilteredValues {
        f_dx_mm: p.x,
        f_dy_mm: p.y,
        f_dz_mm: p.z,
        f_d_mm: f_d,
        sigma_f_dx_mm: sd(0),
        sigma_f_dy_mm: sd(1),
        sigma_f_dz_mm: sd(2),
        sigma_f_d_mm: s_d,
        f_velocity_mm_per_day: along.v_mm_per_day,
        sigma_f_velocity_mm_per_day: along.sigma_v_mm_per_day,
        f_acceleration_mm_per_day2: along.a_mm_per_day2,
        sigma_f_acceleration_mm_per_day2: along.sigma_a_mm_per_day2,
        f_time_to_failure_hours: None,
        sigma_f_time_to_failure_hours: None,
    };
    let z = normal_quantile(0.5 + 0.5 * config.confidence);
    // A forecast only while the subject moves significantly; whether it accelerates is the
    // forecast's own test (the law against a straight line).
    let moving = f_d > z * s_d && along.v_mm_per_day > z * along.sigma_v_mm_per_day;
    let failure = if moving {
        forecast_smoothed(&meas, &kc, u, shared_mm2, config)
    } else {
        None
    };
    let mut values = values;
    values.f_time_to_failure_hours = failure.map(|f| f.time_to_failure_hours);
    values.sigma_f_time_to_failure_hours = failure.map(|f| f.sigma_hours);
    Some(Tracked {
        values,
        along_mm: dir.map(|_| (along.d_mm, along.sigma_d_mm)),
        failure,
    })
}

/// The inverse-velocity forecast. By default, once the displacements along `u` show an onset
/// of acceleration over `FailureConfig::acceleration_window` ([`accelerating`]), the law
/// integrated and fitted to the last `FailureConfig::law_window` epochs
/// ([`fit_law_to_displacements`]); with `FailureConfig::method` `smoothed_velocity`, Fukuzono's
/// line through the inverse of the smoothed velocities ([`forecast_from_velocities`]).
fn forecast_smoothed(
    meas: &[Measurement],
    kc: &KalmanConfig,
    u: Vector3<f64>,
    shared_mm2: Option<Matrix3<f64>>,
    config: &AnalysisConfig,
) -> Option<FailureForecast> {
    let shared = shared_mm2.map_or(0.0, |c| (u.transpose() * c * u)[(0, 0)].max(0.0));
    // The window's epochs (the window counts epochs or days back from the current one).
    let times: Vec<Sample> = meas
        .iter()
        .map(|m| Sample {
            t_days: m.t_days,
            d_mm: 0.0,
            sigma_mm: 1.0,
        })
        .collect();
    match config.failure.method {
        ForecastMethod::Displacement => {
            // The displacements along u of the last n epochs, with their σ: of their own errors
            // (`own`, without the shared part) or whole.
            let along = |n: usize, own: bool| {
                let mut out = (vec![], vec![], vec![]);
                for m in &meas[meas.len() - n..] {
                    let c = Matrix3::from(m.cov_mm2);
                    let total = (u.transpose() * c * u)[(0, 0)].max(0.0);
                    out.0.push(m.t_days);
                    out.1.push(u.dot(&Vector3::from(m.d_mm)));
                    let shared = if own { shared } else { 0.0 };
                    out.2
                        .push((total - shared).max(OWN_SHARE_FLOOR * total).sqrt());
                }
                out
            };
            // The onset test weighs by the whole σ: its Δχ² over a scan of two nonlinear
            // parameters has a heavier tail than χ²(2), and with the own errors alone it raised
            // a false alarm on a still point in the detection benchmark. The law's fit, whose
            // intercept absorbs the shared error, weighs by the own errors.
            let (t, d, s) = along(
                window_slice(&times, config.failure.acceleration_window).len(),
                false,
            );
            accelerating(&t, &d, &s)?;
            let (t, d, s) = along(window_slice(&times, config.failure.law_window).len(), true);
            fit_law_to_displacements(&t, &d, &s).map(|f| f.forecast)
        }
        ForecastMethod::SmoothedVelocity => {
            let n = window_slice(&times, config.failure.window).len();
            let smoothed = smooth(meas, kc).ok()?;
            let win = &smoothed[smoothed.len() - n..];
            let (mut t, mut v, mut s) = (vec![], vec![], vec![]);
            for st in win {
                let a = st.along(u.into());
                t.push(st.t_days);
                v.push(a.v_mm_per_day);
                s.push(a.sigma_v_mm_per_day);
            }
            forecast_from_velocities(&t, &v, &s, &config.failure)
        }
    }
}
