//! The adjusted epoch in the site frame, once the solution stands: the free network's datum
//! (the similarity onto the start coordinates, i.e. inner constraints), the points with their
//! covariance scaled by the variance factor, the joint covariance asked for, the calibrated
//! cameras, the images' orientations, the residuals, and the contract's report.

use nalgebra::{Matrix3, Vector3};

use super::options::AdjustOptions;
use super::prepare::Datum;
use super::report::{
    AdjustmentReport, CalibratedParameter, CameraReport, DroppedObservation, ImageReport,
    PointReport, ResidualReport, VarianceModel,
};
use super::result::{AdjustedPoint, Adjustment, ImageOrientation, JointCovariance};
use crate::photogrammetry::error::AdjustError;
use crate::photogrammetry::input::epoch::EpochProblem;
use crate::photogrammetry::model::bundle::Bundle;
use crate::photogrammetry::model::camera::{Camera, INTERIOR_NAMES};
use crate::photogrammetry::model::central::CentralImage;
use crate::photogrammetry::model::frame::{similarity_fit, Similarity, WorkingFrame};
use crate::photogrammetry::model::orthogonal::OrthoImage;
use crate::photogrammetry::model::Model;
use crate::photogrammetry::solve::lm::LmOutcome;
use crate::photogrammetry::statistics::design::design_statistics;
use crate::photogrammetry::statistics::precision::Cofactors;
use crate::photogrammetry::statistics::variance_components::per_camera;
use crate::photogrammetry::statistics::variance_factor::{chi2_upper, GLOBAL_TEST_Z};

/// What the solution left for the result: the final bundle in the working frame, its cofactors
/// and the solver's outcome, with the problem and the bookkeeping of the run.
pub(super) struct Solution<'a> {
    /// The validated epoch.
    pub problem: &'a EpochProblem,
    /// The options of the run (the joint covariance's points).
    pub options: &'a AdjustOptions,
    /// The solved bundle, in the working frame.
    pub bundle: Bundle,
    /// The working frame of the solution.
    pub frame: WorkingFrame,
    /// Cofactors of the solution (unscaled by the variance factor).
    pub cof: Cofactors,
    /// The solver's outcome (convergence, iterations, cost = vᵀPv).
    pub outcome: LmOutcome,
    /// Degrees of freedom (observations − unknowns + datum defect).
    pub dof: i64,
    /// Free network or control points.
    pub datum: Datum,
    /// Warnings of the run so far.
    pub warnings: Vec<String>,
    /// Observations dropped by data snooping.
    pub dropped: Vec<DroppedObservation>,
    /// Normalized residuals (w_x, w_y) of every observation.
    pub w: Vec<[f64; 2]>,
    /// The variance the snooping's statistics rest on.
    pub variance_model: VarianceModel,
    /// The start coordinates in the working frame (m): the free network's datum.
    pub start_points: &'a [Vector3<f64>],
}

/// From the working frame to the site frame: the datum similarity (free network) then the frame's
/// rotation and origin; cofactors become covariances (m²) with the variance factor.
struct ToSite<'a> {
    frame: &'a WorkingFrame,
    sim: Option<Similarity>,
    variance_factor: f64,
}

impl ToSite<'_> {
    /// A point (m) in the site frame.
    fn point(&self, x: &Vector3<f64>) -> Vector3<f64> {
        self.frame.to_site(self.sim.map_or(*x, |s| s.apply(x)))
    }

    /// A 3 × 3 cofactor block of the working frame as a covariance in site axes (m²).
    fn covariance(&self, q: Matrix3<f64>) -> Matrix3<f64> {
        let (r, s) = self
            .sim
            .map_or((Matrix3::identity(), 1.0), |s| (s.rotation, s.scale));
        self.frame
            .covariance_to_site(&(r * q * r.transpose() * (s * s) * self.variance_factor))
    }

    /// A camera rotation (camera = R (X − Xo)) of the working frame in site axes.
    fn rotation(&self, r_w: &Matrix3<f64>) -> Matrix3<f64> {
        let r = self.sim.map_or(Matrix3::identity(), |s| s.rotation);
        self.frame.rotation_to_site(&(r_w * r.transpose()))
    }
}

/// How far (a factor either way) σ0 may lie from the a-priori σ before the report says so in
/// words: 3, a variance factor beyond 9 or below 1/9, far outside the global test's scatter at
/// [`APRIORI_WARNING_MIN_DOF`] degrees of freedom or more.
pub const APRIORI_WARNING_FACTOR: f64 = 3.0;

/// Fewest degrees of freedom for the a-priori σ warning: fewer leave σ0 too uncertain to judge.
pub const APRIORI_WARNING_MIN_DOF: i64 = 10;

/// A warning, in words a newcomer understands, when the epoch's image coordinates scatter far more
/// or far less than the a-priori σ (`apriori_mm`, the observations' quadratic mean) says: σ0
/// (`sigma0_mm`) beyond [`APRIORI_WARNING_FACTOR`] times it, either way. It does not block: the
/// precisions reported already carry the variance factor.
pub(super) fn apriori_sigma_warning(apriori_mm: f64, sigma0_mm: f64, dof: i64) -> Option<String> {
    if dof < APRIORI_WARNING_MIN_DOF || !(apriori_mm > 0.0 && sigma0_mm.is_finite()) {
        return None;
    }
    let ratio = sigma0_mm / apriori_mm;
    let figures = format!(
        "σ0 {sigma0_mm:.2e} mm against the stated {apriori_mm:.2e} mm (the cameras' or \
         observations' sigma_mm)"
    );
    if ratio >= APRIORI_WARNING_FACTOR {
        Some(format!(
            "the image measurements scatter {ratio:.1} times more than their stated precision \
             ({figures}): that precision is too optimistic, or some measurements are wrong. The \
             coordinates' σ use what this epoch showed; if it repeats, set sigma_mm nearer \
             {sigma0_mm:.2e} mm"
        ))
    } else if ratio <= 1.0 / APRIORI_WARNING_FACTOR {
        Some(format!(
            "the image measurements agree {:.1} times better than their stated precision \
             ({figures}): that precision is too cautious, which weakens the search for wrong \
             measurements and the images' weight against control points. The coordinates' σ \
             use what this epoch showed; set sigma_mm nearer {sigma0_mm:.2e} mm",
            1.0 / ratio
        ))
    } else {
        None
    }
}

/// Precision, datum transformation and the report of a solution. Refuses one that did not
/// converge; a variance factor above the global test's 99.9 % bound is reported as a warning.
pub(super) fn site_result(s: Solution) -> Result<Adjustment, AdjustError> {
    let Solution {
        problem,
        options,
        bundle,
        frame,
        cof,
        outcome,
        dof,
        datum,
        mut warnings,
        dropped,
        w,
        variance_model,
        start_points,
    } = s;
    if !outcome.converged {
        return Err(AdjustError::NoConvergence {
            iterations: outcome.iterations,
            sigma0_mm: problem.reference_sigma_mm() * (outcome.cost / dof as f64).sqrt(),
        });
    }
    let variance_factor = outcome.cost / dof as f64;
    let limit = chi2_upper(dof as f64, GLOBAL_TEST_Z) / dof as f64;
    if variance_factor > limit {
        warnings.push(format!(
            "global test failed: variance factor {variance_factor:.2} exceeds {limit:.2} (99.9 %): the a-priori σ is too optimistic, or a gross or model error remains"
        ));
    }
    let sigma0_mm = problem.reference_sigma_mm() * variance_factor.sqrt();
    if !options.apriori_precision {
        warnings.extend(apriori_sigma_warning(
            problem.reference_sigma_mm(),
            sigma0_mm,
            dof,
        ));
    }
    // The factor the cofactors are scaled by: the a-posteriori variance factor, or 1 (a-priori σ)
    // for a pre-analysis.
    let scale = if options.apriori_precision {
        1.0
    } else {
        variance_factor
    };
    let to_site = ToSite {
        frame: &frame,
        // Free network: the similarity onto the start coordinates gives the inner-constraint datum.
        sim: match datum {
            Datum::Free => similarity_fit(&bundle.points, start_points),
            Datum::Control => None,
        },
        variance_factor: scale,
    };
    let (points, point_reports) = adjusted_points(problem, &bundle, &cof, &to_site);
    let joint_covariance = joint_covariance(problem, options, &cof, &to_site);
    let (cameras, camera_reports) = calibrated_cameras(problem, &bundle, &cof, scale);
    let orientations = orientations(problem, &bundle, &to_site);
    let (residuals, image_reports) = residual_reports(problem, &bundle, &w);
    let variance_components = if options.variance_components {
        let ids: Vec<String> = problem.cameras.iter().map(|c| c.id.clone()).collect();
        per_camera(&bundle, &cof, &ids)
    } else {
        Vec::new()
    };
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
        variance_components,
    };
    let design = options.design_statistics.then(|| {
        let images: Vec<String> = problem.images.iter().map(|i| i.id.clone()).collect();
        let ids: Vec<String> = problem.cameras.iter().map(|c| c.id.clone()).collect();
        design_statistics(&bundle, &cof, &images, &problem.points, &ids)
    });
    Ok(Adjustment {
        report,
        points,
        orientations,
        cameras,
        joint_covariance,
        design,
    })
}

/// Every point in the site frame with its covariance (m²), and its line of the report (σ in mm).
fn adjusted_points(
    problem: &EpochProblem,
    bundle: &Bundle,
    cof: &Cofactors,
    to_site: &ToSite,
) -> (Vec<AdjustedPoint>, Vec<PointReport>) {
    let np = problem.points.len();
    let mut points = Vec::with_capacity(np);
    let mut reports = Vec::with_capacity(np);
    for i in 0..np {
        let xyz = to_site.point(&bundle.points[i]);
        let cov = to_site.covariance(cof.point_block(i, i));
        let sd = |k: usize| cov[(k, k)].max(0.0).sqrt() * 1000.0;
        reports.push(PointReport {
            point: problem.points[i].clone(),
            X: xyz.x,
            Y: xyz.y,
            Z: xyz.z,
            sigma_X_mm: sd(0),
            sigma_Y_mm: sd(1),
            sigma_Z_mm: sd(2),
        });
        points.push(AdjustedPoint {
            name: problem.points[i].clone(),
            xyz: [xyz.x, xyz.y, xyz.z],
            covariance_m2: cov.transpose().into(),
        });
    }
    (points, reports)
}

/// The joint covariance (m², site axes) of the points of
/// [`AdjustOptions::joint_covariance_of`] that the epoch has; None when it has none of them.
fn joint_covariance(
    problem: &EpochProblem,
    options: &AdjustOptions,
    cof: &Cofactors,
    to_site: &ToSite,
) -> Option<JointCovariance> {
    let chosen: Vec<usize> = options
        .joint_covariance_of
        .iter()
        .filter_map(|n| problem.point_index(n))
        .collect();
    if chosen.is_empty() {
        return None;
    }
    let n = chosen.len();
    let d = 3 * n;
    let blocks = cof.point_blocks(&chosen);
    let mut m = vec![0.0; d * d];
    for a in 0..n {
        for b in 0..n {
            let q = to_site.covariance(blocks[a * n + b]);
            for r in 0..3 {
                for s in 0..3 {
                    m[(3 * a + r) * d + 3 * b + s] = q[(r, s)];
                }
            }
        }
    }
    Some(JointCovariance {
        points: chosen.iter().map(|&p| problem.points[p].clone()).collect(),
        matrix_m2: m,
    })
}

/// The cameras with their adjusted interior parameters, and their lines of the report (each
/// calibrated parameter with its σ; c in mm).
fn calibrated_cameras(
    problem: &EpochProblem,
    bundle: &Bundle,
    cof: &Cofactors,
    variance_factor: f64,
) -> (Vec<Camera>, Vec<CameraReport>) {
    let icols = bundle.interior_columns();
    let mut cameras = problem.cameras.clone();
    let mut reports = Vec::new();
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
        reports.push(CameraReport {
            id: cam.id.clone(),
            c_mm: cam.params[0],
            c_sigma_mm: c_sigma,
            calibrated,
        });
    }
    (cameras, reports)
}

/// Each image's rotation and projection centre in the site frame (after the datum similarity).
/// The orthogonal model's centre is placed at the distance its scale and c imply.
fn orientations(
    problem: &EpochProblem,
    bundle: &Bundle,
    to_site: &ToSite,
) -> Vec<ImageOrientation> {
    problem
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
            let xo = to_site.point(&xo_w);
            ImageOrientation {
                image: im.id.clone(),
                station: im.station.clone(),
                camera: problem.cameras[im.camera].id.clone(),
                rotation: to_site.rotation(&r_w).transpose().into(),
                center: [xo.x, xo.y, xo.z],
            }
        })
        .collect()
}

/// Every observation's residual (mm in the image) with its largest |w|, and each image's rms
/// residual over its active observations.
fn residual_reports(
    problem: &EpochProblem,
    bundle: &Bundle,
    w: &[[f64; 2]],
) -> (Vec<ResidualReport>, Vec<ImageReport>) {
    let mut residuals = Vec::with_capacity(bundle.obs.len());
    let mut sums = vec![(0usize, 0.0f64); problem.images.len()];
    for (k, o) in bundle.obs.iter().enumerate() {
        let e = bundle.residual_of(o);
        if o.active {
            sums[o.image].0 += 1;
            sums[o.image].1 += e[0] * e[0] + e[1] * e[1];
        }
        residuals.push(ResidualReport {
            image: problem.images[o.image].id.clone(),
            point: problem.points[o.point].clone(),
            vx_mm: e[0],
            vy_mm: e[1],
            w: w[k][0].abs().max(w[k][1].abs()),
            dropped: !o.active,
        });
    }
    let images = problem
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
    (residuals, images)
}

#[cfg(test)]
mod tests {
    use super::apriori_sigma_warning;

    /// Either direction beyond the factor is named in words; within it, or with too few degrees
    /// of freedom to judge, nothing is said.
    #[test]
    fn the_apriori_sigma_warning_names_the_direction() {
        let optimistic = apriori_sigma_warning(0.001, 0.004, 40).unwrap();
        assert!(
            optimistic.starts_with("the image measurements scatter 4.0 times more")
                && optimistic.contains("too optimistic"),
            "{optimistic}"
        );
        let cautious = apriori_sigma_warning(0.01, 0.001, 40).unwrap();
        assert!(
            cautious.starts_with("the image measurements agree 10.0 times better")
                && cautious.contains("too cautious"),
            "{cautious}"
        );
        assert_eq!(apriori_sigma_warning(0.001, 0.0025, 40), None);
        assert_eq!(apriori_sigma_warning(0.001, 0.0004, 40), None);
        assert_eq!(apriori_sigma_warning(0.001, 0.004, 9), None);
    }
}
