//! The adjustment: validation, then (once `prepare` has the start values, the working frame and
//! the datum: free network with inner constraints, or weighted control points)
//! Levenberg–Marquardt with the Schur complement and data snooping; `site_result` then gives the
//! precision, the site frame and the report. The
//! orthogonal model always runs first; the central model starts from its solution.

use nalgebra::Vector3;

use super::options::AdjustOptions;
use super::prepare::{check_geometry, prepare, Datum, Prepared};
use super::report::{DroppedObservation, VarianceModel};
use super::result::Adjustment;
use super::robust::{affine_stage, choose_mirrors, first_stage};
use super::site_result::{site_result, Solution};
use crate::photogrammetry::error::AdjustError;
use crate::photogrammetry::input::epoch::{EpochInput, EpochProblem};
use crate::photogrammetry::model::bundle::{Bundle, ImageState};
use crate::photogrammetry::model::orthogonal::OrthoImage;
use crate::photogrammetry::model::Model;
use crate::photogrammetry::solve::lm::{
    levenberg_marquardt, levenberg_marquardt_normals, LmOutcome, Start,
};
use crate::photogrammetry::solve::normal_equations::Normals;
use crate::photogrammetry::statistics::precision::Cofactors;
use crate::photogrammetry::statistics::snooping::{
    normalized_residual, ActiveCounts, LinearSnooping,
};
use crate::photogrammetry::statistics::variance_factor::{
    chi2_upper, variance_model, GLOBAL_TEST_Z,
};

/// Validates (the form and its units, [`crate::photogrammetry::input::plausible::validate`]) and
/// adjusts an epoch of the upload form.
pub fn adjust(input: &EpochInput, options: &AdjustOptions) -> Result<Adjustment, AdjustError> {
    let problem = crate::photogrammetry::input::plausible::validate(input)?;
    adjust_problem(&problem, options)
}

/// [`AdjustError::Cancelled`] once the caller no longer wants the adjustment.
fn still_wanted(options: &AdjustOptions) -> Result<(), AdjustError> {
    if options.cancel.is_cancelled() {
        return Err(AdjustError::Cancelled {
            deadline: options.cancel.deadline_passed(),
        });
    }
    Ok(())
}

/// Solves the prepared adjustment; when the solution looks like a wrong basin (no convergence, or
/// too many outliers with a failed global test), tries again from the affine bundle (orthogonal
/// model) and keeps the better. A wrong basin either way is refused as inconsistent.
fn solve_or_retry(
    problem: &EpochProblem,
    options: &AdjustOptions,
    prepared: &Prepared,
) -> Result<Solved, AdjustError> {
    let dof_of = |b: &Bundle| prepared.dof(b);
    let global_test_fails = |x: &Solved| {
        let dof = dof_of(&x.bundle).max(1) as f64;
        x.outcome.cost / dof > chi2_upper(dof, GLOBAL_TEST_Z) / dof
    };
    let failed = |x: &Solved| !x.outcome.converged || (x.too_many_outliers && global_test_fails(x));
    let run = |affine_first: bool| solve(problem, options, prepared, affine_first, &dof_of);
    let mut solved = run(false)?;
    // Without snooping, a failed global test may be a wrong basin as well as gross errors kept: worth
    // the second try, though not a reason to refuse the result (it carries the test's warning).
    let suspect = |x: &Solved| failed(x) || (!options.snooping && global_test_fails(x));
    if suspect(&solved) && options.model == Model::Orthogonal && !options.cancel.is_cancelled() {
        // A wrong basin (many blunders and a failed global test): try again from the affine bundle.
        if let Ok(second) = run(true) {
            let vf = |x: &Solved| x.outcome.cost / dof_of(&x.bundle).max(1) as f64;
            if !suspect(&second) || (second.outcome.converged && vf(&second) < vf(&solved)) {
                solved = second;
            }
        }
    }
    // A wrong basin, whether the iteration still crawled along it or not, is refused as such.
    if failed(&solved)
        && (solved.outcome.converged || (solved.too_many_outliers && global_test_fails(&solved)))
    {
        let dof = dof_of(&solved.bundle).max(1) as f64;
        return Err(AdjustError::Inconsistent {
            sigma0_mm: problem.reference_sigma_mm() * (solved.outcome.cost / dof).sqrt(),
            outliers: solved.outliers,
        });
    }
    Ok(solved)
}

/// Adjusts a validated epoch: start values, the working frame, the solution (with a retry from
/// the affine bundle when it lands in a wrong basin), then datum, precision and the report.
pub fn adjust_problem(
    problem: &EpochProblem,
    options: &AdjustOptions,
) -> Result<Adjustment, AdjustError> {
    check_geometry(problem)?;
    let prepared = prepare(problem, options)?;
    still_wanted(options)?;
    // A cancelled solution stops unconverged, which would read as a wrong basin: the
    // cancellation is what is reported.
    let solved = solve_or_retry(problem, options, &prepared);
    still_wanted(options)?;
    let solved = solved?;
    let (observations, unknowns) = prepared.counts(&solved.bundle);
    if observations <= unknowns {
        return Err(AdjustError::TooFewObservations {
            observations,
            unknowns,
        });
    }
    let dof = observations as i64 - unknowns as i64;
    let Prepared {
        frame,
        datum,
        mut warnings,
        start_points,
        ..
    } = prepared;
    let Solved {
        bundle,
        outcome,
        cof,
        warnings: more,
        dropped,
        w,
        variance_model,
        ..
    } = solved;
    warnings.extend(more);
    site_result(Solution {
        problem,
        options,
        bundle,
        frame,
        cof,
        outcome,
        dof,
        datum,
        warnings,
        dropped,
        w,
        variance_model,
        start_points: &start_points,
    })
}

/// What one run of the pipeline produced.
struct Solved {
    bundle: Bundle,
    outcome: LmOutcome,
    cof: Cofactors,
    warnings: Vec<String>,
    dropped: Vec<DroppedObservation>,
    /// More than a tenth of the observations beyond the critical |w|: data snooping reached its cap
    /// with more left, or, without snooping, that many are kept.
    too_many_outliers: bool,
    /// Observations beyond the critical |w|, dropped or (without snooping) kept.
    outliers: usize,
    /// Normalized residuals (w_x, w_y) of every observation at the solution.
    w: Vec<[f64; 2]>,
    /// The variance the snooping's statistics `w` rest on.
    variance_model: VarianceModel,
}

/// The pipeline from the start values: mirror choice, first stage (robust), self-calibration, the
/// central model if asked, data snooping with its backward step. `affine_first` runs the affine
/// bundle (stage 0) before the perspective stages.
fn solve(
    problem: &EpochProblem,
    options: &AdjustOptions,
    prepared: &Prepared,
    affine_first: bool,
    dof_of: &dyn Fn(&Bundle) -> i64,
) -> Result<Solved, AdjustError> {
    let mut bundle = prepared.bundle.clone();
    // Stage 1: interior held, iteratively reweighted from the start so that a gross error cannot pull
    // the solution into a wrong basin; then gross residuals are set aside (and, with snooping off,
    // taken back before the final adjustment).
    let converged = choose_mirrors(&mut bundle, &prepared.mirrors);
    still_wanted(options)?;
    if affine_first && bundle.model == Model::Orthogonal {
        affine_stage(&mut bundle);
    }
    let (outcome, normals) = if options.model == Model::Orthogonal {
        orthogonal_stages(&mut bundle, options, &prepared.free, converged)
    } else {
        let zbar = prepared.bundle.zbar;
        (
            central_stages(&mut bundle, options, &prepared.free, zbar),
            None,
        )
    };
    // The cofactors of the solution, from the normal equations of its last (negligible) step when
    // the adjustment returned them.
    let datum = prepared.datum;
    let invert = |b: &Bundle, n: Option<Normals>| {
        let n = n.unwrap_or_else(|| b.normals());
        Cofactors::from_normals(b, n, datum == Datum::Free).ok_or_else(|| {
            AdjustError::Singular("the normal equations are not positive definite".into())
        })
    };
    // The cofactors and the snooping's statistics cost as much as the iterations: not for a
    // solution no longer wanted.
    still_wanted(options)?;
    let cof = invert(&bundle, normals)?;
    still_wanted(options)?;
    let screened = if options.snooping {
        let snooped = snoop(&mut bundle, cof, options, invert, dof_of)?;
        Screened {
            outcome: snooped.outcome.unwrap_or(outcome),
            cof: snooped.cof,
            w: snooped.w,
            variance_model: snooped.variance_model,
            capped: snooped.warning.is_some(),
            warnings: snooped.warning.into_iter().collect(),
        }
    } else {
        keep_every_observation(&mut bundle, options, invert, dof_of)?
    };
    Ok(tally(problem, options, bundle, screened))
}

/// Stages 1 and 2 of the orthogonal model: the robust first stage with the interior held, then,
/// when c is free, the adjustment with c. Returns the outcome and the last step's normal
/// equations when the adjustment kept them.
fn orthogonal_stages(
    bundle: &mut Bundle,
    options: &AdjustOptions,
    free: &[[bool; 8]],
    converged: Option<LmOutcome>,
) -> (LmOutcome, Option<Normals>) {
    let stage2: Vec<[bool; 8]> = free
        .iter()
        .map(|f| [f[0], false, false, false, false, false, false, false])
        .collect();
    let calibrate = stage2.iter().flatten().any(|&f| f);
    // With c to be freed, stage 1 ends with the robust rounds: stage 2 converges from there.
    let outcome = first_stage(
        bundle,
        (!calibrate).then_some(options.max_iterations),
        converged,
    );
    if !calibrate {
        return (outcome, None);
    }
    bundle.free = stage2;
    levenberg_marquardt_normals(bundle, options.max_iterations, Start::Near)
}

/// The central model: the orthogonal solution (interior held) starts the collinearity
/// adjustment; gross errors are screened only once the interior orientation (e.g. strong
/// distortion) is modelled. Without `central_from_orthogonal` the start values go to
/// collinearity directly (for comparisons). `zbar`: the working frame's mean depth (mm).
fn central_stages(
    bundle: &mut Bundle,
    options: &AdjustOptions,
    free: &[[bool; 8]],
    zbar: f64,
) -> LmOutcome {
    if options.central_from_orthogonal {
        levenberg_marquardt(bundle, options.max_iterations);
    }
    bundle.images = bundle
        .images
        .iter()
        .enumerate()
        .map(|(j, im)| {
            let c = bundle.interior[bundle.image_camera[j]][0];
            let o = OrthoImage {
                rotation: im.rotation,
                m: im.p[0],
                a4: im.p[1],
                a8: im.p[2],
            };
            let xo = o.center(c, zbar).unwrap_or_else(Vector3::zeros);
            ImageState {
                rotation: im.rotation,
                p: [xo.x, xo.y, xo.z],
            }
        })
        .collect();
    bundle.model = Model::Central;
    bundle.free = free.to_vec();
    levenberg_marquardt(bundle, options.max_iterations);
    first_stage(bundle, Some(options.max_iterations), None)
}

/// The solution after the observations were screened (snooped, or all taken back).
struct Screened {
    outcome: LmOutcome,
    cof: Cofactors,
    /// Normalized residuals (w_x, w_y) of every observation.
    w: Vec<[f64; 2]>,
    variance_model: VarianceModel,
    /// Data snooping stopped at its cap with more left.
    capped: bool,
    warnings: Vec<String>,
}

/// Without data snooping: every observation set aside by the first stage is taken back and the
/// adjustment repeated; the statistics follow the same variance model as with snooping (Pope's
/// τ when the global test rejects the a-priori σ).
fn keep_every_observation(
    bundle: &mut Bundle,
    options: &AdjustOptions,
    invert: impl Fn(&Bundle, Option<Normals>) -> Result<Cofactors, AdjustError>,
    dof_of: &dyn Fn(&Bundle) -> i64,
) -> Result<Screened, AdjustError> {
    for o in &mut bundle.obs {
        o.active = true;
    }
    let (outcome, n) = levenberg_marquardt_normals(bundle, options.max_iterations, Start::Near);
    let cof = invert(bundle, n)?;
    let (variance_model, _, s) = variance_model(bundle, dof_of(bundle), options.critical_w);
    let w = (0..bundle.obs.len())
        .map(|k| normalized_residual(bundle, &cof, k).map(|x| x / s))
        .collect();
    Ok(Screened {
        outcome,
        cof,
        w,
        variance_model,
        capped: false,
        warnings: vec![],
    })
}

/// The dropped observations with their |w|, the outliers kept (without snooping, with a
/// warning), and whether there were too many for a right basin.
fn tally(
    problem: &EpochProblem,
    options: &AdjustOptions,
    bundle: Bundle,
    screened: Screened,
) -> Solved {
    let Screened {
        outcome,
        cof,
        w,
        variance_model,
        capped,
        mut warnings,
    } = screened;
    let dropped: Vec<DroppedObservation> = (0..bundle.obs.len())
        .filter(|&k| !bundle.obs[k].active)
        .map(|k| DroppedObservation {
            image: problem.images[bundle.obs[k].image].id.clone(),
            point: problem.points[bundle.obs[k].point].clone(),
            w: largest(w[k]),
        })
        .collect();
    let beyond = (0..bundle.obs.len())
        .filter(|&k| bundle.obs[k].active && largest(w[k]) > options.critical_w)
        .count();
    if !options.snooping && beyond > 0 {
        warnings.push(format!(
            "{beyond} observations exceed |w| = {} (data snooping is off)",
            options.critical_w
        ));
    }
    let too_many_outliers = if options.snooping {
        capped
    } else {
        beyond > outlier_cap(bundle.obs.len())
    };
    Solved {
        outliers: dropped.len() + beyond,
        bundle,
        outcome,
        cof,
        warnings,
        dropped,
        too_many_outliers,
        w,
        variance_model,
    }
}

/// Largest |w| of an observation's two coordinates.
fn largest(w: [f64; 2]) -> f64 {
    w[0].abs().max(w[1].abs())
}

/// Observations (a tenth of `observations`, at least one) that data snooping may drop, and beyond
/// which a solution failing the global test is taken for a wrong basin.
fn outlier_cap(observations: usize) -> usize {
    (observations / 10).max(1)
}

/// What data snooping leaves: the outcome of its last exact adjustment (None when it made none),
/// the cofactors and normalized residuals of the final solution, and a warning when it was capped.
struct Snooped {
    outcome: Option<LmOutcome>,
    cof: Cofactors,
    w: Vec<[f64; 2]>,
    warning: Option<String>,
    variance_model: VarianceModel,
}

/// Times one observation may be taken back by the backward step, so that one whose |w| lies at the
/// critical value within the linearization error cannot go back and forth.
const MAX_RESTORES: u8 = 2;

/// Data snooping (Baarda), one observation at a time, from the converged bundle and its cofactors
/// `cof`; `invert` gives the cofactors of a new solution from its normal equations.
///
/// Between exact re-adjustments the drops are followed in the linearized problem (see
/// [`LinearSnooping`]). Once no |w| there exceeds the critical value (or the drops reach their cap,
/// a tenth of the observations), the backward step tests the observations set aside (at the start,
/// or dropped while a worse blunder still distorted the solution) against that solution and takes
/// back those that fit, again in the linearized problem; then the exact adjustment from x* + Δ
/// decides again. It ends at an exact solution with nothing to drop and nothing to take back.
fn snoop(
    bundle: &mut Bundle,
    mut cof: Cofactors,
    options: &AdjustOptions,
    invert: impl Fn(&Bundle, Option<Normals>) -> Result<Cofactors, AdjustError>,
    dof_of: &dyn Fn(&Bundle) -> i64,
) -> Result<Snooped, AdjustError> {
    let max_drops = outlier_cap(bundle.obs.len());
    let mut drops = bundle.obs.iter().filter(|o| !o.active).count();
    // The critical |w| (w formed with the a-priori σ) of the variance model of the current exact
    // solution: Baarda's, or Pope's τ_crit · σ̂0 / σ when the global test rejects σ; σ̂0 is
    // re-estimated after every exact re-adjustment.
    let (mut model, widen, mut w_scale) =
        variance_model(bundle, dof_of(bundle), options.critical_w);
    let mut critical_w = options.critical_w * widen;
    let mut lin = LinearSnooping::new(bundle, &cof, critical_w);
    let mut counts = ActiveCounts::of(bundle);
    let mut restores = vec![0u8; bundle.obs.len()];
    let mut outcome = None;
    let mut warning = None;
    loop {
        // Each round re-solves: a cancelled adjustment stops snooping (its result is discarded).
        still_wanted(options)?;
        let mut worst: Option<(usize, f64)> = None;
        for &k in lin.tracked() {
            if !bundle.obs[k].active || !counts.droppable(bundle, k) {
                continue;
            }
            let m = largest(lin.w(bundle, k));
            if m > critical_w && worst.is_none_or(|(_, x)| m > x) {
                worst = Some((k, m));
            }
        }
        let capped = worst.is_some() && drops >= max_drops;
        if worst.is_none() || capped {
            // The backward step (every inactive observation is tracked).
            let back: Vec<usize> = lin
                .tracked()
                .iter()
                .copied()
                .filter(|&k| {
                    !bundle.obs[k].active
                        && restores[k] < MAX_RESTORES
                        && largest(lin.w(bundle, k)) <= critical_w
                })
                .collect();
            let mut restored = false;
            for k in back {
                if lin.restore(bundle, &cof, k) {
                    restores[k] += 1;
                    bundle.obs[k].active = true;
                    counts.restore(bundle, k);
                    drops = drops.saturating_sub(1);
                    restored = true;
                }
            }
            if restored {
                continue;
            }
        }
        let drop = worst.filter(|_| !capped).map(|(k, _)| k);
        if let Some(k) = drop {
            counts.drop(bundle, k);
            drops += 1;
            if lin.drop(bundle, &cof, k) {
                bundle.obs[k].active = false;
                continue;
            }
            // No redundancy left for it in the linearized problem: decide exactly.
        }
        if !lin.modified() && drop.is_none() {
            if capped {
                warning = Some(format!(
                    "data snooping stopped after {max_drops} dropped observations; more residuals exceed |w| = {}",
                    options.critical_w
                ));
            }
            break;
        }
        let (dc, dp) = lin.step(&cof);
        if let Some(k) = drop {
            bundle.obs[k].active = false;
        }
        bundle.apply(&dc, &dp);
        let (o, n) = levenberg_marquardt_normals(bundle, options.max_iterations, Start::Near);
        outcome = Some(o);
        cof = invert(bundle, n)?;
        let widen;
        (model, widen, w_scale) = variance_model(bundle, dof_of(bundle), options.critical_w);
        critical_w = options.critical_w * widen;
        lin = LinearSnooping::new(bundle, &cof, critical_w);
    }
    Ok(Snooped {
        outcome,
        w: lin
            .all_w(bundle)
            .into_iter()
            .map(|w| w.map(|x| x / w_scale))
            .collect(),
        cof,
        warning,
        variance_model: model,
    })
}
