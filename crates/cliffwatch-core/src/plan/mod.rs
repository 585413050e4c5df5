//! Campaign design (issue 78): the precision and the smallest detectable movement of every target
//! of a *planned* camera network, before anyone installs it.
//!
//! The pre-analysis takes the plan's geometry as truth: [`network::planned_epoch`] projects each
//! target into each station with collinearity (eq 2 of the paper; the orthogonal model (5)+(9) is
//! as rigorous, so the residuals are zero), and the ordinary adjustment
//! ([`crate::photogrammetry::adjust()`]) solves that noise-free epoch with the planned a-priori σ
//! and [`AdjustOptions::apriori_precision`]: its covariances are then σ0²·Qxx from the normal
//! equations at the planned geometry with the variance factor 1 — what an epoch of the plan will
//! show on average, with no simulation. Each target's 3 × 3 covariance gives σX, σY, σZ, the σ
//! along the face normal, and the minimum detectable displacement between two epochs of the plan
//! (displacement covariance 2Σ, two independent epochs of the same network) by
//! [`minimum_detectable`], the point page's definition (single-point χ²(3) test at the confidence,
//! detected with probability `power`).

pub mod input;
pub mod network;
pub mod quality;
pub mod site;
pub mod whatif;

use std::collections::BTreeMap;

use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};

use crate::analysis::sensitivity::minimum_detectable;
use crate::analysis::stats::chi2_quantile;
use crate::photogrammetry::statistics::design::ParameterCorrelation;
use crate::photogrammetry::{adjust, AdjustError, AdjustOptions, Cancel, Model, C_PRIOR_RELATIVE};
use quality::ObservationReliability;

pub use input::{Plan, PlanCamera, PlanDatum, PlanError, PlanStation, PlanTarget};
pub use network::{look_at, planned_epoch, PlannedEpoch};
pub use site::{site_plan, SiteNetwork};
pub use whatif::{apply_changes, PlanChange};

/// σ of the three site-frame coordinates in mm.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct SigmaXyz {
    /// σX in mm.
    pub x: f64,
    /// σY in mm.
    pub y: f64,
    /// σZ in mm.
    pub z: f64,
}

/// The predicted precision of one target.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct TargetPrecision {
    /// Point name.
    pub point: String,
    /// A known (stable) point.
    pub known: bool,
    /// Its planned coordinates, m (site frame).
    pub xyz: [f64; 3],
    /// Number of stations that see it.
    pub cameras: usize,
    /// The stations that see it.
    pub stations: Vec<String>,
    /// σX, σY, σZ in mm (None when seen by fewer than two stations).
    pub sigma_mm: Option<SigmaXyz>,
    /// The 3 × 3 covariance in mm² (site frame).
    pub covariance_mm2: Option<[[f64; 3]; 3]>,
    /// σ along the face normal in mm.
    pub sigma_normal_mm: Option<f64>,
    /// Minimum detectable displacement between two epochs along the face normal, mm.
    pub mdd_normal_mm: Option<f64>,
    /// Minimum detectable displacement between two epochs in the worst 3-D direction, mm.
    pub mdd_3d_mm: Option<f64>,
    /// The largest angle between two of its stations' rays, degrees (None when seen by fewer
    /// than two).
    pub intersection_deg: Option<f64>,
}

/// The predicted σ of one camera's self-calibrated c.
///
/// The adjustment holds c with a weak prior centred on the given c (σ
/// [`C_PRIOR_RELATIVE`] of it): `sigma_c_mm`, what an epoch's adjustment reports, counts the
/// prior's information as if the given c were drawn afresh in each epoch. Every epoch of a camera
/// gives the same c, so the prior's share is a common offset of those epochs, and ĉ scatters
/// from epoch to epoch by `sigma_c_repeat_mm` = σc·√(1 − σc²/σp²) (σp the prior's σ), the
/// sampling σ of the estimator with the prior centre fixed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct InteriorPrecision {
    /// Camera id.
    pub camera: String,
    /// σ of c in mm, the adjustment's (None when c is held fixed).
    pub sigma_c_mm: Option<f64>,
    /// σ of ĉ's scatter between epochs that give the same nominal c, mm (None when c is held
    /// fixed).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sigma_c_repeat_mm: Option<f64>,
    /// Share of c's information (1/σc²) that comes from the adjustment's prior on c rather than
    /// from the images, 0–1 (None when c is held fixed).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub c_prior_share: Option<f64>,
}

/// `(sigma_c_repeat_mm, c_prior_share)` of a self-calibrated c of σ `sigma_c_mm` whose given
/// value is `c_mm` (see [`InteriorPrecision`]).
pub fn c_repeatability(sigma_c_mm: f64, c_mm: f64) -> (f64, f64) {
    let prior = C_PRIOR_RELATIVE * c_mm.abs();
    let share = if prior > 0.0 {
        (sigma_c_mm / prior).powi(2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (sigma_c_mm * (1.0 - share).sqrt(), share)
}

/// The pre-analysis of a plan.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct PlanReport {
    /// Projection model.
    pub model: Model,
    /// Confidence of the displacement test (0–1).
    pub confidence: f64,
    /// Detection probability of the MDD (0–1).
    pub power: f64,
    /// The unit face normal used (site frame).
    pub face_normal: [f64; 3],
    /// Degrees of freedom of the planned adjustment.
    pub dof: i64,
    /// The largest σ of a self-calibrated c over the cameras, mm (None when every c is fixed).
    pub sigma_c_mm: Option<f64>,
    /// σ of c per camera.
    pub interior: Vec<InteriorPrecision>,
    /// One entry per target, in plan order.
    pub targets: Vec<TargetPrecision>,
    /// One entry per image observation of the planned adjustment: redundancy numbers and
    /// smallest detectable blunders ([`quality::reliability`]).
    pub observations: Vec<ObservationReliability>,
    /// The smallest redundancy number of an image coordinate (None without observations).
    pub min_redundancy: Option<f64>,
    /// The strongest correlations of the self-calibrated parameters with each other and with
    /// the images' exterior unknowns, strongest first (at most
    /// [`quality::CORRELATIONS_LISTED`]).
    pub correlations: Vec<ParameterCorrelation>,
    /// Weak points of the plan, in words: targets seen by fewer than two stations, weak
    /// intersections (below [`quality::WEAK_INTERSECTION_DEG`]), weakly controlled observations
    /// (redundancy below [`quality::LOW_REDUNDANCY`]), a self-calibrated c with σ beyond
    /// [`WEAK_C_RELATIVE_SIGMA`] of c, strongly correlated with another unknown, or not
    /// determinable with the orthogonal model ([`quality::c_determinability`]), and the planned
    /// adjustment's own warnings.
    pub warnings: Vec<String>,
}

/// σ of a self-calibrated c, relative to c, beyond which the report warns that c is weakly
/// determined: 1 % (a scale error of that size in the targets' distances from the cameras).
pub const WEAK_C_RELATIVE_SIGMA: f64 = 0.01;

/// Largest |coordinate| of a planned target or station, m (a site frame's coordinates, UTM
/// included, stay far below).
pub const MAX_COORDINATE_M: f64 = 1e7;

/// Checks the plan's numbers; the error names the item.
fn check(plan: &Plan) -> Result<(), PlanError> {
    let bad = |item: &str, why: &str| {
        Err(PlanError::Invalid {
            item: item.into(),
            why: why.into(),
        })
    };
    if !(plan.sigma_px.is_finite() && plan.sigma_px > 0.0) {
        return bad("sigma_px", "must be a positive number of pixels");
    }
    if !(0.5..1.0).contains(&plan.confidence) {
        return bad("confidence", "must lie in [0.5, 1)");
    }
    if !(plan.power > 0.0 && plan.power < 1.0) {
        return bad("power", "must lie in (0, 1)");
    }
    if plan.cameras.is_empty() || plan.stations.len() < 2 {
        return bad(
            "stations",
            "a plan needs a camera and at least two stations",
        );
    }
    if !(plan.known_sigma_m.is_finite() && plan.known_sigma_m > 0.0) {
        return bad("known_sigma_m", "must be a positive number of metres");
    }
    for t in plan.targets.iter().filter(|t| t.sigma_m.is_some()) {
        if !t.sigma_m.is_some_and(|v| v.is_finite() && v > 0.0) {
            return bad(&format!("target {}", t.point), "sigma_m must be positive");
        }
    }
    for c in &plan.cameras {
        if c.sigma_px.is_some_and(|v| !(v.is_finite() && v > 0.0)) {
            return bad(&format!("camera {}", c.id), "sigma_px must be positive");
        }
        if !(c.c_mm > 0.0
            && c.c_mm <= 1e4
            && c.pixel_size_mm > 0.0
            && c.pixel_size_mm <= 1.0
            && c.width_px > 0
            && c.height_px > 0)
        {
            return bad(
                &format!("camera {}", c.id),
                "c_mm (up to 10 000), pixel_size_mm (up to 1), width_px and height_px must be \
                 positive",
            );
        }
    }
    if plan.datum == PlanDatum::Control && plan.targets.iter().filter(|t| t.known).count() < 4 {
        return bad(
            "targets",
            "at least four known (stable) targets are needed for the control datum",
        );
    }
    if plan.targets.len() < 4 {
        return bad("targets", "at least four targets are needed");
    }
    let inside = |v: &f64| v.is_finite() && v.abs() <= MAX_COORDINATE_M;
    for t in &plan.targets {
        if !t.xyz.iter().all(inside) {
            return bad(
                &format!("target {}", t.point),
                "coordinates must be finite numbers within ±1e7 m",
            );
        }
    }
    for s in &plan.stations {
        if !s.position.iter().chain(&s.aim).all(inside) {
            return bad(
                &format!("station {}", s.name),
                "position and aim must be finite numbers within ±1e7 m",
            );
        }
    }
    Ok(())
}

/// The face normal: the plan's, or from the targets' centroid toward the stations'.
fn face_normal(plan: &Plan) -> Vector3<f64> {
    let mean = |v: &mut dyn Iterator<Item = [f64; 3]>| {
        let (s, n) = v.fold((Vector3::zeros(), 0.0), |(s, n), x| {
            (s + Vector3::from(x), n + 1.0)
        });
        s / f64::max(n, 1.0)
    };
    let n = plan.face_normal.map(Vector3::from).unwrap_or_else(|| {
        mean(&mut plan.stations.iter().map(|s| s.position))
            - mean(&mut plan.targets.iter().map(|t| t.xyz))
    });
    n.try_normalize(0.0).unwrap_or_else(Vector3::z)
}

/// The pre-analysis of a plan: each target's predicted covariance, σ, σ along the face normal and
/// minimum detectable displacements, σ of c, and warnings (targets seen by fewer than two
/// stations). See the module documentation for the method.
pub fn pre_analysis(plan: &Plan) -> Result<PlanReport, PlanError> {
    pre_analysis_cancellable(plan, Cancel::default())
}

/// [`pre_analysis`] that stops early (an [`crate::photogrammetry::AdjustError::Cancelled`]
/// error) once `cancel` is cancelled or past its deadline.
pub fn pre_analysis_cancellable(plan: &Plan, cancel: Cancel) -> Result<PlanReport, PlanError> {
    check(plan)?;
    let planned = planned_epoch(plan)?;
    let options = AdjustOptions {
        model: plan.model,
        apriori_precision: true,
        design_statistics: true,
        snooping: false,
        cancel,
        ..AdjustOptions::default()
    };
    let xyz: BTreeMap<&str, [f64; 3]> = plan
        .targets
        .iter()
        .map(|t| (t.point.as_str(), t.xyz))
        .collect();
    let seen: BTreeMap<&str, Vec<[f64; 3]>> = planned
        .epoch
        .images
        .iter()
        .map(|i| {
            let pts = i
                .observations
                .iter()
                .filter_map(|o| xyz.get(o.point.as_str()).copied())
                .collect();
            (i.id.as_str(), pts)
        })
        .collect();
    // A singular network whose c the orthogonal model cannot determine: said with the reason.
    let adjustment = adjust(&planned.epoch, &options).map_err(|e| {
        let why = quality::c_determinability(plan, &seen);
        if why.is_empty() || matches!(e, AdjustError::Cancelled { .. }) {
            PlanError::Adjustment(e)
        } else {
            PlanError::Invalid {
                item: "cameras".into(),
                why: format!("{e}; {}", why.join("; ")),
            }
        }
    })?;
    let normal = face_normal(plan);
    let critical = chi2_quantile(plan.confidence, 3.0);
    let mut warnings = Vec::new();
    let targets: Vec<TargetPrecision> = plan
        .targets
        .iter()
        .zip(&planned.seen_by)
        .map(|(t, (_, stations))| {
            let mut out = TargetPrecision {
                point: t.point.clone(),
                known: t.known,
                xyz: t.xyz,
                cameras: stations.len(),
                stations: stations.clone(),
                sigma_mm: None,
                covariance_mm2: None,
                sigma_normal_mm: None,
                mdd_normal_mm: None,
                mdd_3d_mm: None,
                intersection_deg: quality::intersection_deg(plan, t.xyz, stations),
            };
            let Some(p) = adjustment.point(&t.point).filter(|_| stations.len() >= 2) else {
                warnings.push(format!(
                    "target {} is seen by {} station(s): at least two are needed, it is not \
                     measured",
                    t.point,
                    stations.len()
                ));
                return out;
            };
            let cov = Matrix3::from_fn(|i, j| p.covariance_m2[i][j] * 1e6);
            out.sigma_mm = Some(SigmaXyz {
                x: cov[(0, 0)].sqrt(),
                y: cov[(1, 1)].sqrt(),
                z: cov[(2, 2)].sqrt(),
            });
            out.covariance_mm2 = Some(std::array::from_fn(|i| {
                std::array::from_fn(|j| cov[(i, j)])
            }));
            out.sigma_normal_mm = Some((normal.transpose() * cov * normal)[(0, 0)].max(0.0).sqrt());
            // Two independent epochs of the same network: the displacement's covariance is 2Σ.
            if let Some(m) =
                minimum_detectable(&(cov * 2.0), critical, 3, plan.power, Some(&normal))
            {
                out.mdd_normal_mm = m.along_mm;
                out.mdd_3d_mm = Some(m.worst_mm);
            }
            out
        })
        .collect();
    let interior: Vec<InteriorPrecision> = adjustment
        .report
        .cameras
        .iter()
        .map(|c| {
            let given = plan
                .cameras
                .iter()
                .find(|p| p.id == c.id)
                .map_or(c.c_mm, |p| p.c_mm);
            let repeat = c.c_sigma_mm.map(|s| c_repeatability(s, given));
            InteriorPrecision {
                camera: c.id.clone(),
                sigma_c_mm: c.c_sigma_mm,
                sigma_c_repeat_mm: repeat.map(|r| r.0),
                c_prior_share: repeat.map(|r| r.1),
            }
        })
        .collect();
    for (c, i) in adjustment.report.cameras.iter().zip(&interior) {
        if let Some(sc) = c
            .c_sigma_mm
            .filter(|sc| *sc > WEAK_C_RELATIVE_SIGMA * c.c_mm)
        {
            warnings.push(format!(
                "camera {}: c is weakly determined (σ {sc:.2} mm, {:.1} % of c; {:.0} % of that \
                 from the adjustment's prior of {:.0} % of the given c, the images alone \
                 carrying the rest): c shows only through the perspective of the targets' depth \
                 differences as seen from the stations; more relief among the targets, stations \
                 at different distances or more convergent views strengthen it, or hold c fixed \
                 from a calibration",
                c.id,
                100.0 * sc / c.c_mm,
                100.0 * i.c_prior_share.unwrap_or(0.0),
                100.0 * C_PRIOR_RELATIVE
            ));
        }
    }
    let angles: Vec<(String, f64)> = targets
        .iter()
        .filter(|t| t.sigma_mm.is_some())
        .filter_map(|t| t.intersection_deg.map(|a| (t.point.clone(), a)))
        .collect();
    quality::weak_intersections(&angles, &mut warnings);
    let design = adjustment.design.clone().unwrap_or_default();
    let observations = quality::reliability(&design, plan.confidence, plan.power, &mut warnings);
    let min_redundancy = observations
        .iter()
        .map(|o| o.redundancy[0].min(o.redundancy[1]))
        .reduce(f64::min);
    let correlations = quality::strongest_correlations(&design, &mut warnings);
    warnings.extend(quality::c_determinability(plan, &seen));
    warnings.extend(
        adjustment
            .report
            .warnings
            .iter()
            // Normalized residuals of zero residuals say nothing (0/0 where r is tiny).
            .filter(|w| !w.contains("|w|"))
            .map(|w| format!("planned adjustment: {w}")),
    );
    let sigma_c_mm = interior
        .iter()
        .filter_map(|c| c.sigma_c_mm)
        .reduce(f64::max);
    Ok(PlanReport {
        model: plan.model,
        confidence: plan.confidence,
        power: plan.power,
        face_normal: normal.into(),
        dof: adjustment.report.dof,
        sigma_c_mm,
        interior,
        targets,
        observations,
        min_redundancy,
        correlations,
        warnings,
    })
}
