//! The robust first stage of an adjustment: mirror choice among the start's alternatives, the
//! affine bundle, Cauchy-reweighted rounds, a leave-one-image-out rescue from a wrong basin, the
//! re-resection of images that fit badly, and the screening of gross residuals before the data
//! snooping.

use nalgebra::Vector3;

use crate::photogrammetry::model::bundle::{Bundle, ImageState};
use crate::photogrammetry::model::camera::brown_correct;
use crate::photogrammetry::model::orthogonal::OrthoImage;
use crate::photogrammetry::solve::lm::{
    levenberg_marquardt, levenberg_marquardt_normals, levenberg_marquardt_within, LmOutcome, Start,
    ROUND_STEP,
};
use crate::photogrammetry::start::start_values::{resect_image, robust_scale, StartImage};
use crate::photogrammetry::statistics::snooping::ActiveCounts;

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
pub(crate) fn first_stage(
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
        let Ok(res) = resect_image(&image, &known) else {
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
pub(crate) fn affine_stage(bundle: &mut Bundle) {
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
pub(crate) fn choose_mirrors(
    bundle: &mut Bundle,
    mirrors: &[Option<ImageState>],
) -> Option<LmOutcome> {
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
            if base.cancel.is_cancelled() {
                break;
            }
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
        if bundle.cancel.is_cancelled() {
            break;
        }
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
            let e = bundle.residual_of(o);
            (e[0] * e[0] + e[1] * e[1]).sqrt() * o.prior_weight.sqrt() / bundle.sigma[cam]
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
    robust_scale(&active) / std::f64::consts::SQRT_2
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
