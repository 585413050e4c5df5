//! The adjustment: validation, start values, the working frame, Levenberg–Marquardt with the Schur
//! complement, datum (free network with inner constraints, or weighted control points) and data
//! snooping; `site_result` then gives the precision, the site frame and the report. The
//! orthogonal model always runs first; the central model starts from its solution.

use nalgebra::{Matrix3, Vector3};

use super::options::AdjustOptions;
use super::report::{DroppedObservation, VarianceModel};
use super::result::Adjustment;
use super::robust::{affine_stage, choose_mirrors, first_stage};
use super::site_result::{site_result, Solution};
use crate::photogrammetry::error::AdjustError;
use crate::photogrammetry::input::epoch::{EpochInput, EpochProblem};
use crate::photogrammetry::model::bundle::{Bundle, ImageState, Obs};
use crate::photogrammetry::model::camera::{brown_correct, INTERIOR_NAMES};
use crate::photogrammetry::model::frame::WorkingFrame;
use crate::photogrammetry::model::orthogonal::OrthoImage;
use crate::photogrammetry::model::Model;
use crate::photogrammetry::solve::lm::{
    levenberg_marquardt, levenberg_marquardt_normals, LmOutcome, Start,
};
use crate::photogrammetry::solve::normal_equations::Normals;
use crate::photogrammetry::start::start_values::{start_values, StartImage, StartValues};
use crate::photogrammetry::statistics::global_test::{chi2_upper, variance_model, GLOBAL_TEST_Z};
use crate::photogrammetry::statistics::precision::Cofactors;
use crate::photogrammetry::statistics::snooping::{
    normalized_residual, ActiveCounts, LinearSnooping,
};

/// Relative weight of the prior on point increments that holds the free network's datum during the
/// iteration (a fraction of the mean point block diagonal).
const GAUGE: f64 = 1e-9;

/// σ of the prior on a self-calibrated c, relative to its given value.
const C_PRIOR_RELATIVE: f64 = 0.1;

/// Validates and adjusts an epoch of the upload form.
pub fn adjust(input: &EpochInput, options: &AdjustOptions) -> Result<Adjustment, AdjustError> {
    let problem = input.validate()?;
    adjust_problem(&problem, options)
}

/// The datum of an adjustment.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Datum {
    /// Inner constraints on all points (minimum norm against the start coordinates).
    Free,
    /// Control points as weighted observations.
    Control,
}

/// Every point needs rays from two stations: two images from one station (two exposures, or
/// two pointings of one set-up) see it along one line, which leaves its depth undetermined.
fn check_geometry(problem: &EpochProblem) -> Result<(), AdjustError> {
    let mut seen: Vec<Vec<&str>> = vec![Vec::new(); problem.points.len()];
    for im in &problem.images {
        for o in &im.observations {
            seen[o.point].push(im.station.as_str());
        }
    }
    for (p, stations) in seen.iter_mut().enumerate() {
        let images = stations.len();
        if images < 2 {
            return Err(AdjustError::PointInTooFewImages {
                point: problem.points[p].clone(),
                images,
            });
        }
        stations.sort_unstable();
        stations.dedup();
        if let [station] = stations.as_slice() {
            return Err(AdjustError::PointFromOneStation {
                point: problem.points[p].clone(),
                station: (*station).to_string(),
                images,
            });
        }
    }
    Ok(())
}

/// An adjustment ready to run: the stage-1 bundle in the working frame (interior held), the
/// mirror-image alternatives of the start, which interior parameters become unknowns later, and
/// the datum.
struct Prepared {
    frame: WorkingFrame,
    bundle: Bundle,
    mirrors: Vec<Option<ImageState>>,
    free: Vec<[bool; 8]>,
    start_points: Vec<Vector3<f64>>,
    datum: Datum,
    /// Control coordinates observed (3 per control point when control fixes the datum).
    control_eq: usize,
    warnings: Vec<String>,
}

impl Prepared {
    /// Observation equations of `b` (active observations, control and prior
    /// pseudo-observations) and its unknowns less the datum defect of a free network.
    fn counts(&self, b: &Bundle) -> (usize, usize) {
        let active = b.obs.iter().filter(|o| o.active).count();
        let defect = if self.datum == Datum::Free { 7 } else { 0 };
        (
            2 * active + self.control_eq + b.prior_count(),
            (b.camera_unknowns() + 3 * b.points.len()).saturating_sub(defect),
        )
    }

    /// Degrees of freedom of `b`: observation equations less unknowns ([`Self::counts`]).
    fn dof(&self, b: &Bundle) -> i64 {
        let (observations, unknowns) = self.counts(b);
        observations as i64 - unknowns as i64
    }
}

/// Known coordinates per point, centred on their centroid `origin` (m, site frame).
struct KnownPoints {
    centred: Vec<Option<Vector3<f64>>>,
    origin: Vector3<f64>,
}

/// The known coordinates of the points: approximations or control, else the site's earlier
/// epochs.
fn known_points(
    problem: &EpochProblem,
    options: &AdjustOptions,
) -> Result<KnownPoints, AdjustError> {
    let known_site: Vec<Option<Vector3<f64>>> = (0..problem.points.len())
        .map(|p| {
            problem.approx[p]
                .or_else(|| options.prior.get(&problem.points[p]).copied())
                .map(Vector3::from)
        })
        .collect();
    let known_list: Vec<Vector3<f64>> = known_site.iter().flatten().copied().collect();
    if known_list.is_empty() {
        return Err(AdjustError::TooFewKnownPoints {
            image: problem.images[0].id.clone(),
            known: 0,
        });
    }
    let origin = known_list.iter().fold(Vector3::zeros(), |a, b| a + b) / known_list.len() as f64;
    let centred = known_site.iter().map(|k| k.map(|k| k - origin)).collect();
    Ok(KnownPoints { centred, origin })
}

/// The interior parameters each camera estimates (only c with the orthogonal model); none with
/// fewer than three images, which cannot determine them (with a warning).
fn interior_unknowns(
    problem: &EpochProblem,
    options: &AdjustOptions,
    warnings: &mut Vec<String>,
) -> Vec<[bool; 8]> {
    let nimg = problem.images.len();
    let free: Vec<[bool; 8]> = problem
        .cameras
        .iter()
        .map(|c| {
            let f = c.calibrate;
            if options.model != Model::Orthogonal {
                return f;
            }
            let held: Vec<&str> = (1..8)
                .filter(|&k| f[k])
                .map(|k| INTERIOR_NAMES[k])
                .collect();
            if !held.is_empty() {
                warnings.push(format!(
                    "camera '{}': the orthogonal model estimates only c; {} held at the given \
                     values (the central model calibrates them)",
                    c.id,
                    held.join(", ")
                ));
            }
            [f[0], false, false, false, false, false, false, false]
        })
        .collect();
    if nimg >= 3 {
        return free;
    }
    warnings.push(format!(
        "only {nimg} images: the depth of the free network is weakly determined"
    ));
    if free.iter().flatten().any(|&f| f) {
        warnings.push(
            "two images cannot determine the interior orientation: c and the other interior parameters are held at their given values"
                .into(),
        );
    }
    vec![[false; 8]; free.len()]
}

/// Control points fix the datum when there are at least three; fewer are used as approximations
/// of a free network (with a warning). Returns the datum and the number of control points.
fn choose_datum(problem: &EpochProblem, warnings: &mut Vec<String>) -> (Datum, usize) {
    let control_count = problem.control.iter().flatten().count();
    if control_count >= 3 {
        return (Datum::Control, control_count);
    }
    if control_count > 0 {
        warnings.push(format!(
            "{control_count} control point(s) are too few to fix the datum: free network, control used as approximations"
        ));
    }
    (Datum::Free, control_count)
}

/// Start values from the known points, the working frame (Z along the mean viewing axis, origin
/// at the centroid of all start points) and the stage-1 bundle in it.
/// The images as the start values see them: each observation corrected for its camera's lens
/// distortion (image mm).
fn start_images(problem: &EpochProblem) -> Vec<StartImage> {
    problem
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
        .collect()
}

/// The working frame (docs/orthogonal-projection.md): axes from the start rotations' first and
/// third rows, origin at the start points' centroid (in the site frame: centred + `origin`, m).
fn working_frame(start: &StartValues, origin: Vector3<f64>) -> WorkingFrame {
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
    let centroid =
        start.points.iter().fold(Vector3::zeros(), |a, b| a + b) / start.points.len() as f64;
    WorkingFrame::from_axes(&r1s, &r3s, centroid + origin)
}

/// Every observation of the problem, in image order, with its index per point; those the start
/// values flagged as `suspects` (image, observation index; sorted) start inactive.
fn observations(
    problem: &EpochProblem,
    suspects: &[(usize, usize)],
) -> (Vec<Obs>, Vec<Vec<usize>>) {
    let mut obs = Vec::new();
    let mut point_obs = vec![Vec::new(); problem.points.len()];
    for (j, im) in problem.images.iter().enumerate() {
        for (k, o) in im.observations.iter().enumerate() {
            point_obs[o.point].push(obs.len());
            obs.push(Obs {
                image: j,
                point: o.point,
                meas: o.xy,
                active: suspects.binary_search(&(j, k)).is_err(),
                weight: 1.0,
            });
        }
    }
    (obs, point_obs)
}

fn prepare(problem: &EpochProblem, options: &AdjustOptions) -> Result<Prepared, AdjustError> {
    let np = problem.points.len();
    let KnownPoints {
        centred: known,
        origin,
    } = known_points(problem, options)?;
    let start = start_values(&start_images(problem), &known)?;
    let frame = working_frame(&start, origin);
    let to_w = |x_centred: &Vector3<f64>| frame.to_working(x_centred + origin);

    let mut warnings = Vec::new();
    let free = interior_unknowns(problem, options, &mut warnings);
    let (datum, control_count) = choose_datum(problem, &mut warnings);
    let start_points: Vec<Vector3<f64>> = start.points.iter().map(to_w).collect();
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
    let nimg = problem.images.len();
    let images: Vec<ImageState> = (0..nimg)
        .map(|j| state(j, &start.rotations[j], &start.centers[j]))
        .collect();
    let mirrors: Vec<Option<ImageState>> = (0..nimg)
        .map(|j| start.mirrors[j].map(|(r, xo)| state(j, &r, &xo)))
        .collect();
    let (obs, point_obs) = observations(problem, &start.suspects);
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
    Ok(Prepared {
        frame,
        bundle,
        mirrors,
        free,
        start_points,
        datum,
        control_eq: if datum == Datum::Control {
            3 * control_count
        } else {
            0
        },
        warnings,
    })
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
    if suspect(&solved) && options.model == Model::Orthogonal {
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
    let solved = solve_or_retry(problem, options, &prepared)?;
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
    let cof = invert(&bundle, normals)?;
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
