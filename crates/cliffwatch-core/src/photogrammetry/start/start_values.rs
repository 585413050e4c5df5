//! Start values from four known points per image (`docs/model.md`, "Start values"):
//! affine resection (eqs 1, 5, 10–14), a perspective refinement of each image on its known points
//! (the closed-form model, which also picks the right mirror for planar point sets), and intersection
//! of the rays of every other point. Gross misfits of the start are set aside for the data snooping.

use nalgebra::{Matrix3, Matrix6, Vector3, Vector6};

use super::affine::{is_planar, resect, resect_planar, tilt_significance, ConstrainedAffine};
use crate::photogrammetry::error::AdjustError;
use crate::photogrammetry::model::orthogonal::{project, project_jacobian};
use crate::photogrammetry::model::rotation::{perturbed, update};

/// Below this ratio of smallest to largest principal spread the known points count as planar.
pub const PLANAR_RATIO: f64 = 0.03;

/// One image's data for the start: its principal distance and its observations
/// (point index, corrected image coordinates in mm).
#[derive(Debug, Clone)]
pub struct StartImage {
    /// Image id (for errors).
    pub id: String,
    /// Principal distance c in mm.
    pub c: f64,
    /// (point index, corrected x, y in mm).
    pub observations: Vec<(usize, [f64; 2])>,
}

/// Start values in a site frame shifted to the centroid of the known points (m).
#[derive(Debug, Clone)]
pub struct StartValues {
    /// Camera rotations (site axes).
    pub rotations: Vec<Matrix3<f64>>,
    /// Projection centres (m).
    pub centers: Vec<Vector3<f64>>,
    /// Point coordinates (m).
    pub points: Vec<Vector3<f64>>,
    /// Observations (image, index into its observations) whose start misfit is gross, ascending.
    pub suspects: Vec<(usize, usize)>,
    /// Per image, the mirror solution (rotation, centre) of a planar point set, if any.
    pub mirrors: Vec<Option<(Matrix3<f64>, Vector3<f64>)>>,
}

/// Relative decrease of the squared misfit below which the refinement of a start orientation stops
/// (the start needs to be close, not exact: the adjustment converges from it).
const START_TOLERANCE: f64 = 1e-6;

/// Refines one image's orientation on points of known coordinates with the closed-form model
/// (c fixed), at most `iterations` Levenberg–Marquardt steps on (three rotation increments, m, A4, A8). Returns the refined
/// rotation, projection centre (m) and the sum of squared residuals (mm²).
fn refine_image(
    cand: &ConstrainedAffine,
    pts: &[Vector3<f64>],
    xy: &[[f64; 2]],
    c: f64,
    iterations: usize,
) -> Option<(Matrix3<f64>, Vector3<f64>, f64)> {
    // Local frame: the candidate's own camera axes, so that a33 = 1 at the start.
    let frame = cand.rotation;
    let local: Vec<Vector3<f64>> = pts.iter().map(|p| frame * p).collect();
    let zbar = local.iter().map(|p| p.z).sum::<f64>() / local.len() as f64;
    let mut rot = Matrix3::identity();
    let (mut m, mut a4, mut a8) = (cand.m, cand.a4, cand.a8);
    let cost_of = |rot: &Matrix3<f64>, m: f64, a4: f64, a8: f64| -> f64 {
        let rows = perturbed::<f64>(rot, [0.0; 3]);
        local
            .iter()
            .zip(xy)
            .map(|(p, o)| {
                let [x, y] = project(&rows, m, a4, a8, c, zbar, &[p.x, p.y, p.z]);
                (o[0] - x).powi(2) + (o[1] - y).powi(2)
            })
            .sum::<f64>()
    };
    let mut cost = cost_of(&rot, m, a4, a8);
    if !cost.is_finite() {
        return None;
    }
    let mut lambda = 1e-3;
    for _ in 0..iterations {
        let mut n = Matrix6::zeros();
        let mut g = Vector6::zeros();
        for (p, o) in local.iter().zip(xy) {
            // Columns 0..6 of the hand-derived Jacobian: rotation increments, m, A4, A8.
            let (f, jac) = project_jacobian(&rot, m, a4, a8, c, zbar, p);
            for k in 0..2 {
                let j = Vector6::from_column_slice(&jac[k][..6]);
                let e = o[k] - f[k];
                n += j * j.transpose();
                g += j * e;
            }
        }
        let mut improved = false;
        for _ in 0..12 {
            let mut nd = n;
            for k in 0..6 {
                nd[(k, k)] += lambda * n[(k, k)].max(1e-12);
            }
            let Some(step) = nd.cholesky().map(|ch| ch.solve(&g)) else {
                lambda *= 10.0;
                continue;
            };
            let r_new = update(&rot, Vector3::new(step[0], step[1], step[2]));
            let (m2, a42, a82) = (m + step[3], a4 + step[4], a8 + step[5]);
            let c2 = cost_of(&r_new, m2, a42, a82);
            if c2.is_finite() && c2 <= cost {
                let done = cost - c2 <= START_TOLERANCE * cost.max(1e-300);
                rot = r_new;
                m = m2;
                a4 = a42;
                a8 = a82;
                cost = c2;
                lambda = (lambda * 0.1).max(1e-12);
                improved = !done;
                break;
            }
            lambda *= 10.0;
        }
        if !improved {
            break;
        }
    }
    let img = crate::photogrammetry::model::orthogonal::OrthoImage {
        rotation: rot,
        m,
        a4,
        a8,
    };
    let center_local = img.center(c, zbar)?;
    let rotation = rot * frame;
    let center = frame.transpose() * center_local;
    if !(center.iter().all(|v| v.is_finite()) && m > 0.0) {
        return None;
    }
    // The camera must look at the points (negative depth r3·(X − Xo) for all of them).
    let in_front = pts
        .iter()
        .all(|p| rotation.row(2).dot(&(p - center).transpose()) < 0.0);
    in_front.then_some((rotation, center, cost))
}

/// Least-squares intersection of rays: the point closest to all lines Xo + t d (m).
fn intersect_rays(rays: &[(Vector3<f64>, Vector3<f64>)]) -> Option<Vector3<f64>> {
    if rays.len() < 2 {
        return None;
    }
    let mut n = Matrix3::zeros();
    let mut b = Vector3::zeros();
    for (o, d) in rays {
        let p = Matrix3::identity() - d * d.transpose();
        n += p;
        b += p * o;
    }
    let x = n.try_inverse()? * b;
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// A resection of one image.
#[derive(Debug, Clone)]
pub struct Resection {
    /// Rotation (camera = R (X − Xo)).
    pub rotation: Matrix3<f64>,
    /// Projection centre (m).
    pub center: Vector3<f64>,
    /// The mirror solution of a planar point set (rotation, centre), when there is one.
    pub mirror: Option<(Matrix3<f64>, Vector3<f64>)>,
    /// Observations (indices into the image's list) left out as gross misfits.
    pub removed: Vec<usize>,
}

/// Orientation (rotation, centre, squared misfit sum) of one image from points of known coordinates:
/// affine candidates refined with the perspective model, the best kept.
fn fit_orientation(
    pts: &[Vector3<f64>],
    xy: &[[f64; 2]],
    c: f64,
) -> Vec<(Matrix3<f64>, Vector3<f64>, f64)> {
    let candidates: Vec<ConstrainedAffine> = if is_planar(pts, PLANAR_RATIO) {
        resect_planar(pts, xy).map(Vec::from).unwrap_or_default()
    } else {
        resect(pts, xy)
            .and_then(|a| a.constrained())
            .into_iter()
            .collect()
    };
    let mut fits: Vec<_> = candidates
        .iter()
        .filter_map(|cand| refine_image(cand, pts, xy, c, 100))
        .collect();
    fits.sort_by(|a, b| a.2.total_cmp(&b.2));
    fits
}

/// Points whose smallest principal spread is below this fraction of the largest get a mirror candidate
/// (when the image does not determine the tilt, see [`MIRROR_SIGNIFICANCE`]).
pub const MIRROR_RATIO: f64 = 0.3;

/// Tilt significance |γ|/σ(γ) above which the image itself decides the mirror root.
pub const MIRROR_SIGNIFICANCE: f64 = 5.0;

/// The mirror of an orientation through the best-fit plane of the points (the other root of
/// constraints (10)–(11) for a planar set), refined with the perspective model. None where the points
/// are far from planar, or where the refinement falls back onto the original.
fn mirror_fit(
    rot: &Matrix3<f64>,
    pts: &[Vector3<f64>],
    xy: &[[f64; 2]],
    c: f64,
) -> Option<(Matrix3<f64>, Vector3<f64>)> {
    if !is_planar(pts, MIRROR_RATIO) || tilt_significance(pts, xy) > MIRROR_SIGNIFICANCE {
        return None;
    }
    let n = plane_normal(pts)?;
    let reflect = |r: Vector3<f64>| r - 2.0 * r.dot(&n) * n;
    let r1 = reflect(rot.row(0).transpose());
    let r2 = reflect(rot.row(1).transpose());
    // m, A4, A8 for the reflected rows by linear least squares.
    let mut nm = Matrix3::zeros();
    let mut b = Vector3::zeros();
    for (p, o) in pts.iter().zip(xy) {
        for (row, obs, k) in [(r1.dot(p), o[0], 1), (r2.dot(p), o[1], 2)] {
            let mut a = Vector3::new(row, 0.0, 0.0);
            a[k] = 1.0;
            nm += a * a.transpose();
            b += a * obs;
        }
    }
    let sol = nm.try_inverse()? * b;
    let cand = ConstrainedAffine {
        rotation: crate::photogrammetry::model::rotation::from_rows(r1, r2),
        m: sol[0],
        a4: sol[1],
        a8: sol[2],
    };
    // Not refined: with noisy approximations the refinement slides back to the original root; the
    // network decides (see `choose_mirrors` in the adjustment).
    let (r, center, _) = refine_image(&cand, pts, xy, c, 0)?;
    let angle = (r.row(2).dot(&rot.row(2))).clamp(-1.0, 1.0).acos();
    (angle > 1e-3).then_some((r, center))
}

/// Unit normal of the best-fit plane of the points.
fn plane_normal(pts: &[Vector3<f64>]) -> Option<Vector3<f64>> {
    let n = pts.len() as f64;
    let centroid = pts.iter().fold(Vector3::zeros(), |a, p| a + p) / n;
    let mut cov = Matrix3::zeros();
    for p in pts {
        let d = p - centroid;
        cov += d * d.transpose();
    }
    let eig = cov.symmetric_eigen();
    let k = eig.eigenvalues.imin();
    eig.eigenvectors.column(k).into_owned().try_normalize(1e-12)
}

/// Misfit (mm) of an observed image point against collinearity, eq (2).
fn misfit(
    rot: &Matrix3<f64>,
    center: &Vector3<f64>,
    c: f64,
    p: &Vector3<f64>,
    o: &[f64; 2],
) -> f64 {
    let d = (p - center).transpose();
    let w = rot.row(2).dot(&d);
    let x = -c * rot.row(0).dot(&d) / w;
    let y = -c * rot.row(1).dot(&d) / w;
    ((o[0] - x).powi(2) + (o[1] - y).powi(2)).sqrt()
}

/// Known points of an image beyond which the resection for the start uses an evenly spaced subset
/// (the start needs a good orientation, not the best one: the adjustment refines it). Keeps the
/// start of networks with thousands of points per image from costing more than their adjustment.
pub const RESECTION_MAX_POINTS: usize = 100;

/// Resection of one image from its known points (rotation, centre, and the indices of the observations
/// left out), robust to a few gross misfits: the worst point is left out while it misfits by more than
/// eight robust σ and more than five points remain.
pub fn resect_image(
    im: &StartImage,
    known: &[Option<Vector3<f64>>],
) -> Result<Resection, AdjustError> {
    let mut used: Vec<(Vector3<f64>, [f64; 2], usize)> = im
        .observations
        .iter()
        .enumerate()
        .filter_map(|(k, (p, xy))| known[*p].map(|x| (x, *xy, k)))
        .collect();
    let mut removed = Vec::new();
    if used.len() < 4 {
        return Err(AdjustError::TooFewKnownPoints {
            image: im.id.clone(),
            known: used.len(),
        });
    }
    if used.len() > RESECTION_MAX_POINTS {
        // An evenly spaced subset determines a start orientation as well as all of them would.
        let step = used.len().div_ceil(RESECTION_MAX_POINTS);
        used = used.into_iter().step_by(step).collect();
    }
    loop {
        let pts: Vec<Vector3<f64>> = used.iter().map(|u| u.0).collect();
        let xy: Vec<[f64; 2]> = used.iter().map(|u| u.1).collect();
        let fits = fit_orientation(&pts, &xy, im.c);
        let mirror = fits
            .first()
            .and_then(|best| mirror_fit(&best.0, &pts, &xy, im.c))
            .or_else(|| fits.get(1).map(|f| (f.0, f.1)));
        let Some(&(rot, center, _)) = fits.first() else {
            return Err(AdjustError::NoStart {
                image: im.id.clone(),
                reason: "the known points are degenerate (collinear or coincident) for a resection"
                    .into(),
            });
        };
        if used.len() <= 5 {
            return Ok(Resection {
                rotation: rot,
                center,
                mirror,
                removed,
            });
        }
        let res: Vec<f64> = (0..used.len())
            .map(|k| misfit(&rot, &center, im.c, &pts[k], &xy[k]))
            .collect();
        let scale = robust_scale(&res);
        let (worst, &max) = res
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(b.1))
            .expect("non-empty");
        if max > 8.0 * scale && max > 1e-9 {
            removed.push(used.remove(worst).2);
        } else {
            return Ok(Resection {
                rotation: rot,
                center,
                mirror,
                removed,
            });
        }
    }
}

/// 1.4826 × median of absolute values: a robust σ.
pub fn robust_scale(values: &[f64]) -> f64 {
    if values.is_empty() {
        return 0.0;
    }
    let mut v: Vec<f64> = values.iter().map(|x| x.abs()).collect();
    v.sort_by(f64::total_cmp);
    1.4826 * v[v.len() / 2]
}

/// Start values for all images and points. `known` holds the coordinates (m, centred site frame) of
/// points with control, approximate or prior coordinates; every image needs four of them. Points
/// without known coordinates are intersected. (Alternating resection and intersection over all points
/// was tried and dropped: at long range it shrinks the convergence angles toward a degenerate network.)
pub fn start_values(
    images: &[StartImage],
    known: &[Option<Vector3<f64>>],
) -> Result<StartValues, AdjustError> {
    let mut rotations = Vec::new();
    let mut centers = Vec::new();
    let mut suspects: Vec<(usize, usize)> = Vec::new();
    let mut mirrors = Vec::new();
    for (i, im) in images.iter().enumerate() {
        let res = resect_image(im, known)?;
        rotations.push(res.rotation);
        centers.push(res.center);
        mirrors.push(res.mirror);
        suspects.extend(res.removed.into_iter().map(|k| (i, k)));
    }
    suspects.sort_unstable();
    // Observations per point (image, index in the image), for the intersections.
    let mut seen_by: Vec<Vec<(usize, usize)>> = vec![Vec::new(); known.len()];
    for (i, im) in images.iter().enumerate() {
        for (k, (p, _)) in im.observations.iter().enumerate() {
            seen_by[*p].push((i, k));
        }
    }
    let ray = |i: usize, k: usize| {
        let xy = images[i].observations[k].1;
        let d = rotations[i].transpose() * Vector3::new(xy[0], xy[1], -images[i].c);
        (centers[i], d.normalize())
    };
    let mut points = Vec::with_capacity(known.len());
    for (p, k) in known.iter().enumerate() {
        let kept = |ik: &&(usize, usize)| suspects.binary_search(ik).is_err();
        if let Some(k) = k {
            // A known point that misfit nearly every resection (a target moved since its
            // coordinates were taken) would start with fewer than two observations, and its
            // normal block would be empty: its known coordinates are the outlier, not its
            // observations. It starts from the intersection of all its rays, observations active.
            let seen = seen_by[p].len();
            if seen >= 2 && seen_by[p].iter().filter(kept).count() < 2 {
                let all: Vec<_> = seen_by[p].iter().map(|&(i, k)| ray(i, k)).collect();
                if let Some(x) = intersect_rays(&all) {
                    suspects.retain(|ik| !seen_by[p].contains(ik));
                    points.push(x);
                    continue;
                }
            }
            points.push(*k);
            continue;
        }
        let rays: Vec<_> = seen_by[p]
            .iter()
            .filter(kept)
            .map(|&(i, k)| ray(i, k))
            .collect();
        points.push(intersect_rays(&rays).unwrap_or_else(Vector3::zeros));
    }
    Ok(StartValues {
        rotations,
        centers,
        points,
        suspects,
        mirrors,
    })
}
