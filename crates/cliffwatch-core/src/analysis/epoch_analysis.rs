//! One epoch's analysis: datum, congruence, displacements, velocity, time to failure.

use std::collections::HashMap;

use chrono::{DateTime, Utc};
use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};

use super::alignment::{self, Similarity};
use super::block_analysis::{analyse_blocks, BlockAnalysis, BlockInputs, MemberCovariance};
use super::congruence::{test_and_localise, CongruenceTest};
use super::datum::{
    fit_iwst, fit_weighted, transform_all, transformed_joint, DatumFit, DatumMethod, Differences,
};
use super::displacement::{point_test, DisplacementRecord, PointAnalysis};
use super::epoch::{AnalysisConfig, EpochCoordinates, PointConfig, PointRole};
use super::error::AnalysisError;
use super::history::{observed_of, raw_kinematics, samples_of, History};
use super::linalg::sigma_length;
use super::pooling::{pool_forecasts, PoolInputs};
use super::reference_change::changed_since_baseline;
use super::stats::{f_quantile, normal_quantile};
use super::tracking::{track, Observed};
use super::velocity::{days_between, Sample};

/// How the epoch was brought into the reference datum.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DatumReport {
    /// Stable points (S-transformation) or IWST.
    pub method: DatumMethod,
    /// Points that defined the datum in the end.
    pub points: Vec<String>,
    /// Stable points found moving by the congruence test and excluded (in the order found).
    pub excluded: Vec<String>,
    /// Of `excluded`, the points whose displacement also changed significantly from their own
    /// earlier epochs, or that have none to compare with ([`super::reference_change`]): the
    /// reference epoch's error, common to every epoch, cancels in that change, so these are the
    /// exclusions `reference_unstable` counts. None in analyses stored before it was computed
    /// (every excluded point counts then).
    #[serde(default)]
    pub moved: Option<Vec<String>>,
    /// The global congruence tests in order (first: all stable points; then after each exclusion).
    pub congruence: Vec<CongruenceTest>,
    /// Translation of the current epoch relative to the reference datum, mm (at the datum centroid).
    pub translation_mm: [f64; 3],
    /// Small rotations about X, Y, Z in mrad (0 for a translation datum).
    pub rotation_mrad: [f64; 3],
    /// Scale difference in ppm (0 unless a similarity datum).
    pub scale_ppm: f64,
}

/// The analysis of one epoch against the reference epoch.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EpochAnalysis {
    /// Epoch id of the analysed (current) epoch.
    pub epoch: i64,
    /// Observation time of the epoch.
    pub observed_at: DateTime<Utc>,
    /// Reference epoch id.
    pub reference_epoch: i64,
    /// Datum of this epoch.
    pub datum: DatumReport,
    /// One entry per point common to both epochs, in the order of the current epoch.
    pub points: Vec<PointAnalysis>,
    /// Points of the current epoch absent from the reference (no displacement).
    pub new_points: Vec<String>,
    /// Human-readable remarks (fallbacks taken).
    pub warnings: Vec<String>,
    /// The motion of each declared block group.
    #[serde(default)]
    pub blocks: Vec<BlockAnalysis>,
}

impl EpochAnalysis {
    /// The time-series rows to store.
    pub fn records(&self) -> Vec<DisplacementRecord> {
        self.points.iter().map(|p| p.record.clone()).collect()
    }

    /// The points whose filtered forecast is their neighbours' pooled one
    /// ([`super::pooling`]), each with the other targets of the mean series.
    pub fn pooled(&self) -> Vec<(String, Vec<String>)> {
        self.points
            .iter()
            .filter(|p| !p.pooled_with.is_empty())
            .map(|p| (p.record.point.clone(), p.pooled_with.clone()))
            .collect()
    }

    /// The rows of the blocks' motion series (one per block whose motion could be estimated),
    /// in the form of a point's row: `point` names the group.
    pub fn block_records(&self) -> Vec<DisplacementRecord> {
        self.blocks
            .iter()
            .filter_map(|b| b.record(self.epoch, self.observed_at))
            .collect()
    }

    /// The analysis of one point.
    pub fn point(&self, name: &str) -> Option<&PointAnalysis> {
        self.points.iter().find(|p| p.record.point == name)
    }
}

/// The datum of an epoch and how it was found.
struct ChosenDatum {
    fit: DatumFit,
    method: DatumMethod,
    /// The congruence tests of the stable points, in order (none for IWST).
    congruence: Vec<CongruenceTest>,
    /// Indices (into the differences) of the stable points the tests excluded.
    excluded: Vec<usize>,
}

impl ChosenDatum {
    /// What the report says of the datum: its points and the excluded ones (named from
    /// `names`), the congruence tests, and the transformation's translation (mm), rotation (mrad)
    /// and scale (ppm).
    fn report(&self, names: &[String]) -> DatumReport {
        let p = &self.fit.params;
        let get = |k: usize| if k < p.len() { p[k] } else { 0.0 };
        DatumReport {
            method: self.method,
            points: self.fit.datum.iter().map(|&i| names[i].clone()).collect(),
            excluded: self.excluded.iter().map(|&i| names[i].clone()).collect(),
            moved: None,
            congruence: self.congruence.clone(),
            translation_mm: [get(0), get(1), get(2)],
            rotation_mrad: [get(3), get(4), get(5)],
            scale_ppm: get(6) * 1e3,
        }
    }
}

/// Most exact re-fits of the datum after an alignment ([`alignment`]).
const MAX_REFINEMENTS: usize = 4;

/// The differences of `current` against `reference`, their datum and its report. When the two
/// datums differ by more than the linear S-transformation tolerates (a free network whose
/// approximate coordinates held a blunder), `current` is first aligned exactly
/// ([`alignment::coarse`]) and the fitted datum applied exactly until the fit is exact
/// ([`alignment::EXACT_TOLERANCE_M`]); an epoch that needed no alignment is refitted so only when
/// its linear fit alone would err by more than [`alignment::FINE_TOLERANCE_M`]. The report then
/// gives the whole transformation.
fn datum_of(
    reference: &EpochCoordinates,
    current: &EpochCoordinates,
    role: &dyn Fn(&str) -> PointRole,
    config: &AnalysisConfig,
    warnings: &mut Vec<String>,
) -> Result<(Differences, ChosenDatum, DatumReport), AnalysisError> {
    let kind = config.transformation;
    let stable_names: Vec<&str> = reference
        .points
        .iter()
        .map(|p| p.name.as_str())
        .filter(|n| role(n) == PointRole::Stable)
        .collect();
    let mut applied = alignment::coarse(reference, current, &stable_names, kind);
    let before = warnings.len();
    let mut round = 0;
    loop {
        let aligned = applied.map(|a| alignment::undo(current, &a));
        let diffs = Differences::new(reference, aligned.as_ref().unwrap_or(current))?;
        if diffs.len() < kind.min_points() {
            return Err(AnalysisError::TooFewDatumPoints {
                found: diffs.len(),
                needed: kind.min_points(),
            });
        }
        let stable: Vec<usize> = (0..diffs.len())
            .filter(|&i| role(&diffs.names[i]) == PointRole::Stable)
            .collect();
        warnings.truncate(before);
        let chosen = choose_datum(&diffs, &stable, config, warnings)?;
        let step = Similarity::from_linear(&chosen.fit.params, &chosen.fit.centroid);
        let c = chosen.fit.centroid;
        let extent = diffs
            .xyz_m
            .iter()
            .map(|x| (x - c).norm())
            .fold(0.0, f64::max);
        // Once aligned, until the fit is exact; otherwise only when the linear fit is not enough.
        let tolerance = if applied.is_some() {
            alignment::EXACT_TOLERANCE_M
        } else {
            alignment::FINE_TOLERANCE_M
        };
        if round == MAX_REFINEMENTS || step.second_order_m(extent) <= tolerance {
            let mut report = chosen.report(&diffs.names);
            let Some(a) = applied else {
                return Ok((diffs, chosen, report));
            };
            let total = a.after(&step);
            (
                report.translation_mm,
                report.rotation_mrad,
                report.scale_ppm,
            ) = total.report_form(&c);
            // Not when only moving points pulled the coarse fit away (the datum points then agree).
            if total.second_order_m(extent) > alignment::COARSE_TOLERANCE_M {
                warnings.push(format!(
                    "the epoch's datum differs from the reference's by a rotation of {:.3}° and a \
                     scale of {:.0} ppm, beyond the linear S-transformation: it was aligned exactly \
                     (a free network takes its datum from the approximate coordinates: check them \
                     for a blunder)",
                    total.angle().to_degrees(),
                    (total.scale - 1.0) * 1e6
                ));
            }
            return Ok((diffs, chosen, report));
        }
        applied = Some(applied.map_or(step, |a| a.after(&step)));
        round += 1;
    }
}

/// The points of `current` that the reference lacks (their displacements start later).
fn new_points(current: &EpochCoordinates, diffs: &Differences) -> Vec<String> {
    let common: std::collections::HashSet<&str> = diffs.names.iter().map(String::as_str).collect();
    current
        .points
        .iter()
        .filter(|p| !common.contains(p.name.as_str()))
        .map(|p| p.name.clone())
        .collect()
}

/// The datum: the S-transformation onto the `stable` points (indices into `diffs`) after the
/// congruence test has excluded the moving ones; IWST over all points when there are too few
/// stable points or their datum fails (each fallback adds a warning).
fn choose_datum(
    diffs: &Differences,
    stable: &[usize],
    config: &AnalysisConfig,
    warnings: &mut Vec<String>,
) -> Result<ChosenDatum, AnalysisError> {
    let kind = config.transformation;
    let iwst = || -> Result<ChosenDatum, AnalysisError> {
        let all: Vec<usize> = (0..diffs.len()).collect();
        Ok(ChosenDatum {
            fit: fit_iwst(diffs, &all, kind, config.iwst_max_iterations)?,
            method: DatumMethod::Iwst,
            congruence: vec![],
            excluded: vec![],
        })
    };
    if stable.len() < kind.min_points() {
        if !stable.is_empty() {
            warnings.push(format!(
                "{} stable point(s), {} needed: robust IWST over all points instead",
                stable.len(),
                kind.min_points()
            ));
        }
        return iwst();
    }
    match test_and_localise(
        diffs,
        stable,
        kind,
        config.congruence_confidence,
        config.variance_dof,
    ) {
        Ok(c) => {
            if c.tests.last().is_some_and(|t| !t.passed) {
                warnings.push("the remaining stable points are still not congruent".into());
            }
            Ok(ChosenDatum {
                fit: c.fit,
                method: DatumMethod::StablePoints,
                congruence: c.tests,
                excluded: c.excluded,
            })
        }
        Err(e) => {
            warnings.push(format!(
                "stable-point datum failed ({e}); robust IWST over all points instead"
            ));
            iwst()
        }
    }
}

/// Which point is analysed.
struct PointId<'a> {
    name: &'a String,
    role: PointRole,
    /// Its configuration (group, direction of interest), when it has one.
    config: Option<&'a PointConfig>,
    /// Whether it defines the datum.
    in_datum: bool,
}

/// What every point of an epoch's analysis shares.
struct PointInputs<'a> {
    epoch: i64,
    observed_at: DateTime<Utc>,
    /// The reference epoch analysed against itself: every displacement is zero.
    same_epoch: bool,
    /// The reference epoch's time relative to this epoch (days; > 0 when it lies later).
    reference_t_days: f64,
    history: &'a History,
    config: &'a AnalysisConfig,
    /// 3 × the F quantile of the point test (`point_test`).
    critical3: f64,
    /// Normal quantiles of the velocity and acceleration tests.
    z_vel: f64,
    z_acc: f64,
}

impl<'a> PointInputs<'a> {
    /// The epoch's shared inputs, with the tests' quantiles computed once (each is a bisection).
    fn new(
        reference: &EpochCoordinates,
        current: &EpochCoordinates,
        same_epoch: bool,
        history: &'a History,
        config: &'a AnalysisConfig,
    ) -> Self {
        PointInputs {
            epoch: current.epoch,
            observed_at: current.observed_at,
            same_epoch,
            reference_t_days: days_between(current.observed_at, reference.observed_at),
            history,
            config,
            critical3: 3.0
                * f_quantile(
                    config.confidence,
                    3.0,
                    config.variance_dof.unwrap_or(f64::INFINITY),
                ),
            z_vel: normal_quantile(0.5 + 0.5 * config.confidence),
            z_acc: normal_quantile(config.failure.acceleration_confidence),
        }
    }
}

/// One point's analysis: its displacement `d` (mm) with covariance `cov` (mm²) in the datum, the
/// significance test, the displacement along its direction of interest, the raw kinematics and
/// forecast from its history, and the Kalman filter's estimates. `shared` is the reference
/// epoch's share of `cov`.
fn analyse_point(
    point: PointId<'_>,
    mut d: Vector3<f64>,
    mut cov: Matrix3<f64>,
    shared: Matrix3<f64>,
    e: &PointInputs<'_>,
) -> PointAnalysis {
    let PointId {
        name,
        role,
        config: pc,
        in_datum,
    } = point;
    let (config, history) = (e.config, e.history);
    // The filter's input at the reference epoch itself: the difference's covariance as every
    // epoch's carries it (the reference's errors twice), though the displacement is zero exactly.
    let filter_cov = cov;
    if e.same_epoch {
        d = Vector3::zeros();
        cov = Matrix3::zeros();
    }
    let test = point_test(
        &d,
        &cov,
        config.confidence,
        config.variance_dof,
        e.critical3,
    );
    let significant = !e.same_epoch && test.significant;
    let d_mm = d.norm();
    let sigma_mm = sigma_length(&d, &cov);
    let dir = pc.and_then(|c| c.direction).and_then(super::unit_direction);
    let (d_along, s_along) = match dir {
        Some(n) => (
            Some(n.dot(&d)),
            Some((n.transpose() * cov * n)[(0, 0)].max(0.0).sqrt()),
        ),
        None => (None, None),
    };
    let mut samples = samples_of(history.get(name), e.observed_at, config);
    samples.push(Sample {
        t_days: 0.0,
        d_mm,
        sigma_mm: sigma_mm.max(1e-6),
    });
    let (kin, failure) = raw_kinematics(&samples, significant, config, e.z_vel, e.z_acc);
    // Filtered kinematics, also at the reference epoch when earlier epochs are analysed against
    // it (a reference moved later): velocity and forecast do not depend on the reference.
    let mut series = observed_of(history.get(name), e.observed_at, config);
    let tracked = if e.same_epoch && series.is_empty() {
        None
    } else {
        series.push(Observed {
            t_days: 0.0,
            d_mm: d,
            cov_mm2: filter_cov,
        });
        track(&series, dir, None, Some(shared), e.reference_t_days, config)
    };
    let sd = |k: usize| cov[(k, k)].max(0.0).sqrt();
    let record = DisplacementRecord {
        point: name.clone(),
        epoch: e.epoch,
        observed_at: e.observed_at,
        dx_mm: d.x,
        dy_mm: d.y,
        dz_mm: d.z,
        d_mm,
        sigma_dx_mm: sd(0),
        sigma_dy_mm: sd(1),
        sigma_dz_mm: sd(2),
        sigma_mm,
        cov_dxdy_mm2: Some(cov[(0, 1)]),
        cov_dxdz_mm2: Some(cov[(0, 2)]),
        cov_dydz_mm2: Some(cov[(1, 2)]),
        d_along_mm: d_along,
        significant,
        velocity_mm_per_day: kin.map(|k| k.velocity_mm_per_day),
        time_to_failure_hours: failure.map(|f| f.time_to_failure_hours),
        time_to_failure_sigma_hours: failure.map(|f| f.sigma_hours),
        filtered: tracked.map(|t| t.values),
    };
    PointAnalysis {
        record,
        role,
        group: pc.and_then(|c| c.group.clone()),
        in_datum,
        covariance_mm2: cov.into(),
        sigma_along_mm: s_along,
        test_statistic: test.statistic,
        test_dof: test.dof,
        critical_value: test.critical,
        kinematics: kin,
        failure,
        filtered_along_mm: tracked.and_then(|t| t.along_mm),
        filtered_failure: tracked.and_then(|t| t.failure),
        pooled_with: vec![],
    }
}

/// Of the `excluded` stable points (indices into `diffs`), those that moved by the change test
/// ([`changed_since_baseline`]). The point's displacement is taken as in the epochs it is compared
/// with, in which it was mostly kept: in the datum of `fit` with the point added back (the
/// datum absorbs part of a point's error while it is kept).
fn moved_of(
    diffs: &Differences,
    reference_only: &Differences,
    fit: &DatumFit,
    excluded: &[usize],
    history: &History,
    now: DateTime<Utc>,
    e: &PointInputs<'_>,
) -> Vec<String> {
    excluded
        .iter()
        .filter(|&&i| {
            let mut with = fit.datum.clone();
            with.push(i);
            let Ok(kept) = fit_weighted(diffs, &with, e.config.transformation) else {
                return true;
            };
            let (d, cov) = transform_all(diffs, &kept)[i];
            let (_, shared) = transform_all(reference_only, &kept)[i];
            changed_since_baseline(
                &d,
                &cov,
                &shared,
                history.get(&diffs.names[i]),
                now,
                e.critical3,
            )
        })
        .map(|&i| diffs.names[i].clone())
        .collect()
}

/// Analyses `current` against `reference`.
///
/// The datum: the S-transformation onto the points whose role is `stable`, after the congruence test has
/// excluded the moving ones; IWST over all common points when fewer stable points exist than the
/// transformation needs (with a warning). Displacements (mm), their covariances (mm²), the significance
/// test at `config.confidence`, velocity and acceleration over `config.velocity_window` and the
/// inverse-velocity forecast follow for every common point. `history` holds the earlier records of the
/// points (same reference epoch).
///
/// Errors: non-finite input, a malformed joint covariance, fewer common points than the transformation
/// needs, or a datum that does not determine it.
pub fn analyse_epoch(
    reference: &EpochCoordinates,
    current: &EpochCoordinates,
    points: &[PointConfig],
    history: &History,
    config: &AnalysisConfig,
) -> Result<EpochAnalysis, AnalysisError> {
    config.validate()?;
    let cfg: HashMap<&str, &PointConfig> = points.iter().map(|p| (p.name.as_str(), p)).collect();
    let role = |name: &str| cfg.get(name).map(|c| c.role).unwrap_or_default();
    let mut warnings = vec![];
    let (diffs, chosen, mut datum) = datum_of(reference, current, &role, config, &mut warnings)?;
    let new_points = new_points(current, &diffs);
    // The reference epoch itself (not a mean of several epochs that includes it): zero.
    let same_epoch = reference.epoch == current.epoch && reference.points == current.points;
    let fit = chosen.fit;
    let transformed = transform_all(&diffs, &fit);
    // The reference epoch's share of each displacement's covariance, common to every epoch.
    let reference_only = diffs.reference_only();
    let shared: Vec<Matrix3<f64>> = transform_all(&reference_only, &fit)
        .into_iter()
        .map(|(_, c)| c)
        .collect();
    let in_datum: std::collections::HashSet<usize> = fit.datum.iter().copied().collect();
    let epoch_wide = PointInputs::new(reference, current, same_epoch, history, config);
    datum.moved = Some(moved_of(
        &diffs,
        &reference_only,
        &fit,
        &chosen.excluded,
        history,
        current.observed_at,
        &epoch_wide,
    ));
    let filter_cov: Vec<Matrix3<f64>> = transformed.iter().map(|(_, c)| *c).collect();
    let mut out: Vec<PointAnalysis> = transformed
        .into_iter()
        .enumerate()
        .map(|(i, (d, cov))| {
            let name = &diffs.names[i];
            let point = PointId {
                name,
                role: role(name),
                config: cfg.get(name.as_str()).copied(),
                in_datum: in_datum.contains(&i),
            };
            analyse_point(point, d, cov, shared[i], &epoch_wide)
        })
        .collect();
    if !same_epoch {
        pool_forecasts(
            &mut out,
            &PoolInputs {
                current,
                history,
                config,
                filter_cov: &filter_cov,
                shared: &shared,
                reference_t_days: epoch_wide.reference_t_days,
                critical3: epoch_wide.critical3,
            },
        );
    }
    // The joint covariance of any set of points' displacements (the blocks' members).
    let index: HashMap<&str, usize> = diffs
        .names
        .iter()
        .enumerate()
        .map(|(i, n)| (n.as_str(), i))
        .collect();
    let joint_of = |names: &[String]| -> Option<MemberCovariance> {
        let idx: Vec<usize> = names
            .iter()
            .map(|n| index.get(n.as_str()).copied())
            .collect::<Option<_>>()?;
        Some(MemberCovariance {
            joint_mm2: transformed_joint(&diffs, &fit, &idx),
            shared_mm2: transformed_joint(&reference_only, &fit, &idx),
        })
    };
    let blocks = analyse_blocks(&BlockInputs {
        reference,
        points,
        out: &out,
        history,
        now: current.observed_at,
        same_epoch,
        reference_t_days: epoch_wide.reference_t_days,
        config,
        critical3: epoch_wide.critical3,
        z_vel: epoch_wide.z_vel,
        z_acc: epoch_wide.z_acc,
        joint_of: &joint_of,
    });
    Ok(EpochAnalysis {
        epoch: current.epoch,
        observed_at: current.observed_at,
        reference_epoch: reference.epoch,
        datum,
        points: out,
        new_points,
        warnings,
        blocks,
    })
}
