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
use super::lm::{levenberg_marquardt, LmOutcome};
use super::normals::Bundle;
use super::orthogonal::OrthoImage;
use super::precision::Cofactors;
use super::report::{
    AdjustmentReport, CalibratedParameter, CameraReport, DroppedObservation, ImageReport, Model,
    PointReport, ResidualReport,
};
use super::result::{AdjustOptions, AdjustedPoint, Adjustment, ImageOrientation, JointCovariance};
use super::snooping::{droppable, normalized_residual};
use super::start::{start_values, StartImage};

/// Relative weight of the prior on point increments that holds the free network's datum during the
/// iteration (a fraction of the mean point block diagonal).
const GAUGE: f64 = 1e-9;

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
    robust_rounds(&mut trial, ROBUST_ITERATIONS);
    *bundle = trial;
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

/// Iteratively reweighted least squares with Cauchy weights `1/(1 + (r/(3s))²)`, a few rounds, so
/// that gross errors (a mislabeled target) cannot drag the solution into a wrong basin before the
/// screening. Leaves the weights at 1.
fn robust_rounds(bundle: &mut Bundle, iterations: usize) {
    for round in 0..12 {
        let norms = residual_norms(bundle);
        let s = residual_scale(bundle, &norms).max(1.0);
        if s < 1.5 && round > 0 {
            break;
        }
        for (o, r) in bundle.obs.iter_mut().zip(&norms) {
            o.weight = 1.0 / (1.0 + (r / (3.0 * s)).powi(2));
        }
        levenberg_marquardt(bundle, iterations);
    }
    for o in bundle.obs.iter_mut() {
        o.weight = 1.0;
    }
}

fn screen(bundle: &mut Bundle) -> usize {
    let norms = residual_norms(bundle);
    let scale = residual_scale(bundle, &norms);
    let limit = (SCREEN_FACTOR * scale).max(3.0);
    let mut order: Vec<usize> = (0..norms.len()).filter(|&k| norms[k] > limit).collect();
    order.sort_by(|&a, &b| norms[b].total_cmp(&norms[a]));
    let cap = bundle.obs.len() / 5;
    let mut n = 0;
    for k in order {
        if n >= cap {
            break;
        }
        if droppable(bundle, k) {
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
    let images: Vec<ImageState> = (0..nimg)
        .map(|j| {
            let c = problem.cameras[problem.images[j].camera].c();
            let r_w = frame.rotation_to_working(&start.rotations[j]);
            let xo_w = to_w(&start.centers[j]);
            let o = OrthoImage::from_center(r_w, xo_w, c, zbar);
            ImageState {
                rotation: r_w,
                p: [o.m, o.a4, o.a8],
            }
        })
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
                active: !start.suspects.contains(&(j, k)),
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
        let n = bundle.normals();
        let mean: f64 = n.v.iter().map(|v| v.trace() / 3.0).sum::<f64>() / np as f64;
        bundle.gauge = GAUGE * mean.max(1e-300);
    }
    let unknowns = bundle.camera_unknowns() + 3 * np;
    let defect = if datum == Datum::Free { 7 } else { 0 };
    let control_eq = if datum == Datum::Control {
        3 * control_count
    } else {
        0
    };

    // Stage 1: interior held; with snooping on, iteratively reweighted from the start so that a gross
    // error cannot pull the solution into a wrong basin; then gross residuals are set aside.
    let initial = bundle.clone();
    let mut outcome = if options.snooping {
        robust_rounds(&mut bundle, ROBUST_ITERATIONS);
        if residual_scale(&bundle, &residual_norms(&bundle)) > RESCUE_SCALE {
            rescue(&mut bundle, &initial);
        }
        screen(&mut bundle);
        levenberg_marquardt(&mut bundle, options.max_iterations)
    } else {
        levenberg_marquardt(&mut bundle, options.max_iterations)
    };
    let stage2: Vec<[bool; 8]> = free
        .iter()
        .map(|f| [f[0], false, false, false, false, false, false, false])
        .collect();
    if stage2.iter().flatten().any(|&f| f) {
        bundle.free = stage2;
        outcome = levenberg_marquardt(&mut bundle, options.max_iterations);
    }
    if options.model == Model::Central {
        // Start the collinearity adjustment from the orthogonal solution.
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
        bundle.free = free.clone();
        outcome = levenberg_marquardt(&mut bundle, options.max_iterations);
    }

    // Data snooping, one observation at a time.
    let mut dropped: Vec<DroppedObservation> = Vec::new();
    let mut dropped_idx: Vec<usize> = Vec::new();
    let max_drops = (bundle.obs.len() / 10).max(1);
    let mut cof = Cofactors::new(&bundle, datum == Datum::Free).ok_or_else(|| {
        AdjustError::Singular("the normal equations are not positive definite".into())
    })?;
    if options.snooping {
        loop {
            let mut worst: Option<(usize, f64)> = None;
            for k in 0..bundle.obs.len() {
                if !bundle.obs[k].active || !droppable(&bundle, k) {
                    continue;
                }
                let w = normalized_residual(&bundle, &cof, k);
                let m = w[0].abs().max(w[1].abs());
                if m > options.critical_w && worst.is_none_or(|(_, x)| m > x) {
                    worst = Some((k, m));
                }
            }
            let Some((k, w)) = worst else { break };
            if dropped_idx.len() >= max_drops {
                warnings.push(format!(
                    "data snooping stopped after {max_drops} dropped observations; more residuals exceed |w| = {}",
                    options.critical_w
                ));
                break;
            }
            bundle.obs[k].active = false;
            dropped_idx.push(k);
            dropped.push(DroppedObservation {
                image: problem.images[bundle.obs[k].image].id.clone(),
                point: problem.points[bundle.obs[k].point].clone(),
                w,
            });
            outcome = levenberg_marquardt(&mut bundle, options.max_iterations);
            cof = Cofactors::new(&bundle, datum == Datum::Free).ok_or_else(|| {
                AdjustError::Singular("the normal equations are not positive definite".into())
            })?;
        }
        // Observations set aside at the start: keep out those that still misfit, take back the rest.
        let suspects: Vec<usize> = (0..bundle.obs.len())
            .filter(|k| !bundle.obs[*k].active && !dropped_idx.contains(k))
            .collect();
        let mut readmitted = false;
        for k in suspects {
            let w = normalized_residual(&bundle, &cof, k);
            let m = w[0].abs().max(w[1].abs());
            if m > options.critical_w {
                dropped_idx.push(k);
                dropped.push(DroppedObservation {
                    image: problem.images[bundle.obs[k].image].id.clone(),
                    point: problem.points[bundle.obs[k].point].clone(),
                    w: m,
                });
            } else {
                bundle.obs[k].active = true;
                readmitted = true;
            }
        }
        if readmitted {
            outcome = levenberg_marquardt(&mut bundle, options.max_iterations);
            cof = Cofactors::new(&bundle, datum == Datum::Free).ok_or_else(|| {
                AdjustError::Singular("the normal equations are not positive definite".into())
            })?;
        }
    } else {
        for k in 0..bundle.obs.len() {
            bundle.obs[k].active = true;
        }
        outcome = levenberg_marquardt(&mut bundle, options.max_iterations);
        cof = Cofactors::new(&bundle, datum == Datum::Free).ok_or_else(|| {
            AdjustError::Singular("the normal equations are not positive definite".into())
        })?;
    }
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
        &start_points,
    )
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
    start_points: &[Vector3<f64>],
) -> Result<Adjustment, AdjustError> {
    if !outcome.converged {
        return Err(AdjustError::NoConvergence {
            iterations: outcome.iterations,
            sigma0_mm: problem.cameras[0].sigma_mm * (outcome.cost / dof as f64).sqrt(),
        });
    }
    let variance_factor = outcome.cost / dof as f64;
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
        let w = normalized_residual(&bundle, &cof, k);
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
    };
    Ok(Adjustment {
        report,
        points,
        orientations,
        cameras,
        joint_covariance,
    })
}
