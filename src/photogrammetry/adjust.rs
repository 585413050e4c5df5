//! The adjustment: validation, start values, the working frame, Levenberg–Marquardt with the Schur
//! complement, datum (free network with inner constraints, or weighted control points), data snooping,
//! precision and the report. The orthogonal model always runs first; the central model starts from its
//! solution.

use nalgebra::{Matrix3, Vector3};

use super::bundle::{residual_value, ImageState, Obs};
use super::camera::{brown_correct, INTERIOR_NAMES};
use super::central::CentralImage;
use super::epoch::{EpochInput, EpochProblem};
use super::error::AdjustError;
use super::frame::{similarity_fit, WorkingFrame};
use super::lm::{
    levenberg_marquardt, levenberg_marquardt_normals, levenberg_marquardt_within, LmOutcome, Start,
    ROUND_STEP,
};
use super::normal_equations::Normals;
use super::normals::Bundle;
use super::orthogonal::OrthoImage;
use super::precision::Cofactors;
use super::report::{
    AdjustmentReport, CalibratedParameter, CameraReport, DroppedObservation, ImageReport, Model,
    PointReport, ResidualReport, VarianceModel,
};
use super::result::{AdjustOptions, AdjustedPoint, Adjustment, ImageOrientation, JointCovariance};
use super::snooping::{normalized_residual, ActiveCounts, LinearSnooping};
use super::start::{start_values, StartImage};

/// Relative weight of the prior on point increments that holds the free network's datum during the
/// iteration (a fraction of the mean point block diagonal).
const GAUGE: f64 = 1e-9;

/// Standard normal quantile of the global test on the variance factor (99.9 %).
const GLOBAL_TEST_Z: f64 = 3.09;

/// Upper quantile of χ²(ν) for the standard normal quantile z (Wilson–Hilferty).
fn chi2_upper(nu: f64, z: f64) -> f64 {
    let a = 2.0 / (9.0 * nu);
    nu * (1.0 - a + z * a.sqrt()).powi(3)
}

/// Lower quantile of χ²(ν) for the standard normal quantile z (Wilson–Hilferty).
fn chi2_lower(nu: f64, z: f64) -> f64 {
    chi2_upper(nu, -z)
}

/// Critical value of Pope's τ statistic with `r` degrees of freedom at the level whose normal
/// critical value is `z`: τ = t √r / √(r − 1 + t²) with t the Student quantile of r − 1 degrees of
/// freedom (Pope 1976, eq 17), t from z by the Cornish–Fisher expansion.
fn tau_critical(z: f64, r: f64) -> f64 {
    let nu = (r - 1.0).max(1.0);
    let (z3, z5) = (z.powi(3), z.powi(5));
    let t = z + (z3 + z) / (4.0 * nu) + (5.0 * z5 + 16.0 * z3 + 3.0 * z) / (96.0 * nu * nu);
    let tau = t * (r / (r - 1.0 + t * t)).sqrt();
    // τ is bounded by √r; with almost no redundancy the test degenerates to that bound.
    tau.min(r.sqrt())
}

/// Variance factor beyond which the snooping keeps the a-priori σ although the global test rejects
/// it: an a-priori σ off by more than a factor 2 is taken for a wrong basin or many gross errors,
/// which the capped snooping and the retry from the affine bundle must see, not for a misstated σ.
const MAX_TAU_VARIANCE_FACTOR: f64 = 4.0;

/// The snooping's variance model for the bundle's current solution: a-priori when the global test
/// (two-sided, 99.9 %) accepts the variance factor or it exceeds [`MAX_TAU_VARIANCE_FACTOR`], else
/// Pope's τ test with σ̂0. Returns the model and
/// the factor √(variance factor) · τ_crit / `critical_w` by which the critical |w| (formed with the
/// a-priori σ) is widened, and √(variance factor) by which reported w are divided.
fn variance_model(b: &Bundle, dof: i64, critical_w: f64) -> (VarianceModel, f64, f64) {
    let r = dof.max(2) as f64;
    let vf = b.cost() / r;
    let upper = chi2_upper(r, GLOBAL_TEST_Z) / r;
    let lower = chi2_lower(r, GLOBAL_TEST_Z) / r;
    if (lower..=upper).contains(&vf) || !(vf > 0.0 && vf <= MAX_TAU_VARIANCE_FACTOR) {
        (VarianceModel::APriori, 1.0, 1.0)
    } else {
        let s = vf.sqrt();
        (
            VarianceModel::APosteriori,
            s * tau_critical(critical_w, r) / critical_w,
            s,
        )
    }
}

/// σ of the prior on a self-calibrated c, relative to its given value.
const C_PRIOR_RELATIVE: f64 = 0.1;

/// Robust residual scale (in a-priori σ) above which stage 1 is taken to sit in a wrong basin.
const RESCUE_SCALE: f64 = 3.0;

/// Largest epoch (images) for which the leave-one-image-out rescue is tried.
const RESCUE_MAX_IMAGES: usize = 12;

/// Leave-one-image-out rescue of a stage 1 that failed (a gross error in one image's start, e.g.
/// swapped labels, can put the whole network in a wrong basin): adjusts without each image in turn,
/// keeps the best fit, re-resects the left-out image robustly on the adjusted points (its gross errors
/// are set aside as suspects) and puts it back.
fn rescue(bundle: &mut Bundle, initial: &Bundle) {
    let nimg = bundle.images.len();
    if !(4..=RESCUE_MAX_IMAGES).contains(&nimg) {
        return;
    }
    let mut best: Option<(f64, usize, Bundle)> = None;
    for j in 0..nimg {
        let mut trial = initial.clone();
        for o in trial.obs.iter_mut() {
            if o.image == j {
                o.active = false;
            }
        }
        if (0..trial.points.len()).any(|p| {
            trial.point_obs[p]
                .iter()
                .filter(|&&k| trial.obs[k].active)
                .count()
                < 2
        }) {
            continue;
        }
        levenberg_marquardt(&mut trial, 4 * ROBUST_ITERATIONS);
        let s = residual_scale(&trial, &residual_norms(&trial));
        if best.as_ref().is_none_or(|b| s < b.0) {
            best = Some((s, j, trial));
        }
    }
    let Some((s, j, mut trial)) = best else {
        return;
    };
    if s > RESCUE_SCALE {
        return;
    }
    // Put the image back with its start orientation; the reweighted rounds now have four good images
    // holding the points and pull it in while its gross errors get low weights.
    for o in trial.obs.iter_mut() {
        if o.image == j {
            o.active = true;
        }
    }
    robust_rounds(&mut trial, ROBUST_ITERATIONS, ROBUST_ROUNDS);
    *bundle = trial;
}

/// The first stage from the start values: reweighted rounds (and the leave-one-image-out rescue when
/// they end in a poor fit) followed by the screening of gross residuals; then plain
/// Levenberg–Marquardt. The stage is robust whether or not data snooping follows: without snooping,
/// the observations set aside here are taken back before the final adjustment.
/// `converged` is the outcome of an adjustment that already converged at the bundle's state (the
/// mirror choice's); when the robust stage leaves that state as it is, it is not repeated. Without
/// `max_iterations` the final Levenberg–Marquardt is left to the next stage (the outcome returned is
/// then that of the state reached, marked not converged).
fn first_stage(
    bundle: &mut Bundle,
    max_iterations: Option<usize>,
    converged: Option<LmOutcome>,
) -> LmOutcome {
    let initial = bundle.clone();
    let mut unchanged = converged.is_some();
    unchanged &= !robust_rounds(bundle, ROBUST_ITERATIONS, ROBUST_ROUNDS);
    if residual_scale(bundle, &residual_norms(bundle)) > RESCUE_SCALE {
        rescue(bundle, &initial);
        unchanged = false;
    }
    unchanged &= screen(bundle) == 0;
    unchanged &= !repair_images(bundle);
    match (converged, max_iterations) {
        (Some(outcome), _) if unchanged => outcome,
        (_, Some(max)) => levenberg_marquardt(bundle, max),
        (_, None) => LmOutcome {
            iterations: 0,
            converged: false,
            cost: bundle.cost(),
        },
    }
}

/// Share of an image's observations set aside beyond which its orientation is taken to be wrong (a
/// wrong mirror root of a flat face) rather than its observations.
const REPAIR_SHARE: f64 = 0.3;

/// Re-resects images that lost more than [`REPAIR_SHARE`] of their observations to the screening on
/// the adjusted points, which are now accurate enough for the perspective to pick the right mirror
/// root, and takes their observations back (the snooping judges them again).
/// Returns whether the bundle changed.
fn repair_images(bundle: &mut Bundle) -> bool {
    let before = bundle.clone();
    let active = |b: &Bundle| b.obs.iter().filter(|o| o.active).count();
    let counts = ActiveCounts::of(bundle);
    let mut totals = vec![0usize; bundle.images.len()];
    for o in &bundle.obs {
        totals[o.image] += 1;
    }
    let mut repaired = false;
    for j in 0..bundle.images.len() {
        let lost = totals[j] - counts.per_image[j];
        if (lost as f64) <= REPAIR_SHARE * totals[j] as f64 {
            continue;
        }
        let cam = bundle.image_camera[j];
        let image = StartImage {
            id: String::new(),
            c: bundle.interior[cam][0],
            observations: bundle
                .obs
                .iter()
                .filter(|o| o.image == j)
                .map(|o| (o.point, brown_correct(o.meas, &bundle.interior[cam])))
                .collect(),
        };
        let known: Vec<Option<Vector3<f64>>> = bundle.points.iter().map(|p| Some(*p)).collect();
        let Ok(res) = super::start::resect_image(&image, &known) else {
            continue;
        };
        let o = OrthoImage::from_center(res.rotation, res.center, image.c, bundle.zbar);
        bundle.images[j] = ImageState {
            rotation: res.rotation,
            p: [o.m, o.a4, o.a8],
        };
        for (k, o) in bundle.obs.iter_mut().filter(|o| o.image == j).enumerate() {
            o.active = !res.removed.contains(&k);
        }
        repaired = true;
    }
    if repaired {
        levenberg_marquardt(bundle, 4 * ROBUST_ITERATIONS);
        screen(bundle);
        // Kept only if it gave observations back and fits at the noise level (a resection spoilt by
        // gross errors would not).
        let scale = residual_scale(bundle, &residual_norms(bundle));
        if active(bundle) <= active(&before) || scale > 1.5 {
            *bundle = before;
            return false;
        }
    }
    repaired
}

/// Factor on c that turns the closed-form model into the scaled orthographic (affine) projection of
/// eq (5): with H → ∞, K → 1 and u → 1, so x = x_a.
const AFFINE_C_FACTOR: f64 = 1e4;

/// Reweighted rounds of the affine stage.
const AFFINE_ROUNDS: usize = 4;

/// Stage 0, the fallback start: the bundle of the pure affine model (eq 5 with constraints 10–11).
/// Its basin differs from the perspective one, and in the orthogonal parametrization its solution
/// (m, A4, A8, R, points) is directly a start of the perspective adjustment. Reweighted so that gross
/// errors cannot steer it.
fn affine_stage(bundle: &mut Bundle) {
    let c: Vec<f64> = bundle.interior.iter().map(|i| i[0]).collect();
    for i in bundle.interior.iter_mut() {
        i[0] *= AFFINE_C_FACTOR;
    }
    robust_rounds(bundle, ROBUST_ITERATIONS, AFFINE_ROUNDS);
    for (i, c) in bundle.interior.iter_mut().zip(c) {
        i[0] = c;
    }
}

/// Reweighted rounds of the first perspective stage at most.
const ROBUST_ROUNDS: usize = 12;

/// Robust residual scale (a-priori σ) below which the start roots are kept without trying mirrors.
const MIRROR_ACCEPT_SCALE: f64 = 1.5;

/// Up to this many images with a mirror candidate, every combination is tried; beyond, greedy passes.
const EXHAUSTIVE_MIRRORS: usize = 6;

/// Planar point sets give two mirror orientations per image that the perspective of a single image may
/// not tell apart at long range; keep, image by image, the one with which the whole network fits
/// better ("the one consistent with the other images").
/// Returns the outcome of the adjustment that kept the start roots, when it did.
fn choose_mirrors(bundle: &mut Bundle, mirrors: &[Option<ImageState>]) -> Option<LmOutcome> {
    if mirrors.iter().all(Option::is_none) {
        return None;
    }
    // Compared by the robust residual scale, so that a gross error in one image cannot decide.
    let fit = |b: &Bundle| {
        let mut t = b.clone();
        levenberg_marquardt(&mut t, 2 * ROBUST_ITERATIONS);
        residual_scale(&t, &residual_norms(&t))
    };
    let with_mirror: Vec<usize> = (0..mirrors.len())
        .filter(|&j| mirrors[j].is_some())
        .collect();
    // The start roots already fit at the noise level (robustly and by the plain RMS): every
    // alternative would fit worse.
    let mut base = bundle.clone();
    let (outcome, _) =
        levenberg_marquardt_normals(&mut base, 2 * ROBUST_ITERATIONS, Start::Adaptive);
    let norms = residual_norms(&base);
    if outcome.converged
        && residual_scale(&base, &norms) < MIRROR_ACCEPT_SCALE
        && rms_scale(&base, &norms) < MIRROR_ACCEPT_SCALE
    {
        *bundle = base;
        return Some(outcome);
    }
    if with_mirror.len() <= EXHAUSTIVE_MIRRORS {
        // Every combination (2^k small networks).
        let base = bundle.clone();
        let mut best = (f64::INFINITY, base.clone());
        for mask in 0u32..(1 << with_mirror.len()) {
            let mut trial = base.clone();
            for (bit, &j) in with_mirror.iter().enumerate() {
                if mask & (1 << bit) != 0 {
                    trial.images[j] = mirrors[j].expect("has a mirror");
                }
            }
            let cost = fit(&trial);
            if cost < best.0 {
                best = (cost, trial);
            }
        }
        *bundle = best.1;
        return None;
    }
    let mut best = fit(bundle);
    let mut current: Vec<ImageState> = bundle.images.clone();
    let mut alternative: Vec<Option<ImageState>> = mirrors.to_vec();
    for _pass in 0..3 {
        let mut changed = false;
        for j in 0..alternative.len() {
            let Some(m) = alternative[j] else { continue };
            let mut trial = bundle.clone();
            trial.images[j] = m;
            let cost = fit(&trial);
            if cost < best {
                best = cost;
                alternative[j] = Some(current[j]);
                current[j] = m;
                *bundle = trial;
                changed = true;
            }
        }
        if !changed {
            break;
        }
    }
    None
}

/// Iterations per round of the reweighted first stage.
const ROBUST_ITERATIONS: usize = 10;

/// Multiple of the robust residual scale beyond which an observation is set aside after the first stage.
const SCREEN_FACTOR: f64 = 6.0;

/// Screens the residuals of the first stage: observations whose residual exceeds `SCREEN_FACTOR` robust
/// σ (and 3 a-priori σ) are set aside, largest first, keeping every point in ≥ 2 images and every image
/// with ≥ 4 observations. Returns how many were set aside.
fn residual_norms(bundle: &Bundle) -> Vec<f64> {
    bundle
        .obs
        .iter()
        .map(|o| {
            if !o.active {
                return 0.0;
            }
            let cam = bundle.image_camera[o.image];
            let e = residual_value(
                bundle.model,
                &bundle.images[o.image],
                &bundle.interior[cam],
                &bundle.points[o.point],
                o.meas,
                bundle.zbar,
            );
            (e[0] * e[0] + e[1] * e[1]).sqrt() / bundle.sigma[cam]
        })
        .collect()
}

/// Robust scale of the active residual norms, in a-priori σ of one coordinate.
fn residual_scale(bundle: &Bundle, norms: &[f64]) -> f64 {
    let active: Vec<f64> = norms
        .iter()
        .zip(&bundle.obs)
        .filter(|(_, o)| o.active)
        .map(|(n, _)| *n)
        .collect();
    super::start::robust_scale(&active) / std::f64::consts::SQRT_2
}

/// Root mean square of the active residual norms, in a-priori σ of one coordinate.
fn rms_scale(bundle: &Bundle, norms: &[f64]) -> f64 {
    let (n, sum) = norms
        .iter()
        .zip(&bundle.obs)
        .filter(|(_, o)| o.active)
        .fold((0usize, 0.0), |(n, s), (r, _)| (n + 1, s + r * r));
    (sum / (2 * n.max(1)) as f64).sqrt()
}

/// Iteratively reweighted least squares with Cauchy weights `1/(1 + (r/(3s))²)`, a few rounds, so
/// that gross errors (a mislabeled target) cannot drag the solution into a wrong basin before the
/// screening. Leaves the weights at 1. Returns whether it adjusted (not when the residuals are at
/// the noise level already).
fn robust_rounds(bundle: &mut Bundle, iterations: usize, rounds: usize) -> bool {
    let mut adjusted = false;
    for _ in 0..rounds {
        let norms = residual_norms(bundle);
        let s = residual_scale(bundle, &norms).max(1.0);
        // At the noise level already, also by the plain RMS (no gross error hides in the fit).
        if s < 1.5 && (adjusted || rms_scale(bundle, &norms) < 1.5) {
            break;
        }
        adjusted = true;
        for (o, r) in bundle.obs.iter_mut().zip(&norms) {
            o.weight = 1.0 / (1.0 + (r / (3.0 * s)).powi(2));
        }
        levenberg_marquardt_within(bundle, iterations, ROUND_STEP);
    }
    for o in bundle.obs.iter_mut() {
        o.weight = 1.0;
    }
    adjusted
}

fn screen(bundle: &mut Bundle) -> usize {
    let norms = residual_norms(bundle);
    let scale = residual_scale(bundle, &norms);
    let limit = (SCREEN_FACTOR * scale).max(3.0);
    let mut order: Vec<usize> = (0..norms.len()).filter(|&k| norms[k] > limit).collect();
    order.sort_by(|&a, &b| norms[b].total_cmp(&norms[a]));
    let cap = bundle.obs.len() / 5;
    let mut n = 0;
    let mut counts = ActiveCounts::of(bundle);
    for k in order {
        if n >= cap {
            break;
        }
        if counts.droppable(bundle, k) {
            counts.drop(bundle, k);
            bundle.obs[k].active = false;
            n += 1;
        }
    }
    n
}

/// Validates and adjusts an epoch of the upload form.
pub fn adjust(input: &EpochInput, options: &AdjustOptions) -> Result<Adjustment, AdjustError> {
    let problem = input.validate()?;
    adjust_problem(&problem, options)
}

/// The datum of an adjustment.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Datum {
    /// Inner constraints on all points (minimum norm against the start coordinates).
    Free,
    /// Control points as weighted observations.
    Control,
}

fn check_geometry(problem: &EpochProblem) -> Result<(), AdjustError> {
    let mut count = vec![0usize; problem.points.len()];
    for im in &problem.images {
        for o in &im.observations {
            count[o.point] += 1;
        }
    }
    for (p, &n) in count.iter().enumerate() {
        if n < 2 {
            return Err(AdjustError::PointInTooFewImages {
                point: problem.points[p].clone(),
                images: n,
            });
        }
    }
    Ok(())
}

/// Adjusts a validated epoch.
pub fn adjust_problem(
    problem: &EpochProblem,
    options: &AdjustOptions,
) -> Result<Adjustment, AdjustError> {
    check_geometry(problem)?;
    let np = problem.points.len();
    // Known coordinates: control, approx, then the site's earlier epochs.
    let known_site: Vec<Option<Vector3<f64>>> = (0..np)
        .map(|p| {
            problem.approx[p]
                .or_else(|| options.prior.get(&problem.points[p]).copied())
                .map(Vector3::from)
        })
        .collect();
    let known_list: Vec<Vector3<f64>> = known_site.iter().flatten().copied().collect();
    if known_list.is_empty() {
        let image = &problem.images[0];
        return Err(AdjustError::TooFewKnownPoints {
            image: image.id.clone(),
            known: 0,
        });
    }
    let origin = known_list.iter().fold(Vector3::zeros(), |a, b| a + b) / known_list.len() as f64;
    let known: Vec<Option<Vector3<f64>>> =
        known_site.iter().map(|k| k.map(|k| k - origin)).collect();

    let start_images: Vec<StartImage> = problem
        .images
        .iter()
        .map(|im| {
            let cam = &problem.cameras[im.camera];
            StartImage {
                id: im.id.clone(),
                c: cam.c(),
                observations: im
                    .observations
                    .iter()
                    .map(|o| (o.point, brown_correct(o.xy, &cam.params)))
                    .collect(),
            }
        })
        .collect();
    let start = start_values(&start_images, &known)?;

    // Working frame: Z along the mean viewing axis, origin at the centroid of all start points.
    let r1s: Vec<Vector3<f64>> = start
        .rotations
        .iter()
        .map(|r| r.row(0).transpose())
        .collect();
    let r3s: Vec<Vector3<f64>> = start
        .rotations
        .iter()
        .map(|r| r.row(2).transpose())
        .collect();
    let centroid = start.points.iter().fold(Vector3::zeros(), |a, b| a + b) / np as f64;
    let frame = WorkingFrame::from_axes(&r1s, &r3s, centroid + origin);
    let to_w = |x_centred: &Vector3<f64>| frame.to_working(x_centred + origin);

    let mut warnings = Vec::new();
    let nimg = problem.images.len();
    let mut free: Vec<[bool; 8]> = problem
        .cameras
        .iter()
        .map(|c| {
            let mut f = c.calibrate;
            if options.model == Model::Orthogonal {
                f = [f[0], false, false, false, false, false, false, false];
            }
            f
        })
        .collect();
    if nimg < 3 {
        warnings.push(format!(
            "only {nimg} images: the depth of the free network is weakly determined"
        ));
        if free.iter().flatten().any(|&f| f) {
            warnings.push(
                "two images cannot determine the interior orientation: c and the other interior parameters are held at their given values"
                    .into(),
            );
            free = vec![[false; 8]; free.len()];
        }
    }
    let start_points: Vec<Vector3<f64>> = start.points.iter().map(to_w).collect();
    let control_count = problem.control.iter().flatten().count();
    let datum = if control_count >= 3 {
        Datum::Control
    } else {
        Datum::Free
    };
    if control_count > 0 && datum == Datum::Free {
        warnings.push(format!(
            "{control_count} control point(s) are too few to fix the datum: free network, control used as approximations"
        ));
    }
    let zbar = 0.0;
    let state = |j: usize, r: &Matrix3<f64>, xo: &Vector3<f64>| -> ImageState {
        let c = problem.cameras[problem.images[j].camera].c();
        let r_w = frame.rotation_to_working(r);
        let o = OrthoImage::from_center(r_w, to_w(xo), c, zbar);
        ImageState {
            rotation: r_w,
            p: [o.m, o.a4, o.a8],
        }
    };
    let images: Vec<ImageState> = (0..nimg)
        .map(|j| state(j, &start.rotations[j], &start.centers[j]))
        .collect();
    let mirrors: Vec<Option<ImageState>> = (0..nimg)
        .map(|j| start.mirrors[j].map(|(r, xo)| state(j, &r, &xo)))
        .collect();
    let mut obs = Vec::new();
    let mut point_obs = vec![Vec::new(); np];
    for (j, im) in problem.images.iter().enumerate() {
        for (k, o) in im.observations.iter().enumerate() {
            point_obs[o.point].push(obs.len());
            obs.push(Obs {
                image: j,
                point: o.point,
                meas: o.xy,
                active: start.suspects.binary_search(&(j, k)).is_err(),
                weight: 1.0,
            });
        }
    }
    let mut bundle = Bundle {
        model: Model::Orthogonal,
        zbar,
        images,
        image_camera: problem.images.iter().map(|i| i.camera).collect(),
        interior: problem.cameras.iter().map(|c| c.params).collect(),
        // Stage 1 holds the interior orientation: a free c is nearly indeterminate at long range until
        // the exterior orientations and points have settled.
        free: vec![[false; 8]; problem.cameras.len()],
        sigma: problem.cameras.iter().map(|c| c.sigma_mm).collect(),
        points: start_points.clone(),
        obs,
        point_obs,
        control: problem
            .control
            .iter()
            .map(|c| {
                c.filter(|_| datum == Datum::Control)
                    .map(|c| (frame.to_working(Vector3::from(c.xyz)), c.sigma_m))
            })
            .collect(),
        gauge: 0.0,
        // A weak prior on c (10 % of the given value) keeps a self-calibrated c finite where the
        // geometry cannot determine it (a flat face at long range); elsewhere its weight is negligible.
        interior_prior: problem
            .cameras
            .iter()
            .map(|c| {
                let mut p = [None; 8];
                p[0] = Some((c.c(), C_PRIOR_RELATIVE * c.c()));
                p
            })
            .collect(),
    };
    if datum == Datum::Free {
        let mean = bundle.point_block_trace() / (3 * np) as f64;
        bundle.gauge = GAUGE * mean.max(1e-300);
    }
    let unknowns = bundle.camera_unknowns() + 3 * np;
    let defect = if datum == Datum::Free { 7 } else { 0 };
    let control_eq = if datum == Datum::Control {
        3 * control_count
    } else {
        0
    };

    let dof_of = |b: &Bundle| {
        let active = b.obs.iter().filter(|o| o.active).count();
        2 * active as i64 + control_eq as i64 + b.prior_count() as i64
            - (b.camera_unknowns() + 3 * np) as i64
            + defect
    };
    let global_test_fails = |x: &Solved| {
        let dof = dof_of(&x.bundle).max(1) as f64;
        x.outcome.cost / dof > chi2_upper(dof, GLOBAL_TEST_Z) / dof
    };
    let failed = |x: &Solved| !x.outcome.converged || (x.too_many_outliers && global_test_fails(x));
    let mut solved = solve(
        problem,
        options,
        bundle.clone(),
        &mirrors,
        &free,
        zbar,
        datum,
        false,
        &dof_of,
    )?;
    // Without snooping, a failed global test may be a wrong basin as well as gross errors kept: worth
    // the second try, though not a reason to refuse the result (it carries the test's warning).
    let suspect = |x: &Solved| failed(x) || (!options.snooping && global_test_fails(x));
    if suspect(&solved) && options.model == Model::Orthogonal {
        // A wrong basin (many blunders and a failed global test): try again from the affine bundle.
        if let Ok(second) = solve(
            problem, options, bundle, &mirrors, &free, zbar, datum, true, &dof_of,
        ) {
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
            sigma0_mm: problem.cameras[0].sigma_mm * (solved.outcome.cost / dof).sqrt(),
            outliers: solved.outliers,
        });
    }
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
    let active = bundle.obs.iter().filter(|o| o.active).count();
    let unknowns_now = bundle.camera_unknowns() + 3 * np;
    let dof = 2 * active as i64 + control_eq as i64 + bundle.prior_count() as i64
        - unknowns_now as i64
        + defect;
    let _ = unknowns;
    if dof <= 0 {
        return Err(AdjustError::TooFewObservations {
            observations: 2 * active + control_eq,
            unknowns: unknowns_now - defect as usize,
        });
    }
    finish(
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
        &start_points,
    )
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
#[allow(clippy::too_many_arguments)]
fn solve(
    problem: &EpochProblem,
    options: &AdjustOptions,
    mut bundle: Bundle,
    mirrors: &[Option<ImageState>],
    free: &[[bool; 8]],
    zbar: f64,
    datum: Datum,
    affine_first: bool,
    dof_of: &dyn Fn(&Bundle) -> i64,
) -> Result<Solved, AdjustError> {
    let mut warnings = Vec::new();
    // Stage 1: interior held, iteratively reweighted from the start so that a gross error cannot pull
    // the solution into a wrong basin; then gross residuals are set aside (and, with snooping off,
    // taken back before the final adjustment).
    let converged = choose_mirrors(&mut bundle, mirrors);
    if affine_first && bundle.model == Model::Orthogonal {
        affine_stage(&mut bundle);
    }
    let mut normals = None;
    let mut outcome = if options.model == Model::Orthogonal {
        let stage2: Vec<[bool; 8]> = free
            .iter()
            .map(|f| [f[0], false, false, false, false, false, false, false])
            .collect();
        let calibrate = stage2.iter().flatten().any(|&f| f);
        // With c to be freed, stage 1 ends with the robust rounds: stage 2 converges from there.
        let outcome = first_stage(
            &mut bundle,
            (!calibrate).then_some(options.max_iterations),
            converged,
        );
        if calibrate {
            bundle.free = stage2;
            let (outcome, n) =
                levenberg_marquardt_normals(&mut bundle, options.max_iterations, Start::Near);
            normals = n;
            outcome
        } else {
            outcome
        }
    } else {
        // The orthogonal solution (interior held) starts the collinearity adjustment; gross errors are
        // screened only once the interior orientation (e.g. strong distortion) is modelled. Without
        // `central_from_orthogonal` the start values go to collinearity directly (for comparisons).
        if options.central_from_orthogonal {
            levenberg_marquardt(&mut bundle, options.max_iterations);
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
        levenberg_marquardt(&mut bundle, options.max_iterations);
        first_stage(&mut bundle, Some(options.max_iterations), None)
    };

    // Data snooping, one observation at a time.
    // The cofactors of the solution, from the normal equations of its last (negligible) step when
    // the adjustment returned them.
    let invert = |b: &Bundle, n: Option<Normals>| {
        let n = n.unwrap_or_else(|| b.normals());
        Cofactors::from_normals(b, n, datum == Datum::Free).ok_or_else(|| {
            AdjustError::Singular("the normal equations are not positive definite".into())
        })
    };
    let mut cof = invert(&bundle, normals)?;
    let mut final_w = None;
    let mut capped = false;
    let mut model = VarianceModel::APriori;
    if options.snooping {
        let snooped = snoop(&mut bundle, cof, options, invert, dof_of)?;
        (outcome, cof, final_w) = (
            snooped.outcome.unwrap_or(outcome),
            snooped.cof,
            Some(snooped.w),
        );
        model = snooped.variance_model;
        capped = snooped.warning.is_some();
        warnings.extend(snooped.warning);
    } else {
        for k in 0..bundle.obs.len() {
            bundle.obs[k].active = true;
        }
        let n;
        (outcome, n) =
            levenberg_marquardt_normals(&mut bundle, options.max_iterations, Start::Near);
        cof = invert(&bundle, n)?;
    }
    let w: Vec<[f64; 2]> = match final_w {
        Some(w) => w,
        None => {
            // Without snooping the statistics follow the same variance model (Pope's τ when the
            // global test rejects the a-priori σ).
            let (m, _, s) = variance_model(&bundle, dof_of(&bundle), options.critical_w);
            model = m;
            (0..bundle.obs.len())
                .map(|k| normalized_residual(&bundle, &cof, k).map(|x| x / s))
                .collect()
        }
    };
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
    Ok(Solved {
        outliers: dropped.len() + beyond,
        bundle,
        outcome,
        cof,
        warnings,
        dropped,
        too_many_outliers,
        w,
        variance_model: model,
    })
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

/// Precision, datum transformation and the report.
#[allow(clippy::too_many_arguments)]
fn finish(
    problem: &EpochProblem,
    options: &AdjustOptions,
    bundle: Bundle,
    frame: WorkingFrame,
    cof: Cofactors,
    outcome: LmOutcome,
    dof: i64,
    datum: Datum,
    warnings: Vec<String>,
    dropped: Vec<DroppedObservation>,
    w: Vec<[f64; 2]>,
    variance_model: VarianceModel,
    start_points: &[Vector3<f64>],
) -> Result<Adjustment, AdjustError> {
    if !outcome.converged {
        return Err(AdjustError::NoConvergence {
            iterations: outcome.iterations,
            sigma0_mm: problem.cameras[0].sigma_mm * (outcome.cost / dof as f64).sqrt(),
        });
    }
    let variance_factor = outcome.cost / dof as f64;
    let mut warnings = warnings;
    let limit = chi2_upper(dof as f64, GLOBAL_TEST_Z) / dof as f64;
    if variance_factor > limit {
        warnings.push(format!(
            "global test failed: variance factor {variance_factor:.2} exceeds {limit:.2} (99.9 %): the a-priori σ is too optimistic, or a gross or model error remains"
        ));
    }
    let sigma_ref = problem.cameras[0].sigma_mm;
    let sigma0_mm = sigma_ref * variance_factor.sqrt();
    // Free network: the similarity onto the start coordinates gives the inner-constraint datum.
    let sim = match datum {
        Datum::Free => similarity_fit(&bundle.points, start_points),
        Datum::Control => None,
    };
    let to_datum = |x: &Vector3<f64>| sim.map_or(*x, |s| s.apply(x));
    let sim_rot = sim.map_or(Matrix3::identity(), |s| s.rotation);
    let sim_scale = sim.map_or(1.0, |s| s.scale);
    let np = problem.points.len();
    let mut points = Vec::with_capacity(np);
    let mut point_reports = Vec::with_capacity(np);
    let cov_site = |q: Matrix3<f64>| -> Matrix3<f64> {
        let q = sim_rot * q * sim_rot.transpose() * (sim_scale * sim_scale) * variance_factor;
        frame.covariance_to_site(&q)
    };
    for i in 0..np {
        let xyz = frame.to_site(to_datum(&bundle.points[i]));
        let cov = cov_site(cof.point_block(i, i));
        let sd = |k: usize| cov[(k, k)].max(0.0).sqrt() * 1000.0;
        point_reports.push(PointReport {
            point: problem.points[i].clone(),
            X: xyz.x,
            Y: xyz.y,
            Z: xyz.z,
            sigma_X_mm: sd(0),
            sigma_Y_mm: sd(1),
            sigma_Z_mm: sd(2),
        });
        let mut c = [[0.0; 3]; 3];
        for (r, row) in c.iter_mut().enumerate() {
            for (s, v) in row.iter_mut().enumerate() {
                *v = cov[(r, s)];
            }
        }
        points.push(AdjustedPoint {
            name: problem.points[i].clone(),
            xyz: [xyz.x, xyz.y, xyz.z],
            covariance_m2: c,
        });
    }
    // Joint covariance of the requested points.
    let chosen: Vec<usize> = options
        .joint_covariance_of
        .iter()
        .filter_map(|n| problem.point_index(n))
        .collect();
    let joint_covariance = (!chosen.is_empty()).then(|| {
        let d = 3 * chosen.len();
        let mut m = vec![0.0; d * d];
        for (a, &pa) in chosen.iter().enumerate() {
            for (b, &pb) in chosen.iter().enumerate() {
                let q = cof.point_block(pa, pb);
                let q =
                    sim_rot * q * sim_rot.transpose() * (sim_scale * sim_scale) * variance_factor;
                let q = frame.rotation.transpose() * q * frame.rotation;
                for r in 0..3 {
                    for s in 0..3 {
                        m[(3 * a + r) * d + 3 * b + s] = q[(r, s)];
                    }
                }
            }
        }
        JointCovariance {
            points: chosen.iter().map(|&p| problem.points[p].clone()).collect(),
            matrix_m2: m,
        }
    });
    // Cameras.
    let icols = bundle.interior_columns();
    let mut cameras = problem.cameras.clone();
    let mut camera_reports = Vec::new();
    for (k, cam) in cameras.iter_mut().enumerate() {
        cam.params = bundle.interior[k];
        let mut calibrated = Vec::new();
        let mut c_sigma = None;
        for (q, name) in INTERIOR_NAMES.iter().enumerate() {
            if let Some(col) = icols[k][q] {
                let s = (cof.camera_cofactor(col) * variance_factor).max(0.0).sqrt();
                if q == 0 {
                    c_sigma = Some(s);
                }
                calibrated.push(CalibratedParameter {
                    name: name.to_string(),
                    value: cam.params[q],
                    sigma: s,
                });
            }
        }
        camera_reports.push(CameraReport {
            id: cam.id.clone(),
            c_mm: cam.params[0],
            c_sigma_mm: c_sigma,
            calibrated,
        });
    }
    // Orientations in the site frame (after the datum similarity).
    let orientations = problem
        .images
        .iter()
        .enumerate()
        .map(|(j, im)| {
            let st = &bundle.images[j];
            let c = bundle.interior[im.camera][0];
            let (r_w, xo_w) = match bundle.model {
                Model::Orthogonal => {
                    let o = OrthoImage {
                        rotation: st.rotation,
                        m: st.p[0],
                        a4: st.p[1],
                        a8: st.p[2],
                    };
                    (
                        st.rotation,
                        o.center(c, bundle.zbar).unwrap_or_else(Vector3::zeros),
                    )
                }
                Model::Central => {
                    let ci = CentralImage {
                        rotation: st.rotation,
                        center: Vector3::from(st.p),
                    };
                    (ci.rotation, ci.center)
                }
            };
            let r_w = r_w * sim_rot.transpose();
            let xo = frame.to_site(to_datum(&xo_w));
            let r = frame.rotation_to_site(&r_w);
            let mut rotation = [[0.0; 3]; 3];
            for (a, row) in rotation.iter_mut().enumerate() {
                for (b, v) in row.iter_mut().enumerate() {
                    *v = r[(a, b)];
                }
            }
            ImageOrientation {
                image: im.id.clone(),
                station: im.station.clone(),
                camera: problem.cameras[im.camera].id.clone(),
                rotation,
                center: [xo.x, xo.y, xo.z],
            }
        })
        .collect();
    // Residuals.
    let mut residuals = Vec::with_capacity(bundle.obs.len());
    let mut sums = vec![(0usize, 0.0f64); problem.images.len()];
    for (k, o) in bundle.obs.iter().enumerate() {
        let cam = bundle.image_camera[o.image];
        let e = residual_value(
            bundle.model,
            &bundle.images[o.image],
            &bundle.interior[cam],
            &bundle.points[o.point],
            o.meas,
            bundle.zbar,
        );
        let w = w[k];
        if o.active {
            sums[o.image].0 += 1;
            sums[o.image].1 += e[0] * e[0] + e[1] * e[1];
        }
        residuals.push(ResidualReport {
            image: problem.images[o.image].id.clone(),
            point: problem.points[o.point].clone(),
            vx_mm: e[0],
            vy_mm: e[1],
            w: w[0].abs().max(w[1].abs()),
            dropped: !o.active,
        });
    }
    let image_reports = problem
        .images
        .iter()
        .zip(&sums)
        .map(|(im, &(n, s))| ImageReport {
            id: im.id.clone(),
            observations: n,
            rms_mm: if n > 0 {
                (s / (2 * n) as f64).sqrt()
            } else {
                0.0
            },
        })
        .collect();
    let report = AdjustmentReport {
        model: bundle.model,
        converged: outcome.converged,
        iterations: outcome.iterations,
        sigma0_mm,
        dof,
        variance_factor,
        cameras: camera_reports,
        points: point_reports,
        images: image_reports,
        dropped,
        warnings,
        residuals,
        datum: match datum {
            Datum::Free => "free network (inner constraints)".into(),
            Datum::Control => "control points".into(),
        },
        index3_rmse_mm: None,
        index4_rmse_mm: None,
        variance_model,
    };
    Ok(Adjustment {
        report,
        points,
        orientations,
        cameras,
        joint_covariance,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Pope's τ critical value against the Student-t table: t(0.9995; 99) = 3.392 gives
    /// τ = 3.392 √(100 / (99 + 3.392²)) = 3.227 for r = 100; it tends to z for large r and never
    /// exceeds √r.
    #[test]
    fn tau_critical_matches_the_table() {
        assert!((tau_critical(3.2905, 100.0) - 3.227).abs() < 0.01);
        assert!((tau_critical(3.2905, 1e6) - 3.2905).abs() < 1e-3);
        assert!(tau_critical(3.2905, 3.0) <= 3f64.sqrt());
        assert!(tau_critical(3.2905, 170.0) < 3.2905);
    }

    /// The global test's two bounds bracket 1 and tighten with the redundancy.
    #[test]
    fn global_test_bounds_bracket_one() {
        for r in [20.0, 170.0, 2000.0] {
            let (lo, hi) = (
                chi2_lower(r, GLOBAL_TEST_Z) / r,
                chi2_upper(r, GLOBAL_TEST_Z) / r,
            );
            assert!(lo < 1.0 && hi > 1.0 && lo > 0.0, "r = {r}: {lo} {hi}");
        }
        let w170 =
            chi2_upper(170.0, GLOBAL_TEST_Z) / 170.0 - chi2_lower(170.0, GLOBAL_TEST_Z) / 170.0;
        let w2000 =
            chi2_upper(2000.0, GLOBAL_TEST_Z) / 2000.0 - chi2_lower(2000.0, GLOBAL_TEST_Z) / 2000.0;
        assert!(w2000 < w170);
    }
}
