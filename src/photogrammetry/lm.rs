//! Gauss–Newton with Levenberg–Marquardt damping over the bundle's normal equations.

use super::normals::Bundle;

/// How an iteration ended.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LmOutcome {
    /// Accepted iterations.
    pub iterations: usize,
    /// True when the largest update fell below 1e-6 of its a-priori σ (or vᵀPv stopped changing
    /// in the 13th digit).
    pub converged: bool,
    /// Final vᵀPv.
    pub cost: f64,
}

/// The largest update measured in units of its a-priori σ, 1/√N_kk.
fn step_in_sigmas(
    b: &Bundle,
    n: &super::normals::Normals,
    dc: &[f64],
    dp: &[nalgebra::Vector3<f64>],
) -> f64 {
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

/// Runs Levenberg–Marquardt from the bundle's current state for at most `max_iterations` accepted
/// steps; the bundle holds the best state found.
pub fn levenberg_marquardt(b: &mut Bundle, max_iterations: usize) -> LmOutcome {
    let mut lambda = 1e-4;
    let mut iterations = 0;
    let mut cost = b.cost();
    if !cost.is_finite() {
        return LmOutcome {
            iterations,
            converged: false,
            cost,
        };
    }
    while iterations < max_iterations {
        let n = b.normals();
        let mut accepted = None;
        for _ in 0..20 {
            let Some((dc, dp)) = b.solve(&n, lambda) else {
                lambda *= 10.0;
                continue;
            };
            let mut trial = b.clone();
            trial.apply(&dc, &dp);
            let c = trial.cost();
            if c.is_finite() && c <= cost * (1.0 + 1e-15) {
                let step = step_in_sigmas(b, &n, &dc, &dp);
                accepted = Some((trial, c, step));
                lambda = (lambda * 0.2).max(1e-12);
                break;
            }
            lambda *= 10.0;
        }
        let Some((trial, c, step)) = accepted else {
            // No damping, however strong, gives a decrease: the gradient vanishes within rounding, so
            // the state is stationary (typically the start of a later stage that is already converged).
            return LmOutcome {
                iterations,
                converged: true,
                cost,
            };
        };
        iterations += 1;
        let decrease = (cost - c) / cost.max(1e-300);
        *b = trial;
        cost = c;
        if step < 1e-6 || (decrease.abs() < 1e-13 && step < 1e-2) {
            return LmOutcome {
                iterations,
                converged: true,
                cost,
            };
        }
    }
    LmOutcome {
        iterations,
        converged: false,
        cost,
    }
}
