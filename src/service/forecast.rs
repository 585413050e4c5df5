//! The forecast failure time of a subject (a point or a block) as every page and the API state
//! it: the time to failure of its latest row (filtered where the filter has one, as the rules
//! read it by default), its ±2σ interval and the one-sided bound the time-to-failure rules read
//! ("failure likely before"), counted from the row's epoch, not from now. Pure.

use crate::store::displacements::Displacement;
use crate::store::parse_timestamp;

/// Time to failure and its σ (h) of `d`: the filtered forecast, else the raw one.
pub fn ttf(d: &Displacement) -> Option<(f64, Option<f64>)> {
    match d.f_time_to_failure_hours.filter(|h| h.is_finite()) {
        Some(h) => Some((h, d.sigma_f_time_to_failure_hours)),
        None => d
            .time_to_failure_hours
            .filter(|h| h.is_finite())
            .map(|h| (h, d.time_to_failure_sigma_hours)),
    }
}

/// Whether the pages state a forecast of `h` hours with σ `s` (h; unknown: 0): its one-sided
/// upper bound lies within a week ([`cliffwatch_core::analysis::failure::stated`]); otherwise "no
/// forecast yet".
pub fn stated(h: f64, s: Option<f64>) -> bool {
    cliffwatch_core::analysis::failure::stated(h, s.unwrap_or(0.0))
}

/// A forecast failure time as the pages state it (s since 1970).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FailureTime {
    /// The forecast failure time.
    pub at: f64,
    /// Lower end of its ±2σ interval (not before the epoch it counts from).
    pub lower: f64,
    /// Upper end of its ±2σ interval.
    pub upper: f64,
    /// The one-sided upper bound at [`cliffwatch_core::analysis::failure::BOUND_CONFIDENCE`]: failure is
    /// likely before it.
    pub likely_before: f64,
}

/// The forecast failure time of `d` with its ±2σ interval and its one-sided bound, counted from
/// `d`'s epoch; None without a forecast or for one whose bound is beyond a week ("no forecast
/// yet", [`stated`]).
pub fn failure_time(d: &Displacement) -> Option<FailureTime> {
    let (h, s) = ttf(d)?;
    if !stated(h, s) {
        return None;
    }
    let t0 = parse_timestamp(&d.observed_at)?.timestamp() as f64;
    let s = s.filter(|s| s.is_finite()).unwrap_or(0.0);
    let bound = cliffwatch_core::analysis::failure::upper_bound_hours(
        h,
        s,
        cliffwatch_core::analysis::failure::BOUND_CONFIDENCE,
    )?;
    let tf = t0 + h * 3600.0;
    Some(FailureTime {
        at: tf,
        lower: (tf - 2.0 * s * 3600.0).max(t0),
        upper: tf + 2.0 * s * 3600.0,
        likely_before: t0 + bound * 3600.0,
    })
}
