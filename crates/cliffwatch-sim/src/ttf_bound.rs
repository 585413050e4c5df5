//! What any forecaster could do on a failing series of [`super::kinematics`]: the Cramér–Rao
//! bound of the failure time, for the time-to-failure benchmark ([`super::ttf_benchmark`]).
//!
//! The forecaster is given every advantage: it sees the block's displacement along its true
//! direction from the first epoch on, knows the noise (white, σ of the motion's scatter and of the
//! measurement together), knows the model (creep, then the inverse-velocity law continuing the
//! creep's velocity, Fukuzono 1985: four parameters a, v₀, t_a, t_f), and the burst of odd seeds
//! and the errors shared by every point on some days are left out. Its failure time then has at
//! best the σ of the bound, `σ²(t_f) = [(Jᵀ J)⁻¹]_{t_f t_f} σ²` (J the model's derivatives at the
//! epochs). The oracle alarms as cliffwatch's rule does, on the one-sided upper bound: at the
//! first epoch where the true time to failure plus `z·σ` (z at the rule's default confidence,
//! [`cliffwatch_core::analysis::failure::BOUND_CONFIDENCE`]) falls below the rule's threshold
//! ([`oracle_alarm_lead_hours`]). No forecaster can alarm earlier on that rule but by chance.

use nalgebra::{Matrix4, Vector4};

use super::kinematics::MotionCase;
use cliffwatch_core::analysis::failure::{upper_bound_hours, BOUND_CONFIDENCE};

/// The failing block's displacement along its direction at `t` days (mm): creep at `v0` mm/day,
/// then from the onset `ta` the inverse-velocity law to the failure at `tf` (as
/// [`super::kinematics`] draws it, without its burst).
fn creep_then_law(t: f64, a: f64, v0: f64, ta: f64, tf: f64) -> f64 {
    if t <= ta {
        a + v0 * t
    } else {
        a + v0 * (ta + (tf - ta) * ((tf - ta) / (tf - t)).ln())
    }
}

/// σ per epoch of the block's displacement along its direction (mm): the motion's scatter and
/// the block's measurement σ along the direction together (the scatter is drawn as a multiple of
/// the latter).
pub fn sigma_along_mm(c: &MotionCase) -> f64 {
    c.scatter_mm * (1.0 + 1.0 / (c.scatter * c.scatter)).sqrt()
}

/// The Cramér–Rao bound of the failure time (hours) from the epochs `0..=epoch` (days after the
/// first) of the failing case `c`, with the noise of [`sigma_along_mm`]. None for a case that does
/// not fail, an epoch at or after the failure, or a singular information matrix.
pub fn failure_time_bound_hours(c: &MotionCase, epoch: usize) -> Option<f64> {
    let (ta, tf) = (c.onset_days?, c.failure_days?);
    let interval_days = c.scenario.interval_hours / 24.0;
    let t_now = epoch as f64 * interval_days;
    if t_now >= tf {
        return None;
    }
    let p = Vector4::new(0.0, c.creep_mm_per_day, ta, tf);
    let f = |p: &Vector4<f64>, t: f64| creep_then_law(t, p[0], p[1], p[2], p[3]);
    let mut info = Matrix4::<f64>::zeros();
    // An onset before the first epoch (an hourly series of the last days) is not seen: the
    // oracle is given it (its information is that of a known parameter).
    if ta <= 0.0 {
        info[(2, 2)] = 1e12;
    }
    for e in 0..=epoch {
        let t = e as f64 * interval_days;
        let mut j = Vector4::zeros();
        for k in 0..4 {
            // Central differences; the step keeps t_f − h after the last epoch.
            let h = 1e-4 * (1.0 + p[k].abs()).min(tf - t_now);
            let mut up = p;
            let mut down = p;
            up[k] += h;
            down[k] -= h;
            j[k] = (f(&up, t) - f(&down, t)) / (2.0 * h);
        }
        info += j * j.transpose();
    }
    let s = sigma_along_mm(c);
    let cov = info.try_inverse()?;
    let var = cov[(3, 3)] * s * s;
    (var.is_finite() && var > 0.0).then(|| var.sqrt() * 24.0)
}

/// The oracle's first alarm on the failing case `c` under the rule "time to failure below
/// `below_hours`": hours before the failure of the first epoch at which the true time to failure
/// plus `z` times the Cramér–Rao σ ([`failure_time_bound_hours`], z at
/// [`BOUND_CONFIDENCE`]) is below `below_hours`; None when no epoch before the failure has it.
pub fn oracle_alarm_lead_hours(c: &MotionCase, below_hours: f64) -> Option<f64> {
    let tf = c.failure_days?;
    let interval_days = c.scenario.interval_hours / 24.0;
    (0..c.scenario.epochs).find_map(|e| {
        let lead = (tf - e as f64 * interval_days) * 24.0;
        if lead <= 0.0 {
            return None;
        }
        let sigma = failure_time_bound_hours(c, e)?;
        let upper = upper_bound_hours(lead, sigma, BOUND_CONFIDENCE)?;
        (upper < below_hours).then_some(lead)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kinematics::{case, case_with_scatter, MotionKind};

    /// The bound shrinks as the failure nears and grows with the scatter (σ ∝ scatter).
    #[test]
    fn the_bound_shrinks_towards_failure_and_scales_with_the_noise() {
        let c = case_with_scatter(MotionKind::Failing, 4, Some(2.0));
        let n = c.scenario.epochs;
        let late = failure_time_bound_hours(&c, n - 1).expect("bound");
        let early = failure_time_bound_hours(&c, n - 4).expect("bound");
        assert!(
            late < early,
            "{late} h at the last epoch, {early} h three before"
        );
        let c4 = case_with_scatter(MotionKind::Failing, 4, Some(4.0));
        let ratio = failure_time_bound_hours(&c4, n - 4).expect("bound") / early;
        let expected = sigma_along_mm(&c4) / sigma_along_mm(&c);
        assert!(
            (ratio / expected - 1.0).abs() < 1e-6,
            "{ratio} vs {expected}"
        );
        assert!(failure_time_bound_hours(&case(MotionKind::Creep, 4), 10).is_none());
    }
}
