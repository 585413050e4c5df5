//! Campaign design checked against simulation (issue 78): the pre-analysis of a plan
//! ([`cliffwatch_core::plan::pre_analysis`]) against repeated simulated epochs of the plan
//! ([`crate::scenes::long_range_epoch`]), each adjusted as the plan assumes, and against the σ
//! those adjustments report.
//!
//! The plan is the long-range scene of a seed with 16 targets and 4 stations 145–155 m from a
//! 5 m × 3 m face with 1 m relief, 400 mm lens (c self-calibrated, given 1 % off), image σ
//! 0.25 px, [`KNOWN`] known with σ 1 mm (control datum), confidence 0.95, power 0.8. Each epoch
//! has the simulator's image noise (its own noise seed) and the known targets' coordinates given
//! with Gaussian noise of their σ; it is adjusted with the plan's model and datum, c
//! self-calibrated, no data snooping, covariances at the a-priori variance (σ0 = 1). The
//! detection trials pair each epoch with a second one in which every unknown target is moved by
//! its predicted MDD (along the face normal, or along its worst direction), tested by the
//! single-point test `dᵀ(2Σ)⁻¹d > χ²(3; confidence)` with the plan's Σ.

use std::collections::BTreeMap;

use cliffwatch_core::analysis::stats::chi2_quantile;
use cliffwatch_core::photogrammetry::input::epoch::{ApproxInput, ControlInput, EpochInput};
use cliffwatch_core::photogrammetry::{
    adjust, AdjustOptions, Adjustment, Cancel, C_PRIOR_RELATIVE,
};
use cliffwatch_core::plan::{
    pre_analysis, site_plan, Plan, PlanCamera, PlanError, PlanReport, PlanStation, PlanTarget,
    SiteNetwork,
};
use nalgebra::{Matrix3, SymmetricEigen, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use thiserror::Error;

use crate::scenes::{
    long_range, long_range_epoch, EpochVariation, LongRangeParams, SceneError, Truth,
};

/// σ of one image coordinate in the plan and the simulation, pixels.
pub const SIGMA_PX: f64 = 0.25;

/// The known (stable) targets of the plan, spread over the face.
pub const KNOWN: [&str; 4] = ["T101", "T106", "T113", "T116"];

/// Why a measurement could not be made.
#[derive(Debug, Error)]
pub enum AgreementError {
    /// The simulated scene could not be built.
    #[error("scene: {0}")]
    Scene(#[from] SceneError),
    /// The plan could not be analysed.
    #[error("plan: {0}")]
    Plan(#[from] PlanError),
    /// A figure the plan should give is missing (a target not measured, c held fixed).
    #[error("the pre-analysis gives no {0}")]
    Missing(String),
}

/// What to measure.
#[derive(Debug, Clone, PartialEq)]
pub struct AgreementOptions {
    /// Seed of the scene's geometry.
    pub seed: u64,
    /// Number of simulated epochs (each with two displaced companions for the detection trials).
    pub epochs: usize,
    /// Relative error of the c given to the adjustment (the scene's `c_error`, default 0.01).
    pub c_error: f64,
    /// Draw each epoch's given c afresh from the adjustment's prior on c (relative error
    /// N(0, [`C_PRIOR_RELATIVE`]), within ±0.4) instead of `c_error`: the premise under which the
    /// adjustment's σc is the scatter of ĉ.
    pub c_drawn: bool,
}

impl Default for AgreementOptions {
    fn default() -> Self {
        AgreementOptions {
            seed: 1,
            epochs: 200,
            c_error: 0.01,
            c_drawn: false,
        }
    }
}

/// The figures of one target over the epochs.
#[derive(Debug, Clone, PartialEq)]
pub struct TargetAgreement {
    /// Point name.
    pub point: String,
    /// A known (stable) target.
    pub known: bool,
    /// rms of (error / predicted σ) over the epochs, X, Y, Z (dimensionless).
    pub rms: [f64; 3],
    /// Mean of σ_adjustment / σ_predicted over the epochs, X, Y, Z (dimensionless).
    pub sigma_ratio: [f64; 3],
    /// Largest |σ_adjustment / σ_predicted − 1| of a single epoch and component.
    pub sigma_ratio_worst: f64,
}

/// The measured agreement of one plan with its simulated epochs.
#[derive(Debug, Clone, PartialEq)]
pub struct Agreement {
    /// The plan's pre-analysis.
    pub report: PlanReport,
    /// Per target, in plan order.
    pub targets: Vec<TargetAgreement>,
    /// Σ (error/σ_predicted)² over targets and epochs, X, Y, Z.
    pub sum_squares: [f64; 3],
    /// Number of (target, epoch) terms in each of `sum_squares`.
    pub terms: usize,
    /// Σ (error along the face normal / predicted σ along it)² over targets and epochs.
    pub normal_sum_squares: f64,
    /// Σ ((ĉ − c)/σc)² over the epochs, with σc the predicted `sigma_c_mm`.
    pub c_sum_squares: f64,
    /// Σ ((ĉ − c)/σc_repeat)² over the epochs, with the predicted `sigma_c_repeat_mm`.
    pub c_repeat_sum_squares: f64,
    /// Mean of σc_adjustment / σc_predicted.
    pub c_sigma_ratio: f64,
    /// The existing site: each epoch taken as a site ([`site_plan`] of it, pre-analysed) against
    /// its own adjustment's σ: mean of σ_adjustment / σ_predicted over epochs, targets and
    /// components.
    pub site_ratio_mean: f64,
    /// The existing site: the largest |σ_adjustment / σ_predicted − 1| of any epoch, target and
    /// component.
    pub site_ratio_worst: f64,
    /// Detection trials along the face normal: (detected, trials).
    pub normal: (usize, usize),
    /// Detection trials along each target's worst direction: (detected, trials).
    pub worst: (usize, usize),
    /// Epochs used.
    pub epochs: usize,
    /// Epochs (or displaced companions) whose adjustment failed, left out.
    pub failed: usize,
    /// The first failed adjustment's error, in words.
    pub first_failure: Option<String>,
}

impl Agreement {
    /// Pooled rms of (error / predicted σ) over targets and epochs, X, Y, Z.
    pub fn pooled_rms(&self) -> [f64; 3] {
        self.sum_squares
            .map(|s| (s / self.terms.max(1) as f64).sqrt())
    }

    /// Pooled rms of (error / predicted σ) along the face normal over targets and epochs.
    pub fn normal_rms(&self) -> f64 {
        (self.normal_sum_squares / self.terms.max(1) as f64).sqrt()
    }

    /// rms of (ĉ − c)/σc and of (ĉ − c)/σc_repeat over the epochs.
    pub fn c_rms(&self) -> (f64, f64) {
        let n = self.epochs.max(1) as f64;
        (
            (self.c_sum_squares / n).sqrt(),
            (self.c_repeat_sum_squares / n).sqrt(),
        )
    }
}

/// The scene of `seed`: 16 targets, 4 stations 145–155 m away, image noise [`SIGMA_PX`], c given
/// off by `c_error`.
pub fn scene_params(seed: u64, c_error: f64) -> LongRangeParams {
    LongRangeParams {
        seed,
        n_points: 16,
        n_stations: 4,
        distance_min_m: 145.0,
        distance_max_m: 155.0,
        noise_px: SIGMA_PX,
        c_error,
        ..LongRangeParams::default()
    }
}

/// The plan of a scene: its cameras aimed exactly as in the truth (up = r2), its targets at their
/// true coordinates, [`KNOWN`] known with σ 1 mm, c self-calibrated.
pub fn plan_of(p: &LongRangeParams, truth: &Truth) -> Plan {
    let stations = truth
        .cameras
        .iter()
        .map(|(name, cam)| PlanStation {
            name: name.clone(),
            camera: "cam".into(),
            position: cam.xo,
            aim: std::array::from_fn(|i| cam.xo[i] - 100.0 * cam.r[2][i]),
            up: Some(cam.r[1]),
            sees: None,
        })
        .collect();
    let targets = truth
        .points
        .iter()
        .map(|(name, xyz)| PlanTarget {
            point: name.clone(),
            xyz: *xyz,
            known: KNOWN.contains(&name.as_str()),
            sigma_m: None,
        })
        .collect();
    Plan {
        model: Default::default(),
        sigma_px: SIGMA_PX,
        confidence: 0.95,
        power: 0.8,
        known_sigma_m: 0.001,
        datum: Default::default(),
        face_normal: None,
        cameras: vec![PlanCamera {
            id: "cam".into(),
            c_mm: p.c_mm,
            calibrate_c: true,
            pixel_size_mm: p.pixel_size_mm,
            width_px: p.width_px,
            height_px: p.height_px,
            sigma_px: None,
        }],
        stations,
        targets,
    }
}

/// One predicted target: name, known, covariance (mm²).
struct Predicted {
    name: String,
    known: bool,
    cov: Matrix3<f64>,
}

/// Measures the agreement of the plan of `options.seed` with `options.epochs` simulated epochs.
pub fn measure(options: &AgreementOptions) -> Result<Agreement, AgreementError> {
    let p = scene_params(options.seed, options.c_error);
    let (_, truth) = long_range(&p)?;
    let plan = plan_of(&p, &truth);
    let report = pre_analysis(&plan)?;
    let missing = |what: &str| AgreementError::Missing(what.into());
    let n = Vector3::from(report.face_normal);
    let mut predicted = Vec::new();
    let (mut normal_moves, mut worst_moves) = (Vec::new(), Vec::new());
    for (k, t) in report.targets.iter().enumerate() {
        let c = t.covariance_mm2.ok_or_else(|| missing("covariance"))?;
        let cov = Matrix3::from_fn(|i, j| c[i][j]);
        if !t.known {
            let along = n * t.mdd_normal_mm.ok_or_else(|| missing("MDD"))? * 1e-3;
            normal_moves.push((k, [along[0], along[1], along[2]]));
            let eigen = SymmetricEigen::new(cov);
            let axis = eigen
                .eigenvectors
                .column(eigen.eigenvalues.imax())
                .into_owned();
            let worst = axis * t.mdd_3d_mm.ok_or_else(|| missing("MDD"))? * 1e-3;
            worst_moves.push((k, [worst[0], worst[1], worst[2]]));
        }
        predicted.push(Predicted {
            name: t.point.clone(),
            known: t.known,
            cov,
        });
    }
    let camera = report.interior.first().ok_or_else(|| missing("camera"))?;
    let sigma_c = camera.sigma_c_mm.ok_or_else(|| missing("σ of c"))?;
    let sigma_c_repeat = camera.sigma_c_repeat_mm.ok_or_else(|| missing("σ of c"))?;
    let critical = chi2_quantile(plan.confidence, 3.0);
    let adjust_options = AdjustOptions {
        model: plan.model,
        snooping: false,
        apriori_precision: true,
        ..AdjustOptions::default()
    };
    let mut rng = ChaCha8Rng::seed_from_u64(1_000_000 + options.seed);
    let control = Normal::new(0.0, plan.known_sigma_m).map_err(|_| missing("known σ"))?;
    let prior = Normal::new(0.0, C_PRIOR_RELATIVE).map_err(|_| missing("prior"))?;
    let epoch = |noise_seed: u64, displaced: &[(usize, [f64; 3])], rng: &mut ChaCha8Rng| {
        let variation = EpochVariation {
            noise_seed,
            displaced: displaced.to_vec(),
        };
        let mut given = p.clone();
        if options.c_drawn {
            given.c_error = prior.sample(rng).clamp(-0.4, 0.4);
        }
        let (mut input, truth) = long_range_epoch(&given, &variation)?;
        for t in plan.targets.iter().filter(|t| t.known) {
            let x = *truth
                .points
                .get(&t.point)
                .ok_or_else(|| AgreementError::Missing("true point".into()))?;
            input.control.push(ControlInput {
                point: t.point.clone(),
                X: x[0] + control.sample(rng),
                Y: x[1] + control.sample(rng),
                Z: x[2] + control.sample(rng),
                sigma_m: Some(plan.known_sigma_m),
            });
        }
        Ok::<_, AgreementError>(adjust(&input, &adjust_options).map(|a| (a, truth.points, input)))
    };
    let mut out = Agreement {
        targets: predicted
            .iter()
            .map(|t| TargetAgreement {
                point: t.name.clone(),
                known: t.known,
                rms: [0.0; 3],
                sigma_ratio: [0.0; 3],
                sigma_ratio_worst: 0.0,
            })
            .collect(),
        report: report.clone(),
        sum_squares: [0.0; 3],
        terms: 0,
        normal_sum_squares: 0.0,
        c_sum_squares: 0.0,
        c_repeat_sum_squares: 0.0,
        c_sigma_ratio: 0.0,
        site_ratio_mean: 0.0,
        site_ratio_worst: 0.0,
        normal: (0, 0),
        worst: (0, 0),
        epochs: 0,
        failed: 0,
        first_failure: None,
    };
    for e in 0..options.epochs as u64 {
        let (a, truth, input) = match epoch(10_000 + e, &[], &mut rng)? {
            Ok(x) => x,
            Err(err) => {
                out.failed += 1;
                out.first_failure.get_or_insert(err.to_string());
                continue;
            }
        };
        errors(
            &mut out,
            &predicted,
            &a,
            &truth,
            (p.c_mm, n),
            (sigma_c, sigma_c_repeat),
        )?;
        let (mean, worst) = site_ratios(&input, &a, plan.confidence)?;
        out.site_ratio_mean += mean;
        out.site_ratio_worst = out.site_ratio_worst.max(worst);
        for (kind, moves) in [(0u64, &normal_moves), (1, &worst_moves)] {
            let b = match epoch((kind + 2) * 100_000 + e, moves, &mut rng)? {
                Ok((b, _, _)) => b,
                Err(err) => {
                    out.failed += 1;
                    out.first_failure.get_or_insert(err.to_string());
                    continue;
                }
            };
            let tally = if kind == 0 {
                &mut out.normal
            } else {
                &mut out.worst
            };
            for t in predicted.iter().filter(|t| !t.known) {
                let (xa, xb) = match (a.point(&t.name), b.point(&t.name)) {
                    (Some(xa), Some(xb)) => (xa.xyz, xb.xyz),
                    _ => return Err(missing("adjusted point")),
                };
                let d = Vector3::from_fn(|k, _| (xb[k] - xa[k]) * 1e3);
                let inverse = (t.cov * 2.0)
                    .try_inverse()
                    .ok_or_else(|| missing("invertible covariance"))?;
                if (d.transpose() * inverse * d)[(0, 0)] > critical {
                    tally.0 += 1;
                }
                tally.1 += 1;
            }
        }
    }
    let n = out.epochs.max(1) as f64;
    for t in &mut out.targets {
        t.rms = t.rms.map(|s| (s / n).sqrt());
        t.sigma_ratio = t.sigma_ratio.map(|s| s / n);
    }
    out.c_sigma_ratio /= n;
    out.site_ratio_mean /= n;
    Ok(out)
}

/// An epoch taken as an existing site (its input, with its adjusted coordinates as start values;
/// [`KNOWN`] stable, control datum): the plan of the site ([`site_plan`]) pre-analysed, against
/// the σ the epoch's adjustment `a` (a-priori variance) reports. Returns the mean of
/// σ_adjustment / σ_predicted over targets and components, and the largest |ratio − 1|.
pub fn site_ratios(
    input: &EpochInput,
    a: &Adjustment,
    confidence: f64,
) -> Result<(f64, f64), AgreementError> {
    let mut epoch = input.clone();
    epoch.approx = a
        .points
        .iter()
        .map(|p| ApproxInput {
            point: p.name.clone(),
            X: p.xyz[0],
            Y: p.xyz[1],
            Z: p.xyz[2],
        })
        .collect();
    let net = SiteNetwork {
        model: a.report.model,
        epoch,
        stable: KNOWN.iter().map(|k| k.to_string()).collect(),
        control_datum: true,
        confidence,
        face_normal: None,
    };
    let plan = site_plan(&net, Cancel::default())?;
    let report = pre_analysis(&plan)?;
    let (mut sum, mut n, mut worst) = (0.0, 0usize, 0.0f64);
    for t in &report.targets {
        let s = t
            .sigma_mm
            .ok_or_else(|| AgreementError::Missing("σ".into()))?;
        let p = a
            .point(&t.point)
            .ok_or_else(|| AgreementError::Missing("adjusted point".into()))?;
        for (i, predicted) in [s.x, s.y, s.z].into_iter().enumerate() {
            let ratio = (p.covariance_m2[i][i] * 1e6).sqrt() / predicted;
            sum += ratio;
            n += 1;
            worst = worst.max((ratio - 1.0).abs());
        }
    }
    Ok((sum / n.max(1) as f64, worst))
}

/// Adds one epoch's errors and σ ratios (the per-target sums are turned into rms and means at the
/// end of [`measure`]).
fn errors(
    out: &mut Agreement,
    predicted: &[Predicted],
    a: &Adjustment,
    truth: &BTreeMap<String, [f64; 3]>,
    (c_mm, normal): (f64, Vector3<f64>),
    (sigma_c, sigma_c_repeat): (f64, f64),
) -> Result<(), AgreementError> {
    for (t, o) in predicted.iter().zip(&mut out.targets) {
        let est = a
            .point(&t.name)
            .ok_or_else(|| AgreementError::Missing("adjusted point".into()))?;
        let tru = truth
            .get(&t.name)
            .ok_or_else(|| AgreementError::Missing("true point".into()))?;
        let error = Vector3::from_fn(|i, _| (est.xyz[i] - tru[i]) * 1e3);
        let along = (normal.transpose() * t.cov * normal)[(0, 0)].sqrt();
        out.normal_sum_squares += (error.dot(&normal) / along).powi(2);
        for i in 0..3 {
            let s = t.cov[(i, i)].sqrt();
            let e = (est.xyz[i] - tru[i]) * 1e3 / s;
            o.rms[i] += e * e;
            out.sum_squares[i] += e * e;
            let ratio = (est.covariance_m2[i][i] * 1e6).sqrt() / s;
            o.sigma_ratio[i] += ratio;
            o.sigma_ratio_worst = o.sigma_ratio_worst.max((ratio - 1.0).abs());
        }
        out.terms += 1;
    }
    let cam = a
        .report
        .cameras
        .first()
        .ok_or_else(|| AgreementError::Missing("adjusted camera".into()))?;
    let e = cam.c_mm - c_mm;
    out.c_sum_squares += (e / sigma_c).powi(2);
    out.c_repeat_sum_squares += (e / sigma_c_repeat).powi(2);
    out.c_sigma_ratio += cam.c_sigma_mm.unwrap_or(f64::NAN) / sigma_c;
    out.epochs += 1;
    Ok(())
}
