//! Gauss–Newton with Levenberg–Marquardt damping over the bundle's normal equations.

use super::normal_equations::Normals;
use super::normals::ReduceBuffers;
use crate::photogrammetry::model::bundle::Bundle;

/// How an iteration ended.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LmOutcome {
    /// Accepted iterations.
    pub iterations: usize,
    /// True when the largest update, or the distance to the optimum extrapolated from the last two
    /// updates, fell below 1e-6 of its a-priori σ (or vᵀPv stopped changing in the 13th digit).
    pub converged: bool,
    /// Final vᵀPv.
    pub cost: f64,
}

/// Relative increase of vᵀPv that a step may show and still be taken: the rounding of a sum of
/// many squares (a step that close to the minimum cannot be judged by the cost, and rejecting it
/// only raises the damping and solves again).
const ROUNDING: f64 = 1e-12;

/// Where an iteration starts, which sets its Marquardt damping λ (relative to the diagonal): λ of
/// the first step and its factor after every accepted step; λ is raised tenfold at every rejected
/// step.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Start {
    /// From start values, which may lie in the reach of a wrong basin (the mirror roots of a flat
    /// face): cautious steps first (λ = 1e-4, × 0.2 after an accepted step).
    Rough,
    /// From a converged state of a neighbouring problem (c freed, observations dropped or taken
    /// back): the Gauss–Newton step nearly at once (λ = 1e-8, × 0.1), since strong damping would
    /// hold back the weakly determined directions (depth and c at long range) for the several
    /// iterations it takes to decay. On the 100 × 10 000 network these stages took 18 iterations
    /// with the rough start's damping, 8 with this.
    Near,
    /// From start values that are likely good (the start roots, before any mirror is tried): as
    /// Rough, but λ falls × 0.01 after a step whose decrease of vᵀPv the linearized model predicted
    /// within [`LINEAR_GAIN`] (ρ = actual / predicted decrease). There the damping only holds back
    /// the weakly determined directions, so releasing it fast saves iterations: 9 → 5 on the
    /// 100 × 10 000 network. Used only where a wrong basin is caught afterwards (the mirror choice
    /// judges the fit): released everywhere, it sent flat-face seed 6 and label-swap seed 5 astray.
    Adaptive,
}

impl Start {
    /// (initial λ, factor after an accepted step).
    fn damping(self) -> (f64, f64) {
        match self {
            Start::Rough | Start::Adaptive => (1e-4, 0.2),
            Start::Near => (1e-8, 0.1),
        }
    }
}

/// Largest update (in a-priori σ of its unknown) that counts as converged.
const CONVERGED_STEP: f64 = 1e-6;

/// A step whose size (a-priori σ) is below this multiple of the convergence threshold may end the
/// iteration by the extrapolated distance to the optimum (see [`distance_left`]).
const EXTRAPOLATE_WITHIN: f64 = 100.0;

/// Largest contraction ratio taken from two successive steps; beyond it the iteration is not yet in
/// its linear regime and no distance is extrapolated.
const MAX_RATIO: f64 = 0.5;

/// Distance (a-priori σ) from the state after a step of size `step` to the optimum, extrapolated
/// from the linear convergence of Gauss–Newton: with the ratio ρ = step / previous of two successive
/// steps, the steps still to come sum to step · ρ / (1 − ρ). Gauss–Newton converges linearly on a
/// problem with non-zero residuals, at a rate set by the residuals and the curvature of the model
/// (here ρ ≈ 10⁻²…10⁻³ per iteration), so that once the ratio is small the state is far closer to
/// the optimum than the last step. `None` without a previous step or with a ratio above
/// [`MAX_RATIO`].
fn distance_left(step: f64, previous: Option<f64>) -> Option<f64> {
    let rho = step / previous?;
    (rho <= MAX_RATIO).then(|| step * rho / (1.0 - rho))
}

/// |ρ − 1| within which a step of [`Start::Adaptive`] counts as linear.
const LINEAR_GAIN: f64 = 0.05;

/// Factor on λ after a linear step of [`Start::Adaptive`].
const LINEAR_DECREASE: f64 = 0.01;

/// Decrease of vᵀPv that the linearized model predicts for the update (dc, dp) solved with damping
/// λ: with (N + G + λD) h = g, it is 2 hᵀg − hᵀNh = hᵀg + hᵀGh + λ hᵀDh.
fn predicted_decrease(
    b: &Bundle,
    n: &Normals,
    dc: &[f64],
    dp: &[nalgebra::Vector3<f64>],
    lambda: f64,
) -> f64 {
    let mut s = 0.0;
    for (k, d) in dc.iter().enumerate() {
        s += d * n.bc[k] + lambda * n.u[(k, k)] * d * d;
    }
    for (i, d) in dp.iter().enumerate() {
        s += d.dot(&n.bp[i]) + b.gauge * d.norm_squared();
        for k in 0..3 {
            s += lambda * n.v[i][(k, k)] * d[k] * d[k];
        }
    }
    s
}

/// The largest update measured in units of its a-priori σ, 1/√N_kk.
fn step_in_sigmas(b: &Bundle, n: &Normals, dc: &[f64], dp: &[nalgebra::Vector3<f64>]) -> f64 {
    let mut worst: f64 = 0.0;
    for (k, d) in dc.iter().enumerate() {
        worst = worst.max(d.abs() * n.u[(k, k)].max(0.0).sqrt());
    }
    for (i, d) in dp.iter().enumerate() {
        for k in 0..3 {
            worst = worst.max(d[k].abs() * (n.v[i][(k, k)] + b.gauge).max(0.0).sqrt());
        }
    }
    worst
}

/// Runs Levenberg–Marquardt from the bundle's current state (start values: cautious damping at
/// first) for at most `max_iterations` accepted steps; the bundle holds the best state found.
pub fn levenberg_marquardt(b: &mut Bundle, max_iterations: usize) -> LmOutcome {
    run(b, max_iterations, CONVERGED_STEP, Start::Rough).0
}

/// As [`levenberg_marquardt`] from `start` (see [`Start`]), also returning, when it converged
/// by a small last step (below 1e-6 σ of every unknown, or below 1e-4 σ with the distance left
/// extrapolated below 1e-6 σ; or stationary, vᵀPv unchanged with a step below 1e-2 σ), the normal
/// equations of the state before that step: good for the cofactors of the solution without building
/// them again (the Jacobian does not change measurably over such steps).
pub fn levenberg_marquardt_normals(
    b: &mut Bundle,
    max_iterations: usize,
    start: Start,
) -> (LmOutcome, Option<Normals>) {
    run(b, max_iterations, CONVERGED_STEP, start)
}

/// Largest update (in a-priori σ) that ends a round of the reweighted first stage: its weights
/// change with the next round, and the later stages converge to [`CONVERGED_STEP`] from it (10⁻²
/// σ: one iteration less than 10⁻³ on the 5 × 28 epoch, the same accuracy table for the
/// orthogonal model).
pub const ROUND_STEP: f64 = 1e-2;

/// As [`levenberg_marquardt`] (cautious damping at first), converged once the largest update falls
/// below `converged_step` a-priori σ of its unknown; returns the normal equations as
/// [`levenberg_marquardt_normals`] does.
pub fn levenberg_marquardt_within(
    b: &mut Bundle,
    max_iterations: usize,
    converged_step: f64,
) -> (LmOutcome, Option<Normals>) {
    run(b, max_iterations, converged_step, Start::Rough)
}

fn run(
    b: &mut Bundle,
    max_iterations: usize,
    converged_step: f64,
    start: Start,
) -> (LmOutcome, Option<Normals>) {
    let (mut lambda, decrease) = start.damping();
    let mut iterations = 0;
    let mut cost = b.cost();
    if !cost.is_finite() {
        let outcome = LmOutcome {
            iterations,
            converged: false,
            cost,
        };
        return (outcome, None);
    }
    let mut previous_step = None;
    // The normal equations of the previous iteration, rebuilt in place.
    let mut buffer: Option<Normals> = None;
    let mut reduce_buffers = ReduceBuffers::default();
    while iterations < max_iterations {
        // A cancelled adjustment stops here, unconverged; the adjuster then reports it as such.
        if b.cancel.is_cancelled() {
            break;
        }
        let n = match buffer.take() {
            Some(mut n) => {
                b.normals_into(&mut n);
                n
            }
            None => b.normals(),
        };
        let saved = (b.images.clone(), b.interior.clone(), b.points.clone());
        let mut accepted = None;
        for _ in 0..20 {
            if b.cancel.is_cancelled() {
                break;
            }
            let Some((dc, dp)) = b.solve(&n, lambda, &mut reduce_buffers) else {
                lambda *= 10.0;
                continue;
            };
            let step = step_in_sigmas(b, &n, &dc, &dp);
            b.apply(&dc, &dp);
            let c = b.cost();
            if step < converged_step && c.is_finite() {
                // The update is far below the precision of every unknown: converged. Its cost is
                // not compared, since rounding alone can make a negligible step look like an ascent.
                let outcome = LmOutcome {
                    iterations: iterations + 1,
                    converged: true,
                    cost: c,
                };
                return (outcome, Some(n));
            }
            let descends = c.is_finite() && c <= cost * (1.0 + ROUNDING);
            if descends
                && step < EXTRAPOLATE_WITHIN * converged_step
                && distance_left(step, previous_step).is_some_and(|d| d < converged_step)
            {
                // What is left after this step is below the threshold: converged as well, without
                // one more build of the normal equations only to see a negligible step.
                let outcome = LmOutcome {
                    iterations: iterations + 1,
                    converged: true,
                    cost: c,
                };
                return (outcome, Some(n));
            }
            if descends {
                accepted = Some((c, step));
                let linear = start == Start::Adaptive && {
                    let rho = (cost - c) / predicted_decrease(b, &n, &dc, &dp, lambda).max(1e-300);
                    (rho - 1.0).abs() < LINEAR_GAIN
                };
                let f = if linear { LINEAR_DECREASE } else { decrease };
                lambda = (lambda * f).max(1e-12);
                break;
            }
            (b.images, b.interior, b.points) = saved.clone();
            lambda *= 10.0;
        }
        let Some((c, step)) = accepted else {
            // No damping, however strong, gives a decrease: the gradient vanishes within rounding, so
            // the state is stationary (typically the start of a later stage that is already converged).
            // Unless the tries were cut short by a cancellation: then nothing is known.
            let outcome = LmOutcome {
                iterations,
                converged: !b.cancel.is_cancelled(),
                cost,
            };
            return (outcome, Some(n));
        };
        iterations += 1;
        previous_step = Some(step);
        let decrease = (cost - c) / cost.max(1e-300);
        cost = c;
        if step < converged_step || (decrease.abs() < 1e-13 && step < 1e-2) {
            // Stationary: the normal equations of the state 10⁻² σ away at most serve for the
            // cofactors as well.
            let outcome = LmOutcome {
                iterations,
                converged: true,
                cost,
            };
            return (outcome, Some(n));
        }
        buffer = Some(n);
    }
    let outcome = LmOutcome {
        iterations,
        converged: false,
        cost,
    };
    (outcome, None)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::photogrammetry::test_support::bundle;
    use nalgebra::Vector3;

    /// Near a zero-residual solution the model is linear: the decrease of vᵀPv a damped step
    /// achieves equals the predicted one to within the step's second-order effects (a sign error
    /// or a factor 2 in the prediction would give ρ = −1, 2 or ½).
    #[test]
    fn predicted_decrease_matches_the_actual_one_near_a_solution() {
        for (nimg, np, per_point) in [(4, 7, 4), (12, 40, 3)] {
            let mut b = bundle(nimg, np, per_point);
            for k in 0..b.obs.len() {
                let o = b.obs[k];
                let e = b.residual_of(&o);
                b.obs[k].meas = [o.meas[0] - e[0], o.meas[1] - e[1]];
            }
            for (i, p) in b.points.iter_mut().enumerate() {
                let t = i as f64;
                *p += 1e-4 * Vector3::new((3.1 * t).sin(), (1.3 * t).cos(), (0.7 * t).sin());
            }
            for lambda in [1e-6, 1e-3, 1e-1] {
                let mut trial = b.clone();
                let n = trial.normals();
                let cost = trial.cost();
                let mut buffers = ReduceBuffers::default();
                let (dc, dp) = trial.solve(&n, lambda, &mut buffers).expect("solves");
                let predicted = predicted_decrease(&trial, &n, &dc, &dp, lambda);
                trial.apply(&dc, &dp);
                let rho = (cost - trial.cost()) / predicted;
                assert!(
                    (rho - 1.0).abs() < 1e-3,
                    "{nimg} x {np}, λ {lambda}: ρ = {rho}"
                );
            }
        }
    }
}
