//! Forecasts pooled over targets that move together but are not declared as a block.
//!
//! A site often does not know its block in advance. A single target's forecast is then as
//! uncertain as its own scatter makes it, and the alarm can come late or not at all. Where
//! neighbouring targets move together (within [`super::FailureConfig::pool_radius_m`] of each other,
//! each moving significantly, their displacements and filtered velocities equal within their
//! σ), their mean displacement series is a block's motion without the block: its noise falls by
//! the square root of their number, while what they share (the motion and its scatter) stays. The
//! forecast of that mean series is given to each of them when it is tighter than the target's
//! own, and the target's analysis names the targets it was pooled with. A declared block stays
//! the strongest evidence: its members are never pooled.

use std::collections::HashMap;

use nalgebra::{Matrix3, Vector3};

use super::displacement::PointAnalysis;
use super::epoch::{AnalysisConfig, EpochCoordinates, GroupKind, PointRole};
use super::history::{observed_of, History};
use super::stats::normal_quantile;
use super::tracking::{track, Observed};

/// Fewest targets (the target itself included) whose mean series is forecast.
pub const MIN_POOLED_TARGETS: usize = 3;

/// Epochs closer than this (days, about 0.1 s) are the same epoch.
const SAME_EPOCH_DAYS: f64 = 1e-6;

/// The epoch-wide inputs of the pooling.
pub(super) struct PoolInputs<'a> {
    /// The current epoch's coordinates (positions in m).
    pub current: &'a EpochCoordinates,
    /// The points' earlier records (same reference).
    pub history: &'a History,
    /// The analysis settings.
    pub config: &'a AnalysisConfig,
    /// Each point's displacement covariance as the filter takes it at the current epoch (mm², in
    /// the order of the analysed points).
    pub filter_cov: &'a [Matrix3<f64>],
    /// The reference epoch's share of each point's covariance (mm², same order).
    pub shared: &'a [Matrix3<f64>],
    /// Days from the current epoch to the reference epoch (≤ 0).
    pub reference_t_days: f64,
    /// The critical value of a 3-D displacement test at the site's confidence.
    pub critical3: f64,
}

/// Whether the point may be pooled: a monitored point outside every declared block whose
/// filtered displacement is significant.
fn candidate(p: &PointAnalysis, blocks: &[&str], z: f64) -> bool {
    let in_block = p.group.as_deref().is_some_and(|g| blocks.contains(&g));
    let moving = p
        .record
        .filtered
        .is_some_and(|f| f.f_d_mm > z * f.sigma_f_d_mm);
    p.role == PointRole::Monitored && !in_block && moving && !p.record.d_mm.is_nan()
}

/// Whether points `a` and `b` move together: their displacements agree within their joint σ (the
/// 3-D test at the site's confidence) and so do their filtered velocities.
fn together(a: &PointAnalysis, b: &PointAnalysis, critical3: f64, z: f64) -> bool {
    let d = |p: &PointAnalysis| Vector3::new(p.record.dx_mm, p.record.dy_mm, p.record.dz_mm);
    let diff = d(a) - d(b);
    let cov = Matrix3::from(a.covariance_mm2) + Matrix3::from(b.covariance_mm2);
    let Some(ch) = cov.cholesky() else {
        return false;
    };
    let w = ch.solve(&diff);
    if !(diff.dot(&w) <= critical3) {
        return false;
    }
    match (a.record.filtered, b.record.filtered) {
        (Some(fa), Some(fb)) => {
            let s = fa
                .sigma_f_velocity_mm_per_day
                .hypot(fb.sigma_f_velocity_mm_per_day);
            (fa.f_velocity_mm_per_day - fb.f_velocity_mm_per_day).abs() <= z * s
        }
        _ => false,
    }
}

/// Gives every pooled target of `points` the forecast of its pool's mean series where that is
/// tighter than its own (see the module's notes). `points` are the epoch's analysed points, in
/// the order of `inputs.filter_cov` and `inputs.shared`.
pub(super) fn pool_forecasts(points: &mut [PointAnalysis], inputs: &PoolInputs<'_>) {
    let config = inputs.config;
    let radius = config.failure.pool_radius_m;
    if !(radius > 0.0) {
        return;
    }
    let blocks: Vec<&str> = config
        .groups
        .iter()
        .filter(|g| g.kind == GroupKind::Block)
        .map(|g| g.name.as_str())
        .collect();
    let z = normal_quantile(0.5 + 0.5 * config.confidence);
    let position: HashMap<&str, Vector3<f64>> = inputs
        .current
        .points
        .iter()
        .map(|p| (p.name.as_str(), Vector3::from(p.xyz_m)))
        .collect();
    let candidates: Vec<usize> = (0..points.len())
        .filter(|&i| candidate(&points[i], &blocks, z))
        .filter(|&i| position.contains_key(points[i].record.point.as_str()))
        .collect();
    let mut forecasts: HashMap<Vec<usize>, Option<super::FailureForecast>> = HashMap::new();
    let mut updates = vec![];
    for &i in &candidates {
        let at = position[points[i].record.point.as_str()];
        let mut pool: Vec<usize> = candidates
            .iter()
            .copied()
            .filter(|&j| {
                j == i
                    || ((position[points[j].record.point.as_str()] - at).norm() <= radius
                        && together(&points[i], &points[j], inputs.critical3, z))
            })
            .collect();
        if pool.len() < MIN_POOLED_TARGETS {
            continue;
        }
        pool.sort_unstable();
        let pooled = *forecasts
            .entry(pool.clone())
            .or_insert_with(|| pooled_forecast(points, &pool, inputs));
        let Some(f) = pooled else { continue };
        let own = points[i].filtered_failure;
        if own.is_none_or(|o| f.sigma_hours < o.sigma_hours) {
            let others = pool
                .iter()
                .filter(|&&j| j != i)
                .map(|&j| points[j].record.point.clone())
                .collect();
            updates.push((i, f, others));
        }
    }
    for (i, f, others) in updates {
        let p = &mut points[i];
        p.filtered_failure = Some(f);
        if let Some(v) = p.record.filtered.as_mut() {
            v.f_time_to_failure_hours = Some(f.time_to_failure_hours);
            v.sigma_f_time_to_failure_hours = Some(f.sigma_hours);
        }
        p.pooled_with = others;
    }
}

/// The forecast of the mean displacement series of the points `pool` (indices into `points`):
/// the epochs all of them have, each the mean of their displacements with the covariance of a
/// mean of independent points (mm, mm²), tracked along the mean's own motion.
fn pooled_forecast(
    points: &[PointAnalysis],
    pool: &[usize],
    inputs: &PoolInputs<'_>,
) -> Option<super::FailureForecast> {
    let k = pool.len() as f64;
    let mut sums: Vec<(f64, Vector3<f64>, Matrix3<f64>, usize)> = vec![];
    for &j in pool {
        let p = &points[j];
        let mut series = observed_of(
            inputs.history.get(&p.record.point),
            inputs.current.observed_at,
            inputs.config,
        );
        series.push(Observed {
            t_days: 0.0,
            d_mm: Vector3::new(p.record.dx_mm, p.record.dy_mm, p.record.dz_mm),
            cov_mm2: inputs.filter_cov[j],
        });
        // `sums` stays sorted by time: each epoch found by bisection (an hourly site's 40 days
        // are ~950 epochs per target).
        for o in series {
            let at = sums.partition_point(|s| s.0 <= o.t_days - SAME_EPOCH_DAYS);
            match sums.get_mut(at) {
                Some(s) if s.0 < o.t_days + SAME_EPOCH_DAYS => {
                    s.1 += o.d_mm;
                    s.2 += o.cov_mm2;
                    s.3 += 1;
                }
                _ => sums.insert(at, (o.t_days, o.d_mm, o.cov_mm2, 1)),
            }
        }
    }
    let mean: Vec<Observed> = sums
        .into_iter()
        .filter(|s| s.3 == pool.len())
        .map(|(t_days, d, c, _)| Observed {
            t_days,
            d_mm: d / k,
            cov_mm2: c / (k * k),
        })
        .collect();
    let shared = pool
        .iter()
        .fold(Matrix3::zeros(), |acc, &j| acc + inputs.shared[j])
        / (k * k);
    track(
        &mean,
        None,
        None,
        Some(shared),
        inputs.reference_t_days,
        inputs.config,
    )?
    .failure
}
