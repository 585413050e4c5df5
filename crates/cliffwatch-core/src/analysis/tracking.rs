//! Filtered kinematics of one subject (a point or a block) at the current epoch: the Kalman filter
//! ([`super::kalman`]) over the subject's displacement series up to the current epoch, and the
//! inverse-velocity forecast once the series shows an onset of acceleration (`super::onset`,
//! [`super::failure`]).
//!
//! The filter runs again over the last [`AnalysisConfig::filter_epochs`] epochs (or forecast
//! bins: [`AnalysisConfig::filter_start`]) at every analysis
//! (no filter state is stored): a recompute or a replay gives bit-identical values, and the
//! filter's memory (a few tens of epochs with the default process noise) is shorter than the
//! window, so the truncation does not show.

use nalgebra::{Matrix3, Vector3};

use super::displacement::FilteredValues;
use super::epoch::AnalysisConfig;
use super::epoch::ForecastMethod;
use super::epoch::Window;
use super::failure::{
    fit_law_to_displacements_3d, forecast_from_velocities, line_fit, FailureForecast,
};
use super::kalman::{filter, smooth, KalmanConfig, KalmanState, Measurement};
use super::linalg::length_of;
use super::onset::{persistently_accelerating, PERSIST_EPOCHS};
use super::onset_law::fit_onset_law;
use super::reversible::{cycle_chi2, moves_backward, slows_down};
use super::stats::normal_quantile;
use super::velocity::{window_slice, Sample};

/// Smallest share of an epoch's variance taken as its own error (an epoch observed with fewer
/// stations than the current one can have a covariance below the shared part).
const OWN_SHARE_FLOOR: f64 = 0.25;

/// Epochs closer in time than this (days, about 0.1 s) are the same instant.
const ORIGIN_EPSILON_DAYS: f64 = 1e-6;

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
/// be normalised); the velocity is taken along it, else along the subject's filtered motion since
/// its origin (`motion_since_origin`; `reference_t_days`: the reference epoch's time relative
/// to the current epoch, days).
/// `shared_mm2`: the share of every epoch's covariance that all epochs have in common (the
/// reference epoch's errors, mm²): the law's fit for the forecast has a free intercept, which
/// absorbs a common error, so it weighs each epoch by the rest, its own error.
/// `None` when the series is empty or the filter refuses it (non-finite or singular input).
pub fn track(
    series: &[Observed],
    direction: Option<Vector3<f64>>,
    process_noise: Option<f64>,
    shared_mm2: Option<Matrix3<f64>>,
    reference_t_days: f64,
    config: &AnalysisConfig,
) -> Option<Tracked> {
    let start = config.filter_start(series.len(), config.filter_epochs.max(2), |k| {
        -series[k].t_days
    });
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
    let (m, m_cov) = motion_since_origin(&states, reference_t_days);
    let (m_len, m_sigma) = length_of(&m, &m_cov);
    let dir = direction.and_then(|v| super::unit_direction(v.into()));
    let u = dir.or_else(|| (m_len > 1e-9).then(|| m / m_len))?;
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
    // A forecast only once the subject has moved significantly; whether it creeps and then
    // accelerates is the forecast's own test (the onset against a straight line). The filter's
    // velocity is not asked to be significant too: along the depth of a long-range network its σ
    // (process noise included) held the forecast back until a day or two before failure.
    let moving = m_len > z * m_sigma;
    let failure = if moving {
        match binned(&meas, config.failure.forecast_bin_hours) {
            // The share all epochs have in common, of a full bin's mean (a partial bin's own
            // error comes out a little larger: conservative).
            Some((bins, m)) => {
                let shared = shared_mm2.map(|s| s / m as f64);
                confirmed_forecast(&bins, &kc, u, shared, config)
            }
            None => confirmed_forecast(&meas, &kc, u, shared_mm2, config),
        }
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

/// `meas` (oldest first, times relative to the current epoch) averaged over bins of
/// `bin_hours` counted back from the current epoch (an epoch k hours back in bin
/// `round(k / bin_hours)`): each bin's mean time and displacement, and the covariance of the
/// mean as if its epochs were independent (`Σ Cᵢ / m²`: the onset test reads a bin's whole
/// error as it reads an epoch's), with the most epochs any bin holds. None when nothing is
/// binned (`bin_hours` ≤ 0, or one epoch per bin): the epochs as they are.
fn binned(meas: &[Measurement], bin_hours: f64) -> Option<(Vec<Measurement>, usize)> {
    if !(bin_hours > 0.0) {
        return None;
    }
    let bin_of = |m: &Measurement| (-m.t_days * 24.0 / bin_hours).round() as i64;
    if meas.windows(2).all(|w| bin_of(&w[0]) != bin_of(&w[1])) {
        return None;
    }
    let mut out: Vec<Measurement> = vec![];
    let mut most = 1;
    let mut k = 0;
    while k < meas.len() {
        let b = bin_of(&meas[k]);
        let end = k + meas[k..].iter().take_while(|m| bin_of(m) == b).count();
        let group = &meas[k..end];
        let m = group.len() as f64;
        most = most.max(group.len());
        let t = group.iter().map(|g| g.t_days).sum::<f64>() / m;
        let d: Vector3<f64> = group
            .iter()
            .map(|g| Vector3::from(g.d_mm))
            .sum::<Vector3<f64>>()
            / m;
        let cov: Matrix3<f64> = group
            .iter()
            .map(|g| Matrix3::from(g.cov_mm2))
            .sum::<Matrix3<f64>>()
            / (m * m);
        out.push(Measurement {
            t_days: t,
            d_mm: d.into(),
            cov_mm2: cov.into(),
        });
        k = end;
    }
    Some((out, most))
}

/// The subject's filtered motion at the current epoch (the last of `states`) since its origin,
/// with its covariance (mm, mm²). The origin is the reference epoch, where the displacement is
/// zero by definition, unless the window holds epochs before the reference (a reference moved
/// later in the series, `reference_t_days` days from the current epoch): then the window's first
/// filtered state, with its covariance added (their correlation left out: the test is
/// conservative). So the direction of the motion, the velocity along it and whether the subject
/// moves do not depend on where in the series the reference lies.
fn motion_since_origin(
    states: &[KalmanState],
    reference_t_days: f64,
) -> (Vector3<f64>, Matrix3<f64>) {
    let pos = |s: &KalmanState| {
        (
            Vector3::from(s.position_mm()),
            Matrix3::from(s.position_covariance_mm2()),
        )
    };
    let Some(now) = states.last() else {
        return (Vector3::zeros(), Matrix3::zeros());
    };
    let (p, pc) = pos(now);
    match states.first() {
        Some(first)
            if states.len() > 1 && first.t_days < reference_t_days - ORIGIN_EPSILON_DAYS =>
        {
            let (p0, pc0) = pos(first);
            (p - p0, pc + pc0)
        }
        _ => (p, pc),
    }
}

/// Earlier epochs a forecast is checked against lie at least this share of
/// `FailureConfig::confirm_hours` apart (the previous epoch always counts): an hourly series
/// refits about five times over the window, not once an hour.
const CONFIRM_SPACING: f64 = 0.25;

/// The forecast at the current epoch ([`forecast_smoothed`]); with
/// `FailureConfig::confirm_hours` > 0, withheld unless the series without the current epoch
/// gives a forecast too, and so does the series ending at each earlier epoch observed within
/// `confirm_hours` of the current one (spaced by [`CONFIRM_SPACING`]), each holding the current
/// failure time inside its 90 % interval, its upper end widened by the hours elapsed since (a
/// missing bound is open). Every fit's hours count from the current epoch: the series' times
/// are relative to it.
fn confirmed_forecast(
    meas: &[Measurement],
    kc: &KalmanConfig,
    u: Vector3<f64>,
    shared_mm2: Option<Matrix3<f64>>,
    config: &AnalysisConfig,
) -> Option<FailureForecast> {
    let now = forecast_smoothed(meas, kc, u, shared_mm2, config)?;
    if looks_reversible(meas, u, shared_mm2, config, &now) {
        return None;
    }
    let confirm_hours = config.failure.confirm_hours;
    if !(confirm_hours > 0.0) {
        return Some(now);
    }
    let mut last_checked: Option<f64> = None;
    let mut failure_times = vec![now.time_to_failure_hours];
    for end in (2..meas.len()).rev() {
        let earlier = &meas[..end];
        // Hours from the earlier epoch to the current one (t_days is relative to the current).
        let elapsed_hours = -earlier[earlier.len() - 1].t_days * 24.0;
        if last_checked.is_some() && elapsed_hours > confirm_hours {
            return Some(with_spread(now, &failure_times, config));
        }
        if last_checked.is_some_and(|h| elapsed_hours - h < CONFIRM_SPACING * confirm_hours) {
            continue;
        }
        last_checked = Some(elapsed_hours);
        // The earlier fit's hours count from the current epoch already (its times are relative
        // to it). A failure time later than the earlier interval by up to the hours elapsed
        // since still agrees (near failure the intervals are a few hours wide and a day's data
        // may push the forecast later); one earlier than it does not: a burst's or a step's
        // first epochs pull the failure time towards now.
        let previous = forecast_smoothed(earlier, kc, u, shared_mm2, config)?;
        failure_times.push(previous.time_to_failure_hours);
        let lower = previous.lower_hours.unwrap_or(0.0);
        let upper = previous.upper_hours.unwrap_or(f64::INFINITY) + elapsed_hours;
        if !(lower..=upper).contains(&now.time_to_failure_hours) {
            return None;
        }
        // Both ways: the earlier failure time inside the current forecast's interval too, so a
        // forecast that lurches earlier (a burst speeding up) does not pass on the earlier
        // forecast's width alone.
        if config.failure.confirm_both_ways {
            let lower = now.lower_hours.unwrap_or(0.0);
            let upper = now.upper_hours.unwrap_or(f64::INFINITY);
            if !(lower..=upper).contains(&previous.time_to_failure_hours) {
                return None;
            }
        }
    }
    // Too few epochs before the current one to confirm it.
    None
}

/// `now` with the spread of the failure times forecast over the confirmation window
/// (`failure_times`, hours from the current epoch, `now`'s first) added to its σ in quadrature,
/// when `FailureConfig::confirm_spread` asks for it: forecasts that keep moving are less
/// certain than each fit says.
fn with_spread(
    now: FailureForecast,
    failure_times: &[f64],
    config: &AnalysisConfig,
) -> FailureForecast {
    let n = failure_times.len();
    if !config.failure.confirm_spread || n < 2 {
        return now;
    }
    let mean = failure_times.iter().sum::<f64>() / n as f64;
    let var = failure_times
        .iter()
        .map(|t| (t - mean).powi(2))
        .sum::<f64>()
        / (n - 1) as f64;
    FailureForecast {
        sigma_hours: (now.sigma_hours.powi(2) + var).sqrt(),
        ..now
    }
    .with_interval()
}

/// The inverse-velocity forecast, once the displacements along `u` show an onset of
/// acceleration over `FailureConfig::acceleration_window` ([`persistently_accelerating`]). By
/// default the onset model with a step allowed, fitted to the same window along `u`
/// ([`fit_onset_law`], each epoch weighed by its own error); with `FailureConfig::method`
/// `displacement`, the law alone fitted to the displacement vectors of the last
/// `FailureConfig::law_window` epochs ([`fit_law_to_displacements_3d`]); with
/// `smoothed_velocity`, Fukuzono's line through the inverse of the smoothed velocities
/// ([`forecast_from_velocities`]).
fn forecast_smoothed(
    meas: &[Measurement],
    kc: &KalmanConfig,
    u: Vector3<f64>,
    shared_mm2: Option<Matrix3<f64>>,
    config: &AnalysisConfig,
) -> Option<FailureForecast> {
    match config.failure.method {
        ForecastMethod::OnsetLaw | ForecastMethod::Displacement => {
            // The onset test, along u with the displacements' whole σ: its Δχ² over a scan of
            // two nonlinear parameters has a heavier tail than χ²(2), and with the own errors
            // alone it raised a false alarm on a still point in the detection benchmark.
            // It must pass on the windows ending at each of the last PERSIST_EPOCHS epochs, and
            // its variance factor (the motion's scatter beyond σ over the long window) is a
            // floor of the short law's.
            let n = window_len(meas, config.failure.acceleration_window);
            let with_earlier = (n + PERSIST_EPOCHS - 1).min(meas.len());
            let (mut t, mut d, mut s) = (vec![], vec![], vec![]);
            for m in &meas[meas.len() - with_earlier..] {
                let c = Matrix3::from(m.cov_mm2);
                t.push(m.t_days);
                d.push(u.dot(&Vector3::from(m.d_mm)));
                s.push((u.transpose() * c * u)[(0, 0)].max(0.0).sqrt());
            }
            let onset = persistently_accelerating(&t, &d, &s, n)?;
            if config.failure.method == ForecastMethod::OnsetLaw {
                let (t, d, s) = own_along(&meas[meas.len() - n..], u, shared_mm2);
                return fit_onset_law(&t, &d, &s).map(|f| f.forecast);
            }
            // The law's fit in three dimensions, weighed by each epoch's own error: its
            // intercept absorbs the error all epochs share.
            let n = window_len(meas, config.failure.law_window);
            let win = &meas[meas.len() - n..];
            let t: Vec<f64> = win.iter().map(|m| m.t_days).collect();
            let d: Vec<Vector3<f64>> = win.iter().map(|m| Vector3::from(m.d_mm)).collect();
            let own: Vec<Matrix3<f64>> = win
                .iter()
                .map(|m| own_covariance(&Matrix3::from(m.cov_mm2), shared_mm2.as_ref()))
                .collect();
            fit_law_to_displacements_3d(&t, &d, &own, u, onset.variance_factor).map(|f| f.forecast)
        }
        ForecastMethod::SmoothedVelocity => {
            let n = window_len(meas, config.failure.window);
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

/// The epochs `meas` along `u`: times (days), displacements (mm) and σ (mm), each epoch
/// weighed by its own error (its covariance less `shared_mm2`): a fit's free intercept absorbs
/// the error all epochs share.
fn own_along(
    meas: &[Measurement],
    u: Vector3<f64>,
    shared_mm2: Option<Matrix3<f64>>,
) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let (mut t, mut d, mut s) = (vec![], vec![], vec![]);
    for m in meas {
        let c = own_covariance(&Matrix3::from(m.cov_mm2), shared_mm2.as_ref());
        t.push(m.t_days);
        d.push(u.dot(&Vector3::from(m.d_mm)));
        s.push((u.transpose() * c * u)[(0, 0)].max(0.0).sqrt());
    }
    (t, d, s)
}

/// z of the tests for a reversal or a slowing within the window (one-sided; many stretches are
/// tested, so more than the usual 2.33).
const REVERSIBLE_Z: f64 = 3.0;

/// Whether the onset law's window along `u` shows the evidence of a reversible motion that
/// `FailureConfig` asks for ([`super::reversible`]): a stretch moving backward, a stretch
/// slower than an earlier one, or creep plus a cycle fitting about as well as the law of `now`.
/// Only for the onset law (`ForecastMethod::OnsetLaw`).
fn looks_reversible(
    meas: &[Measurement],
    u: Vector3<f64>,
    shared_mm2: Option<Matrix3<f64>>,
    config: &AnalysisConfig,
    now: &FailureForecast,
) -> bool {
    let f = &config.failure;
    if f.method != ForecastMethod::OnsetLaw
        || !(f.refuse_backward || f.refuse_slowing || f.cycle_margin.is_some())
    {
        return false;
    }
    let n = window_len(meas, f.acceleration_window);
    let (t, d, s) = own_along(&meas[meas.len() - n..], u, shared_mm2);
    if f.refuse_backward && moves_backward(&t, &d, &s, REVERSIBLE_Z) {
        return true;
    }
    if f.refuse_slowing && slows_down(&t, &d, &s, REVERSIBLE_Z) {
        return true;
    }
    if let Some(margin) = f.cycle_margin {
        let w: Vec<f64> = s.iter().map(|s| 1.0 / (s * s)).collect();
        let Some((chi2_line, _, _)) = line_fit(&t, &d, &w) else {
            return false;
        };
        // The law's χ² from the share of the line's misfit it explains (its r²).
        let chi2_law = (1.0 - now.r2) * chi2_line;
        let factor = (chi2_law / n.saturating_sub(6).max(1) as f64).max(1.0);
        if cycle_chi2(&t, &d, &s).is_some_and(|c| c < chi2_law + margin * factor) {
            return true;
        }
    }
    false
}

/// How many of the newest epochs of `meas` fall in `window` (epochs, or days back from the
/// current one).
fn window_len(meas: &[Measurement], window: Window) -> usize {
    let times: Vec<Sample> = meas
        .iter()
        .map(|m| Sample {
            t_days: m.t_days,
            d_mm: 0.0,
            sigma_mm: 1.0,
        })
        .collect();
    window_slice(&times, window).len()
}

/// An epoch's own error: its covariance `total` less the share `shared` all epochs have in
/// common (mm²). The shared share is scaled down where it would leave less than
/// [`OWN_SHARE_FLOOR`] of the total in some direction (an epoch observed with fewer stations than
/// the current one can have a covariance below the shared part).
fn own_covariance(total: &Matrix3<f64>, shared: Option<&Matrix3<f64>>) -> Matrix3<f64> {
    let Some(shared) = shared else {
        return *total;
    };
    let Some(l) = total.cholesky() else {
        return *total;
    };
    // The shared share relative to the total: L⁻¹ S L⁻ᵀ, whose largest eigenvalue is the
    // largest share of the total variance in any direction.
    let Some(l_inv) = l.l().try_inverse() else {
        return *total;
    };
    let relative = l_inv * shared * l_inv.transpose();
    let largest = relative
        .symmetric_eigenvalues()
        .iter()
        .copied()
        .fold(0.0, f64::max);
    let scale = if largest > 1.0 - OWN_SHARE_FLOOR {
        (1.0 - OWN_SHARE_FLOOR) / largest
    } else {
        1.0
    };
    total - shared * scale
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The smallest eigenvalue of `own` relative to `total` (L⁻¹ own L⁻ᵀ).
    fn smallest_share(own: &Matrix3<f64>, total: &Matrix3<f64>) -> f64 {
        let l_inv = total.cholesky().unwrap().l().try_inverse().unwrap();
        (l_inv * own * l_inv.transpose())
            .symmetric_eigenvalues()
            .iter()
            .copied()
            .fold(f64::INFINITY, f64::min)
    }

    #[test]
    fn own_covariance_removes_the_shared_share_and_keeps_the_floor() {
        let total = Matrix3::new(1.0, 0.2, 0.1, 0.2, 0.5, 0.0, 0.1, 0.0, 4.0);
        // A small shared share is removed whole.
        let small = Matrix3::from_diagonal(&Vector3::new(0.2, 0.1, 1.0));
        let own = own_covariance(&total, Some(&small));
        assert!((own - (total - small)).norm() < 1e-12);
        // One larger than the total in some direction is scaled so that the floor remains.
        let large = Matrix3::from_diagonal(&Vector3::new(2.0, 0.1, 1.0));
        let own = own_covariance(&total, Some(&large));
        let share = smallest_share(&own, &total);
        assert!((share - OWN_SHARE_FLOOR).abs() < 1e-9, "{share}");
        assert!(own.cholesky().is_some());
        // No shared share, or a singular total: the total.
        assert_eq!(own_covariance(&total, None), total);
        let singular = Matrix3::zeros();
        assert_eq!(own_covariance(&singular, Some(&small)), singular);
    }

    fn epoch(hours_back: f64, d: f64, var: f64) -> Measurement {
        Measurement {
            t_days: -hours_back / 24.0,
            d_mm: [d, 0.0, 0.0],
            cov_mm2: (Matrix3::identity() * var).into(),
        }
    }

    /// Epochs at least a bin apart are left alone (a daily series under daily bins, a 12-hourly
    /// one under 12-hour bins: the forecast sees exactly what it saw unbinned); an hourly series
    /// becomes bins of the mean time and displacement, counted back from the current epoch, the
    /// current bin holding the epochs less than half a bin back.
    #[test]
    fn bins_leave_sparse_series_alone_and_average_dense_ones() {
        let daily: Vec<_> = (0..10)
            .rev()
            .map(|k| epoch(24.0 * k as f64, k as f64, 1.0))
            .collect();
        assert!(binned(&daily, 24.0).is_none());
        assert!(binned(&daily, 0.0).is_none());
        let twelve: Vec<_> = (0..10)
            .rev()
            .map(|k| epoch(12.0 * k as f64, 0.0, 1.0))
            .collect();
        assert!(binned(&twelve, 12.0).is_none());
        // 72 hourly epochs, d = hours back: bins 0 (0–11 h), 1 (12–35 h), 2 (36–59 h), 3
        // (60–71 h), oldest first.
        let hourly: Vec<_> = (0..72)
            .rev()
            .map(|k| epoch(k as f64, k as f64, 2.0))
            .collect();
        let (bins, most) = binned(&hourly, 24.0).expect("binned");
        assert_eq!(bins.len(), 4);
        assert_eq!(most, 24);
        let expect = [(60.0, 71.0), (36.0, 59.0), (12.0, 35.0), (0.0, 11.0)];
        for (b, (lo, hi)) in bins.iter().zip(expect) {
            let (mid, m) = (0.5 * (lo + hi), hi - lo + 1.0);
            assert!((b.d_mm[0] - mid).abs() < 1e-9, "{b:?}");
            assert!((b.t_days + mid / 24.0).abs() < 1e-9, "{b:?}");
            assert!((b.cov_mm2[0][0] - 2.0 / m).abs() < 1e-12, "{b:?}");
        }
    }
}
