//! The epoch made ready for the solver: the geometry check, the known points, the start values
//! and the working frame, which interior parameters become unknowns, the datum (free network or
//! control), and the first bundle with its observations.

use nalgebra::{Matrix3, Vector3};

use super::options::AdjustOptions;
use crate::photogrammetry::error::AdjustError;
use crate::photogrammetry::input::epoch::EpochProblem;
use crate::photogrammetry::model::bundle::{Bundle, ImageState, Obs};
use crate::photogrammetry::model::camera::{brown_correct, INTERIOR_NAMES};
use crate::photogrammetry::model::frame::WorkingFrame;
use crate::photogrammetry::model::orthogonal::OrthoImage;
use crate::photogrammetry::model::Model;
use crate::photogrammetry::start::start_values::{start_values, StartImage, StartValues};

/// Relative weight of the prior on point increments that holds the free network's datum during the
/// iteration (a fraction of the mean point block diagonal).
const GAUGE: f64 = 1e-9;

/// σ of the prior on a self-calibrated c, relative to its given value (0.1: 10 %). The prior
/// centre is the given c, the same in every epoch of a camera: its share of c's information is a
/// common offset of those epochs, not scatter between them (`plan::InteriorPrecision`).
pub const C_PRIOR_RELATIVE: f64 = 0.1;

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
pub(super) fn check_geometry(problem: &EpochProblem) -> Result<(), AdjustError> {
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
pub(super) struct Prepared {
    pub(super) frame: WorkingFrame,
    pub(super) bundle: Bundle,
    pub(super) mirrors: Vec<Option<ImageState>>,
    pub(super) free: Vec<[bool; 8]>,
    pub(super) start_points: Vec<Vector3<f64>>,
    pub(super) datum: Datum,
    /// Control coordinates observed (3 per control point when control fixes the datum).
    pub(super) control_eq: usize,
    pub(super) warnings: Vec<String>,
}

impl Prepared {
    /// Observation equations of `b` (active observations, control and prior
    /// pseudo-observations) and its unknowns less the datum defect of a free network.
    pub(super) fn counts(&self, b: &Bundle) -> (usize, usize) {
        let active = b.obs.iter().filter(|o| o.active).count();
        let defect = if self.datum == Datum::Free { 7 } else { 0 };
        (
            2 * active + self.control_eq + b.prior_count(),
            (b.camera_unknowns() + 3 * b.points.len()).saturating_sub(defect),
        )
    }

    /// Degrees of freedom of `b`: observation equations less unknowns ([`Self::counts`]).
    pub(super) fn dof(&self, b: &Bundle) -> i64 {
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

/// The working frame (docs/model.md): axes from the start rotations' first and
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
                prior_weight: o
                    .sigma_mm
                    .map_or(1.0, |s| (problem.cameras[im.camera].sigma_mm / s).powi(2)),
            });
        }
    }
    (obs, point_obs)
}

pub(super) fn prepare(
    problem: &EpochProblem,
    options: &AdjustOptions,
) -> Result<Prepared, AdjustError> {
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
        cancel: options.cancel.clone(),
        // A weak prior on c (10 % of the given value) keeps a self-calibrated c finite where the
        // geometry cannot determine it (a flat face at long range). Its weight is not always
        // negligible: with 1 m of relief at 150 m it carries about half of c's information.
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
