//! The blocks of an epoch: each declared group's rigid-body motion ([`super::rigid_body`]) from its
//! members' displacements with their joint covariance, in this epoch and the past epochs of the
//! history, its raw and filtered kinematics and forecasts ([`super::tracking`]), and the readings
//! its rules see.

use std::collections::HashMap;

use chrono::{DateTime, Utc};
use nalgebra::{DMatrix, Matrix3, Vector3};
use serde::{Deserialize, Serialize};

use super::alerts::{Metric, Reading, Readings, Source};
use super::displacement::{DisplacementRecord, PointAnalysis};
use super::epoch::{AnalysisConfig, EpochCoordinates, GroupConfig, PointConfig};
use super::failure::FailureForecast;
use super::history::{past_start, raw_kinematics, record_covariance, History};
use super::linalg::length_of;
use super::rigid_body::{
    at_rest, estimate_block, estimate_block_correlated, translation_share, BlockMotion, BlockPoint,
};
use super::tracking::{track, Observed, Tracked};
use super::velocity::{days_between, Sample};

/// The fewest members measured in an epoch (and in its reference epoch) from which a block has a
/// motion in that epoch: a "block" of one point would only repeat that point's alerts.
pub const MIN_BLOCK_POINTS: usize = 2;

/// The analysis of one block group in one epoch: its members and the values its rules read.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BlockAnalysis {
    /// Group name.
    pub group: String,
    /// Member points present in this epoch.
    pub points: Vec<String>,
    /// Raw and filtered values of the block's metrics (displacement at the block's centroid in
    /// mm, along the block's direction in mm, velocity in mm/day, time to failure in hours).
    pub readings: Readings,
    /// The block's motion in this epoch (None when it could not be estimated, or fewer than
    /// [`MIN_BLOCK_POINTS`] members were measured).
    #[serde(default)]
    pub motion: Option<BlockMotion>,
    /// Raw time-to-failure forecast of the block (inverse velocity of its translation).
    #[serde(default)]
    pub failure: Option<FailureForecast>,
    /// Filtered state of the block's translation.
    #[serde(default)]
    pub filtered: Option<super::displacement::FilteredValues>,
    /// Time-to-failure forecast from the block's smoothed velocities, with its interval.
    #[serde(default)]
    pub filtered_failure: Option<FailureForecast>,
}

/// What the blocks of an epoch are analysed from: the epoch's point analyses, the points'
/// history, and the joint covariance of any set of points' displacements in this epoch.
pub(super) struct BlockInputs<'a> {
    /// The reference epoch (the points' reference positions).
    pub reference: &'a EpochCoordinates,
    /// The site's point configurations (group membership).
    pub points: &'a [PointConfig],
    /// This epoch's point analyses.
    pub out: &'a [PointAnalysis],
    /// The points' earlier records.
    pub history: &'a History,
    /// This epoch's time.
    pub now: DateTime<Utc>,
    /// This epoch is the reference epoch itself: every displacement is zero, exactly.
    pub same_epoch: bool,
    /// The reference epoch's time relative to this epoch (days; > 0 when it lies later).
    pub reference_t_days: f64,
    /// The site's analysis settings.
    pub config: &'a AnalysisConfig,
    /// Critical value of the 3-D displacement test (the points' one, at the site's confidence).
    pub critical3: f64,
    /// Normal quantile of the velocity's significance test (at the site's confidence).
    pub z_vel: f64,
    /// Normal quantile of the acceleration's significance test.
    pub z_acc: f64,
    /// The joint covariance of the displacements of the named points in this epoch, in their
    /// order; None when it is not available.
    pub joint_of: &'a dyn Fn(&[String]) -> Option<MemberCovariance>,
}

/// The joint covariance (mm², 3k × 3k) of k points' displacements in one epoch.
pub(super) struct MemberCovariance {
    /// The whole covariance.
    pub joint_mm2: DMatrix<f64>,
    /// The reference epoch's share of it, common to every epoch analysed against it.
    pub shared_mm2: DMatrix<f64>,
}

/// The motion of each declared block in this epoch and in the past epochs of the history, its
/// filtered kinematics and forecasts, and the readings its rules see.
pub(super) fn analyse_blocks(inputs: &BlockInputs) -> Vec<BlockAnalysis> {
    let positions: HashMap<&str, [f64; 3]> = inputs
        .reference
        .points
        .iter()
        .map(|p| (p.name.as_str(), p.xyz_m))
        .collect();
    inputs
        .config
        .groups
        .iter()
        .map(|g| analyse_block(g, &positions, inputs))
        .collect()
}

fn analyse_block(
    g: &GroupConfig,
    positions: &HashMap<&str, [f64; 3]>,
    inputs: &BlockInputs,
) -> BlockAnalysis {
    let BlockInputs {
        points,
        out,
        config,
        joint_of,
        ..
    } = *inputs;
    let members: Vec<String> = g
        .members(points)
        .into_iter()
        .filter(|m| positions.contains_key(m.as_str()) && out.iter().any(|p| &p.record.point == m))
        .collect();
    let current: Vec<BlockPoint> = members
        .iter()
        .filter_map(|m| {
            let p = out.iter().find(|p| &p.record.point == m)?;
            let r = &p.record;
            Some(BlockPoint {
                name: m.clone(),
                xyz_m: positions[m.as_str()],
                d_mm: [r.dx_mm, r.dy_mm, r.dz_mm],
                cov_mm2: p.covariance_mm2,
            })
        })
        .collect();
    if current.len() < MIN_BLOCK_POINTS {
        return BlockAnalysis::without_motion(g, members);
    }
    // This epoch's joint covariance of the members, when every member is present; the past
    // epochs' is taken with the same correlations (see `correlated_like`).
    let (joint_now, shared_joint) = (current.len() == members.len())
        .then(|| joint_of(&members))
        .flatten()
        .map(|m| (m.joint_mm2, m.shared_mm2))
        .unzip();
    // The reference epoch itself: the block has not moved, exactly.
    if inputs.same_epoch {
        let joint = joint_now.as_ref().zip(shared_joint.as_ref());
        return at_reference_epoch(g, members, &current, joint, positions, inputs);
    }
    let motion = match &joint_now {
        Some(j) => estimate_block_correlated(&current, j, config.confidence),
        None => estimate_block(&current, config.confidence),
    }
    .ok();
    // The reference epoch's share of the translation's covariance.
    let shared = joint_now
        .as_ref()
        .zip(shared_joint.as_ref())
        .and_then(|(j, s)| translation_share(&current, j, s));
    let mut series = past_motions(&members, positions, inputs, joint_now.as_ref());
    let kinematics = match &motion {
        Some(b) => {
            series.push(Observed {
                t_days: 0.0,
                d_mm: Vector3::from(b.translation_mm),
                cov_mm2: Matrix3::from(b.covariance_mm2),
            });
            block_kinematics(b, g, &series, shared, inputs)
        }
        None => BlockKinematics::default(),
    };
    let BlockKinematics {
        readings,
        failure,
        filtered,
        filtered_failure,
    } = kinematics;
    BlockAnalysis {
        readings,
        motion,
        failure,
        filtered,
        filtered_failure,
        ..BlockAnalysis::without_motion(g, members)
    }
}

/// The block at the reference epoch: its motion zero and exactly known, its displacement 0 and
/// not significant, so that its motion series starts where its points' series do. When earlier
/// epochs are analysed against it (a reference moved later in the series) and every member is
/// measured (`joint`: the members' joint covariance and the reference's share of it), the
/// filter runs as in any epoch, so the block's filtered velocity and forecast do not depend on
/// where the reference lies.
fn at_reference_epoch(
    g: &GroupConfig,
    members: Vec<String>,
    current: &[BlockPoint],
    joint: Option<(&DMatrix<f64>, &DMatrix<f64>)>,
    positions: &HashMap<&str, [f64; 3]>,
    inputs: &BlockInputs,
) -> BlockAnalysis {
    let tracked = joint.and_then(|(j, s)| {
        let mut series = past_motions(&members, positions, inputs, Some(j));
        if series.is_empty() {
            return None;
        }
        // The filter's input: the translation's covariance as every epoch's difference carries
        // it (the reference's errors twice), though the translation is zero exactly.
        let b = estimate_block_correlated(current, j, inputs.config.confidence).ok()?;
        series.push(Observed {
            t_days: 0.0,
            d_mm: Vector3::zeros(),
            cov_mm2: Matrix3::from(b.covariance_mm2),
        });
        let dir = g.direction.and_then(super::unit_direction);
        let shared = translation_share(current, j, s);
        track(
            &series,
            dir,
            g.process_noise,
            shared,
            inputs.reference_t_days,
            inputs.config,
        )
    });
    let mut readings = Readings::default();
    let zero = Reading {
        value: Some(0.0),
        sigma: 0.0,
        significant: false,
    };
    readings.set(Metric::DisplacementMm, Source::Raw, zero);
    if g.direction.is_some() {
        readings.set(Metric::DisplacementAlongMm, Source::Raw, zero);
    }
    if let Some(t) = &tracked {
        set_filtered(&mut readings, t);
    }
    BlockAnalysis {
        readings,
        motion: at_rest(current).ok(),
        filtered: tracked.map(|t| t.values),
        filtered_failure: tracked.and_then(|t| t.failure),
        ..BlockAnalysis::without_motion(g, members)
    }
}

/// The block's translation in the past epochs of the history (those the filter reads before
/// `now`: `past_start`) in which every current member has a usable record,
/// oldest first; each with this epoch's correlations when `joint_now` is known.
fn past_motions(
    members: &[String],
    positions: &HashMap<&str, [f64; 3]>,
    inputs: &BlockInputs,
    joint_now: Option<&DMatrix<f64>>,
) -> Vec<Observed> {
    let BlockInputs {
        history,
        now,
        config,
        ..
    } = *inputs;
    let mut by_epoch: std::collections::BTreeMap<DateTime<Utc>, Vec<BlockPoint>> =
        Default::default();
    for m in members {
        let Some(h) = history.get(m) else { continue };
        let end = h.partition_point(|r| r.observed_at < now);
        let start = past_start(&h[..end], now, config);
        for r in &h[start..end] {
            if let Some(cov) = record_covariance(r) {
                by_epoch.entry(r.observed_at).or_default().push(BlockPoint {
                    name: m.clone(),
                    xyz_m: positions[m.as_str()],
                    d_mm: [r.dx_mm, r.dy_mm, r.dz_mm],
                    cov_mm2: cov.into(),
                });
            }
        }
    }
    by_epoch
        .into_iter()
        .filter(|(_, ps)| ps.len() == members.len())
        .filter_map(|(t, ps)| {
            let b = match joint_now.and_then(|j| correlated_like(j, &ps)) {
                Some(j) => estimate_block_correlated(&ps, &j, config.confidence),
                None => estimate_block(&ps, config.confidence),
            }
            .ok()?;
            Some(Observed {
                t_days: days_between(now, t),
                d_mm: Vector3::from(b.translation_mm),
                cov_mm2: Matrix3::from(b.covariance_mm2),
            })
        })
        .collect()
}

/// What a block's rules read, with its forecasts.
#[derive(Default)]
struct BlockKinematics {
    readings: Readings,
    failure: Option<FailureForecast>,
    filtered: Option<super::displacement::FilteredValues>,
    filtered_failure: Option<FailureForecast>,
}

/// The readings of a block whose motion `b` is known in this epoch: its displacement (and along
/// the group's direction), the raw velocity and forecast from the length of its translation
/// `series` (this epoch last), and the Kalman filter's estimates (`shared`: the reference epoch's
/// share of the translation's covariance).
fn block_kinematics(
    b: &BlockMotion,
    g: &GroupConfig,
    series: &[Observed],
    shared: Option<Matrix3<f64>>,
    inputs: &BlockInputs,
) -> BlockKinematics {
    let BlockInputs {
        config,
        critical3,
        z_vel,
        z_acc,
        ..
    } = *inputs;
    let mut readings = Readings::default();
    let (d, sd) = b.length();
    // The translation's 3-D test, as a point's displacement is tested (a 1-D quantile on the
    // length called a still block significant in 8.5 % of epochs, not 1 %).
    let significant = super::displacement::point_test(
        &Vector3::from(b.translation_mm),
        &Matrix3::from_fn(|r, c| b.covariance_mm2[r][c]),
        config.confidence,
        config.variance_dof,
        critical3,
    )
    .significant;
    readings.set(
        Metric::DisplacementMm,
        Source::Raw,
        Reading {
            value: Some(d),
            sigma: sd,
            significant,
        },
    );
    let dir = g.direction.and_then(super::unit_direction);
    if let Some(v) = dir {
        let (a, sa) = b.along(v.into());
        readings.set(
            Metric::DisplacementAlongMm,
            Source::Raw,
            Reading {
                value: Some(a),
                sigma: sa,
                significant,
            },
        );
    }
    // Raw velocity and forecast from the block's length series, as for a point.
    let samples: Vec<Sample> = series
        .iter()
        .map(|o| {
            let (len, s) = length_of(&o.d_mm, &o.cov_mm2);
            Sample {
                t_days: o.t_days,
                d_mm: len,
                sigma_mm: s.max(1e-6),
            }
        })
        .collect();
    let (kin, failure) = raw_kinematics(&samples, significant, config, z_vel, z_acc);
    if let Some(k) = kin {
        readings.set(
            Metric::VelocityMmPerDay,
            Source::Raw,
            Reading {
                value: Some(k.velocity_mm_per_day),
                sigma: k.sigma_velocity_mm_per_day,
                significant: significant && k.velocity_significant,
            },
        );
    }
    readings.set(
        Metric::TimeToFailureHours,
        Source::Raw,
        Reading::forecast(failure),
    );
    let tracked = track(
        series,
        dir,
        g.process_noise,
        shared,
        inputs.reference_t_days,
        config,
    );
    if let Some(t) = &tracked {
        set_filtered(&mut readings, t);
    }
    BlockKinematics {
        readings,
        failure,
        filtered: tracked.map(|t| t.values),
        filtered_failure: tracked.and_then(|t| t.failure),
    }
}

/// Sets the block's filtered readings from the filter's estimates `t`.
fn set_filtered(readings: &mut Readings, t: &Tracked) {
    let f = t.values;
    readings.set(
        Metric::DisplacementMm,
        Source::Filtered,
        Reading::new(Some(f.f_d_mm), Some(f.sigma_f_d_mm)),
    );
    if let Some((a, sa)) = t.along_mm {
        readings.set(
            Metric::DisplacementAlongMm,
            Source::Filtered,
            Reading::new(Some(a), Some(sa)),
        );
    }
    readings.set(
        Metric::VelocityMmPerDay,
        Source::Filtered,
        Reading::new(
            Some(f.f_velocity_mm_per_day),
            Some(f.sigma_f_velocity_mm_per_day),
        ),
    );
    readings.set(
        Metric::TimeToFailureHours,
        Source::Filtered,
        Reading::forecast(t.failure),
    );
}

/// The joint covariance of a past epoch's member displacements (`past`, in the order of
/// `joint_now`'s points) with this epoch's correlations: `T Σ_now Tᵀ` with the block-diagonal
/// `T_i = L_past,i L_now,i⁻¹` (L the Cholesky factors of each point's 3 × 3 covariance), so each
/// point keeps its own stored covariance and the cross-covariances (the datum's, the reference
/// epoch's: the same stations and stable points every epoch) scale with it. Stored records keep
/// no cross-covariances. None when a covariance is not positive definite.
fn correlated_like(joint_now: &DMatrix<f64>, past: &[BlockPoint]) -> Option<DMatrix<f64>> {
    let n = 3 * past.len();
    if joint_now.shape() != (n, n) {
        return None;
    }
    let mut t = DMatrix::<f64>::zeros(n, n);
    for (k, p) in past.iter().enumerate() {
        let now = Matrix3::from(joint_now.fixed_view::<3, 3>(3 * k, 3 * k));
        let l_now = now.cholesky()?.l();
        let l_past = Matrix3::from(p.cov_mm2).cholesky()?.l();
        let tk = l_past * l_now.try_inverse()?;
        t.view_mut((3 * k, 3 * k), (3, 3)).copy_from(&tk);
    }
    Some(&t * joint_now * t.transpose())
}

impl BlockAnalysis {
    /// A block without a motion in this epoch: its members, no readings.
    fn without_motion(g: &GroupConfig, members: Vec<String>) -> Self {
        BlockAnalysis {
            group: g.name.clone(),
            points: members,
            readings: Readings::default(),
            motion: None,
            failure: None,
            filtered: None,
            filtered_failure: None,
        }
    }

    /// The block's row of the motion series in a point's form (`point` is the group): the
    /// translation (mm) with its covariance (mm²), its length, the raw velocity (mm/day) and
    /// forecast (h) of the length, the filtered values. `None` without a motion this epoch.
    pub fn record(&self, epoch: i64, observed_at: DateTime<Utc>) -> Option<DisplacementRecord> {
        let m = self.motion.as_ref()?;
        let (d, sd) = m.length();
        let c = m.covariance_mm2;
        let raw = |metric: Metric| self.readings.get(metric, Source::Raw);
        Some(DisplacementRecord {
            point: self.group.clone(),
            epoch,
            observed_at,
            dx_mm: m.translation_mm[0],
            dy_mm: m.translation_mm[1],
            dz_mm: m.translation_mm[2],
            d_mm: d,
            sigma_dx_mm: c[0][0].max(0.0).sqrt(),
            sigma_dy_mm: c[1][1].max(0.0).sqrt(),
            sigma_dz_mm: c[2][2].max(0.0).sqrt(),
            sigma_mm: sd,
            cov_dxdy_mm2: Some(c[0][1]),
            cov_dxdz_mm2: Some(c[0][2]),
            cov_dydz_mm2: Some(c[1][2]),
            d_along_mm: raw(Metric::DisplacementAlongMm).value,
            significant: raw(Metric::DisplacementMm).significant,
            velocity_mm_per_day: raw(Metric::VelocityMmPerDay).value,
            time_to_failure_hours: self.failure.map(|f| f.time_to_failure_hours),
            time_to_failure_sigma_hours: self.failure.map(|f| f.sigma_hours),
            filtered: self.filtered,
        })
    }
}
