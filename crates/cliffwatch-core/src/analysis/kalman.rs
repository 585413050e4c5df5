//! Kalman filter and Rauch–Tung–Striebel smoother over one point's (or block's) displacement
//! series: a 3-D kinematic state (position in mm, velocity in mm/day, optionally acceleration in
//! mm/day²), irregular time steps in days, each epoch's full 3 × 3 covariance.
//!
//! Model (Bar-Shalom, Li & Kirubarajan 2001, *Estimation with Applications to Tracking and
//! Navigation*, §6.2): per axis the state follows `x(k+1) = F(Δt) x(k) + w(k)`, the axes coupled
//! only through the measurement covariance.
//! - [`MotionModel::ConstantVelocity`]: continuous white-noise acceleration of spectral density q
//!   (mm²/day³), `F = [[1, Δt], [0, 1]]`, `Q = q [[Δt³/3, Δt²/2], [Δt²/2, Δt]]` (eq. 6.2.2-12).
//! - [`MotionModel::ConstantAcceleration`]: continuous white-noise jerk of spectral density q
//!   (mm²/day⁵), `F = [[1, Δt, Δt²/2], [0, 1, Δt], [0, 0, 1]]`,
//!   `Q = q [[Δt⁵/20, Δt⁴/8, Δt³/6], [Δt⁴/8, Δt³/3, Δt²/2], [Δt³/6, Δt²/2, Δt]]` (eq. 6.2.3-8).
//!
//! Measurement: the displacement `z = H x + v`, `v ~ N(0, R)` with R the epoch's 3 × 3
//! covariance. Update `P = P⁻ − K S Kᵀ` (eq. 5.2.3-17, equal to the Joseph form for the optimal
//! gain), symmetrised.
//! Smoother: RTS (eq. 8.6.2-1 to -4).
//!
//! Initialisation: position from the first measurement with its covariance, velocity 0 ± 10
//! mm/day and acceleration 0 ± 2 mm/day² per axis — wide against what a cliff does between two
//! campaigns, so the first epochs are weighted by the data, yet finite, so a series of two epochs
//! already has a velocity.
//!
//! Default: constant acceleration, q = 0.05 mm²/day⁵ (see [`KalmanConfig::default`]).
//! Deterministic: the same input gives bit-identical output (alerts are replayed on recompute).

use nalgebra::{Matrix3, SMatrix, SVector, Vector3};

pub use super::epoch::{KalmanConfig, MotionModel};
use super::error::AnalysisError;

/// The state is always 9-dimensional, axis-major `[x, vx, ax, y, vy, ay, z, vz, az]`, on the stack.
/// For [`MotionModel::ConstantVelocity`] the acceleration slots are decoupled (no transition
/// into velocity, no process noise, not observed): they keep their initial variance and never
/// touch the position and velocity, which come out exactly as from a 6-state filter.
type V9 = SVector<f64, 9>;
type M9 = SMatrix<f64, 9, 9>;

/// σ of the initial velocity per axis, mm/day.
const INITIAL_SIGMA_VELOCITY: f64 = 10.0;
/// σ of the initial acceleration per axis, mm/day².
const INITIAL_SIGMA_ACCELERATION: f64 = 2.0;

/// One epoch of the series: days (any origin, increasing), displacement in mm, its 3 × 3
/// covariance in mm².
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Measurement {
    /// Time in days.
    pub t_days: f64,
    /// Displacement (X, Y, Z) in mm.
    pub d_mm: [f64; 3],
    /// Covariance of the displacement in mm².
    pub cov_mm2: [[f64; 3]; 3],
}

/// The state of the filter (or smoother) at one epoch.
#[derive(Debug, Clone, PartialEq)]
pub struct KalmanState {
    /// Time in days (that of the measurement).
    pub t_days: f64,
    /// Derivatives per axis (2: position, velocity; 3: and acceleration).
    order: usize,
    /// State, axis-major: `[x, vx, ax, y, vy, ay, z, vz, az]` in mm, mm/day, mm/day² (the
    /// acceleration slots are inert for constant velocity).
    x: V9,
    /// Covariance of the state.
    p: M9,
}

/// The state projected onto a direction: displacement, velocity and acceleration along it, with σ.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Along {
    /// Displacement along the direction, mm.
    pub d_mm: f64,
    /// σ of `d_mm`, mm.
    pub sigma_d_mm: f64,
    /// Velocity along the direction, mm/day.
    pub v_mm_per_day: f64,
    /// σ of the velocity, mm/day.
    pub sigma_v_mm_per_day: f64,
    /// Acceleration along the direction, mm/day² (None for constant velocity).
    pub a_mm_per_day2: Option<f64>,
    /// σ of the acceleration, mm/day².
    pub sigma_a_mm_per_day2: Option<f64>,
}

impl KalmanState {
    fn index(&self, axis: usize, derivative: usize) -> usize {
        axis * 3 + derivative
    }

    fn block(&self, derivative: usize) -> (Vector3<f64>, Matrix3<f64>) {
        let idx = |a: usize| self.index(a, derivative);
        (
            Vector3::from_fn(|a, _| self.x[idx(a)]),
            Matrix3::from_fn(|r, c| self.p[(idx(r), idx(c))]),
        )
    }

    /// Filtered displacement (X, Y, Z) in mm.
    pub fn position_mm(&self) -> [f64; 3] {
        self.block(0).0.into()
    }

    /// Covariance of the displacement in mm².
    pub fn position_covariance_mm2(&self) -> [[f64; 3]; 3] {
        self.block(0).1.into()
    }

    /// Velocity (X, Y, Z) in mm/day.
    pub fn velocity_mm_per_day(&self) -> [f64; 3] {
        self.block(1).0.into()
    }

    /// Acceleration (X, Y, Z) in mm/day² (None for constant velocity).
    pub fn acceleration_mm_per_day2(&self) -> Option<[f64; 3]> {
        (self.order == 3).then(|| self.block(2).0.into())
    }

    /// 3-D length of the displacement and its linearised σ, mm (σ = √(trace/3) at the origin).
    pub fn length(&self) -> (f64, f64) {
        let (p, c) = self.block(0);
        super::linalg::length_of(&p, &c)
    }

    /// The state along a direction (normalised here; an unusable one gives zeros).
    pub fn along(&self, direction: [f64; 3]) -> Along {
        let u = super::unit_direction(direction).unwrap_or_else(Vector3::zeros);
        let proj = |derivative: usize| {
            let (v, c) = self.block(derivative);
            (u.dot(&v), (u.transpose() * c * u)[(0, 0)].max(0.0).sqrt())
        };
        let (d, sd) = proj(0);
        let (v, sv) = proj(1);
        let acc = (self.order == 3).then(|| proj(2));
        Along {
            d_mm: d,
            sigma_d_mm: sd,
            v_mm_per_day: v,
            sigma_v_mm_per_day: sv,
            a_mm_per_day2: acc.map(|a| a.0),
            sigma_a_mm_per_day2: acc.map(|a| a.1),
        }
    }
}

/// Transition and process noise of one axis over `dt` days (3 × 3; for constant velocity the
/// acceleration row and column are inert).
fn axis_model(order: usize, dt: f64, q: f64) -> (Matrix3<f64>, Matrix3<f64>) {
    let (dt2, dt3) = (dt * dt, dt * dt * dt);
    match order {
        2 => (
            Matrix3::new(1.0, dt, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0),
            Matrix3::new(dt3 / 3.0, dt2 / 2.0, 0.0, dt2 / 2.0, dt, 0.0, 0.0, 0.0, 0.0) * q,
        ),
        _ => {
            let (dt4, dt5) = (dt3 * dt, dt3 * dt2);
            (
                Matrix3::new(1.0, dt, dt2 / 2.0, 0.0, 1.0, dt, 0.0, 0.0, 1.0),
                Matrix3::new(
                    dt5 / 20.0,
                    dt4 / 8.0,
                    dt3 / 6.0,
                    dt4 / 8.0,
                    dt3 / 3.0,
                    dt2 / 2.0,
                    dt3 / 6.0,
                    dt2 / 2.0,
                    dt,
                ) * q,
            )
        }
    }
}

/// The full 9 × 9 transition: the axis transition on each axis.
fn transition(fa: &Matrix3<f64>) -> M9 {
    let mut f = M9::zeros();
    for a in 0..3 {
        f.fixed_view_mut::<3, 3>(a * 3, a * 3).copy_from(fa);
    }
    f
}

/// The transition over `dt` days and the predicted covariance `F P Fᵀ + Q`, formed block by block
/// (F and Q are block-diagonal with the same 3 × 3 axis block, so each 3 × 3 block of P is
/// propagated alone: a third of the work of the full product).
fn predict_covariance(order: usize, dt: f64, q: f64, p: &M9) -> (M9, M9) {
    let (fa, qa) = axis_model(order, dt, q);
    let mut pp = M9::zeros();
    for a in 0..3 {
        for b in a..3 {
            let blk = p.fixed_view::<3, 3>(a * 3, b * 3);
            let mut out = fa * blk * fa.transpose();
            if a == b {
                out += qa;
            }
            pp.fixed_view_mut::<3, 3>(a * 3, b * 3).copy_from(&out);
            if a != b {
                pp.fixed_view_mut::<3, 3>(b * 3, a * 3)
                    .copy_from(&out.transpose());
            }
        }
    }
    (transition(&fa), pp)
}

fn check(meas: &[Measurement], config: &KalmanConfig) -> Result<(), AnalysisError> {
    config.validate()?;
    let bad = |k: usize, why: &str| {
        Err(AnalysisError::InvalidInput(format!(
            "Kalman filter, measurement {k}: {why}"
        )))
    };
    for (k, m) in meas.iter().enumerate() {
        if !m.t_days.is_finite()
            || !m.d_mm.iter().all(|v| v.is_finite())
            || !m.cov_mm2.iter().flatten().all(|v| v.is_finite())
        {
            return bad(k, "non-finite value");
        }
        if k > 0 && !(m.t_days > meas[k - 1].t_days) {
            return bad(k, "times must increase");
        }
        if Matrix3::from(m.cov_mm2).cholesky().is_none() {
            return bad(k, "covariance not positive definite");
        }
    }
    Ok(())
}

/// One step of the forward pass: the filtered state, the predicted covariance and the transition
/// that led to it (identity at the first measurement).
type Step = (KalmanState, M9, M9);

/// Forward pass: the predicted and filtered states at every measurement.
fn forward(meas: &[Measurement], config: &KalmanConfig) -> Result<Vec<Step>, AnalysisError> {
    check(meas, config)?;
    let order = config.model.order();
    let singular = |k: usize| {
        AnalysisError::InvalidInput(format!(
            "Kalman filter, measurement {k}: innovation covariance singular"
        ))
    };
    let mut out: Vec<Step> = Vec::with_capacity(meas.len());
    let mut x = V9::zeros();
    let mut p = M9::zeros();
    for (k, m) in meas.iter().enumerate() {
        let r = Matrix3::from_fn(|i, j| 0.5 * (m.cov_mm2[i][j] + m.cov_mm2[j][i]));
        let z = Vector3::from(m.d_mm);
        if k == 0 {
            // Initialisation: position from the first measurement.
            x = V9::zeros();
            p = M9::zeros();
            for a in 0..3 {
                x[a * 3] = z[a];
                for b in 0..3 {
                    p[(a * 3, b * 3)] = r[(a, b)];
                }
                p[(a * 3 + 1, a * 3 + 1)] = INITIAL_SIGMA_VELOCITY.powi(2);
                // Inert for constant velocity; any positive variance keeps P invertible.
                p[(a * 3 + 2, a * 3 + 2)] = INITIAL_SIGMA_ACCELERATION.powi(2);
            }
            out.push((
                KalmanState {
                    t_days: m.t_days,
                    order,
                    x,
                    p,
                },
                p,
                M9::identity(),
            ));
            continue;
        }
        let dt = m.t_days - meas[k - 1].t_days;
        let (f, pp) = predict_covariance(order, dt, config.process_noise, &p);
        let xp = f * x;
        // Update. With the optimal gain K = P⁻Hᵀ S⁻¹ the Joseph form (eq. 5.2.3-18) equals
        // P = P⁻ − K S Kᵀ (eq. 5.2.3-17), symmetric by construction; H selects the position slots.
        let pht = SMatrix::<f64, 9, 3>::from_fn(|i, a| pp[(i, a * 3)]);
        let s = Matrix3::from_fn(|a, b| pp[(a * 3, b * 3)]) + r;
        let s_inv = s.cholesky().ok_or_else(|| singular(k))?.inverse();
        let gain = pht * s_inv;
        let innovation = z - Vector3::from_fn(|a, _| xp[a * 3]);
        x = xp + gain * innovation;
        p = pp - gain * pht.transpose();
        p = (p + p.transpose()) * 0.5;
        out.push((
            KalmanState {
                t_days: m.t_days,
                order,
                x,
                p,
            },
            pp,
            f,
        ));
    }
    Ok(out)
}

/// The causal filter's estimate at every measurement (with what was known then).
///
/// Errors: a process noise ≤ 0 or not finite, non-finite input, times that do not increase, a
/// covariance that is not positive definite (the measurement's index is named).
pub fn filter(
    meas: &[Measurement],
    config: &KalmanConfig,
) -> Result<Vec<KalmanState>, AnalysisError> {
    Ok(forward(meas, config)?.into_iter().map(|s| s.0).collect())
}

/// The RTS smoother's estimate at every measurement (with the whole series). Errors as [`filter`].
pub fn smooth(
    meas: &[Measurement],
    config: &KalmanConfig,
) -> Result<Vec<KalmanState>, AnalysisError> {
    let fwd = forward(meas, config)?;
    let n = fwd.len();
    let mut out: Vec<KalmanState> = fwd.iter().map(|s| s.0.clone()).collect();
    for k in (0..n.saturating_sub(1)).rev() {
        let (pred_p, f) = (&fwd[k + 1].1, &fwd[k + 1].2);
        let filt = &fwd[k].0;
        let pred_x = f * filt.x;
        let Some(ch) = pred_p.cholesky() else {
            return Err(AnalysisError::InvalidInput(format!(
                "Kalman smoother, measurement {}: predicted covariance singular",
                k + 1
            )));
        };
        // C = P_f Fᵀ P_p⁻¹ (eq. 8.6.2-2)
        let c = filt.p * f.transpose() * ch.inverse();
        let (next_x, next_p) = (out[k + 1].x, out[k + 1].p);
        let x = filt.x + c * (next_x - pred_x);
        let p = filt.p + c * (next_p - pred_p) * c.transpose();
        out[k].x = x;
        out[k].p = (p + p.transpose()) * 0.5;
    }
    Ok(out)
}
