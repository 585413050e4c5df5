//! The motion of a rigid block from its points' displacements (the rigid-body model of deformation
//! analysis, Caspary 1987 §7.2; Niemeier 2008 §12.6): `d_i = t + ω × (x_i − c)`, with `t` the
//! translation at the block's centroid `c` (mm), `ω` small rotations (mrad = mm/m) and `x_i` the
//! points' reference positions (m). Estimated by generalised least squares with the joint
//! covariance of the points' displacements ([`estimate_block_correlated`]: the datum and the
//! reference epoch put errors common to all points, which do not average out), or with each
//! point's 3 × 3 covariance alone ([`estimate_block`]).
//! With fewer than three points, or points on a line, only the translation is estimated (the
//! weighted mean). The residuals' χ² test says whether the points move as one block.

use nalgebra::{DMatrix, DVector, Matrix3, Vector3};
use serde::{Deserialize, Serialize};

use super::error::AnalysisError;
use super::stats::f_quantile;

/// One member point: reference position (m), displacement (mm) and its covariance (mm²).
#[derive(Debug, Clone, PartialEq)]
pub struct BlockPoint {
    /// Point name.
    pub name: String,
    /// Reference position in the site frame, m.
    pub xyz_m: [f64; 3],
    /// Displacement in mm.
    pub d_mm: [f64; 3],
    /// Covariance of the displacement in mm².
    pub cov_mm2: [[f64; 3]; 3],
}

/// Which motion model was estimated.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BlockModel {
    /// Translation and three small rotations (≥ 3 points, not on a line).
    Rigid,
    /// Translation only.
    Translation,
}

/// The estimated motion of a block.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BlockMotion {
    /// The model estimated.
    pub model: BlockModel,
    /// Member points used.
    pub points: Vec<String>,
    /// Translation at the block's centroid, mm.
    pub translation_mm: [f64; 3],
    /// Covariance of the translation, mm².
    pub covariance_mm2: [[f64; 3]; 3],
    /// Small rotations about X, Y, Z in mrad (rigid model only).
    pub rotation_mrad: Option<[f64; 3]>,
    /// σ of the rotations in mrad.
    pub sigma_rotation_mrad: Option<[f64; 3]>,
    /// Weighted sum of squared residuals vᵀPv.
    pub test_statistic: f64,
    /// Redundancy (3n − parameters).
    pub redundancy: usize,
    /// The residuals pass the χ² test at the confidence given: the points move as one block.
    pub rigid: bool,
}

impl BlockMotion {
    /// The translation along a direction (normalised here; an unusable one gives zeros) and its
    /// σ, mm.
    pub fn along(&self, direction: [f64; 3]) -> (f64, f64) {
        let u = super::unit_direction(direction).unwrap_or_else(Vector3::zeros);
        let c = Matrix3::from(self.covariance_mm2);
        (
            u.dot(&Vector3::from(self.translation_mm)),
            (u.transpose() * c * u)[(0, 0)].max(0.0).sqrt(),
        )
    }

    /// 3-D length of the translation and its linearised σ, mm.
    pub fn length(&self) -> (f64, f64) {
        let t = Vector3::from(self.translation_mm);
        super::linalg::length_of(&t, &Matrix3::from(self.covariance_mm2))
    }
}

/// Estimates the block's motion from its points taken as uncorrelated; `confidence` is that of
/// the rigidity test.
///
/// Errors: no point, a non-finite value or a covariance that is not positive definite (the point
/// is named), or normal equations that cannot be inverted.
pub fn estimate_block(
    points: &[BlockPoint],
    confidence: f64,
) -> Result<BlockMotion, AnalysisError> {
    check_points(points)?;
    let mut weight = DMatrix::<f64>::zeros(3 * points.len(), 3 * points.len());
    for (k, p) in points.iter().enumerate() {
        let inv = Matrix3::from(p.cov_mm2)
            .cholesky()
            .map(|ch| ch.inverse())
            .ok_or_else(|| AnalysisError::Singular {
                what: format!("displacement covariance of block point {}", p.name),
            })?;
        weight.view_mut((3 * k, 3 * k), (3, 3)).copy_from(&inv);
    }
    solve(points, &weight, confidence)
}

/// The motion of a block at the reference epoch: zero and exactly known. The reference epoch's
/// own displacements are zero with zero covariance, which leave the estimate's weights undefined;
/// the model and redundancy are those [`estimate_block`] gives the same points.
///
/// Errors: no point, or a non-finite value.
pub fn at_rest(points: &[BlockPoint]) -> Result<BlockMotion, AnalysisError> {
    check_points(points)?;
    let u = design(points).ncols();
    let rigid = u == 6;
    Ok(BlockMotion {
        model: if rigid {
            BlockModel::Rigid
        } else {
            BlockModel::Translation
        },
        points: points.iter().map(|p| p.name.clone()).collect(),
        translation_mm: [0.0; 3],
        covariance_mm2: [[0.0; 3]; 3],
        rotation_mrad: rigid.then_some([0.0; 3]),
        sigma_rotation_mrad: rigid.then_some([0.0; 3]),
        test_statistic: 0.0,
        redundancy: 3 * points.len() - u,
        rigid: true,
    })
}

/// Estimates the block's motion with the joint covariance of its points' displacements
/// (`joint_mm2`, 3n × 3n in the order of `points`; the cross-covariances the datum and the
/// epochs put between them): generalised least squares, so the translation's covariance keeps
/// the errors common to the points (the datum's, the reference epoch's) that a per-point
/// weighting would average away. The points' own `cov_mm2` are not read.
///
/// Errors: no point, a non-finite value, a joint covariance of the wrong size or not positive
/// definite, or normal equations that cannot be inverted.
pub fn estimate_block_correlated(
    points: &[BlockPoint],
    joint_mm2: &DMatrix<f64>,
    confidence: f64,
) -> Result<BlockMotion, AnalysisError> {
    check_points(points)?;
    let n = 3 * points.len();
    if joint_mm2.shape() != (n, n) || !joint_mm2.iter().all(|v| v.is_finite()) {
        return Err(AnalysisError::InvalidInput(format!(
            "the joint covariance of a block of {} points must be a finite {n} × {n} matrix",
            points.len()
        )));
    }
    let weight = joint_mm2
        .clone()
        .cholesky()
        .map(|ch| ch.inverse())
        .ok_or_else(|| AnalysisError::Singular {
            what: format!(
                "joint displacement covariance of block points {}",
                points
                    .iter()
                    .map(|p| p.name.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        })?;
    solve(points, &weight, confidence)
}

/// The covariance (mm²) of the translation that [`estimate_block_correlated`] with `joint_mm2`
/// estimates, due to errors of covariance `part_mm2` alone (3n × 3n, e.g. the reference epoch's
/// share of `joint_mm2`): `K part Kᵀ` with the estimator's gain `K = (AᵀWA)⁻¹AᵀW`. None when the
/// sizes do not match or `joint_mm2` or the normal equations cannot be inverted.
pub fn translation_share(
    points: &[BlockPoint],
    joint_mm2: &DMatrix<f64>,
    part_mm2: &DMatrix<f64>,
) -> Option<Matrix3<f64>> {
    let n = 3 * points.len();
    if points.is_empty() || joint_mm2.shape() != (n, n) || part_mm2.shape() != (n, n) {
        return None;
    }
    let weight = joint_mm2.clone().cholesky()?.inverse();
    let a = design(points);
    let at_w = a.transpose() * &weight;
    let gain = (&at_w * &a).cholesky()?.inverse() * at_w;
    let share = &gain * part_mm2 * gain.transpose();
    Some(Matrix3::from_fn(|r, c| share[(r, c)]))
}

/// Every point's position, displacement and covariance finite; at least one point.
fn check_points(points: &[BlockPoint]) -> Result<(), AnalysisError> {
    if points.is_empty() {
        return Err(AnalysisError::InvalidInput(
            "a block needs at least one point".into(),
        ));
    }
    for p in points {
        if !p
            .xyz_m
            .iter()
            .chain(&p.d_mm)
            .chain(p.cov_mm2.iter().flatten())
            .all(|v| v.is_finite())
        {
            return Err(AnalysisError::NonFinite {
                what: format!("block point {}", p.name),
            });
        }
    }
    Ok(())
}

/// The design matrix (3n × u) of the rigid-body model `d_i = t + ω × r_i = t − [r_i]× ω` (ω in
/// mrad = mm/m, r_i in m from the centroid; u = 6), or of the translation alone (u = 3) with
/// fewer than three points or points on a line.
fn design(points: &[BlockPoint]) -> DMatrix<f64> {
    let n = points.len() as f64;
    let centroid = points
        .iter()
        .fold(Vector3::zeros(), |a, p| a + Vector3::from(p.xyz_m))
        / n;
    let arms: Vec<Vector3<f64>> = points
        .iter()
        .map(|p| Vector3::from(p.xyz_m) - centroid)
        .collect();
    // Rigid only when the arms span a plane: the second singular value of the arms is not tiny.
    let spread = DMatrix::from_fn(arms.len(), 3, |r, c| arms[r][c]);
    let sv = spread.singular_values();
    let mut s: Vec<f64> = sv.iter().copied().collect();
    s.sort_by(|a, b| b.total_cmp(a));
    let rigid_model =
        points.len() >= 3 && s.len() >= 2 && s[1] > 1e-3 * s[0].max(1e-9) && s[1] > 1e-4;
    let u = if rigid_model { 6 } else { 3 };
    let mut a = DMatrix::<f64>::zeros(3 * points.len(), u);
    for (k, arm) in arms.iter().enumerate() {
        for r in 0..3 {
            a[(3 * k + r, r)] = 1.0;
        }
        if u == 6 {
            let cross = Matrix3::new(0.0, -arm.z, arm.y, arm.z, 0.0, -arm.x, -arm.y, arm.x, 0.0);
            for r in 0..3 {
                for c in 0..3 {
                    a[(3 * k + r, 3 + c)] = -cross[(r, c)];
                }
            }
        }
    }
    a
}

/// Weighted least squares of the rigid-body model (or the translation alone) with the weight
/// matrix `weight` (3n × 3n, the inverse of the displacements' covariance).
fn solve(
    points: &[BlockPoint],
    weight: &DMatrix<f64>,
    confidence: f64,
) -> Result<BlockMotion, AnalysisError> {
    let a = design(points);
    let u = a.ncols();
    let d = DVector::from_iterator(
        3 * points.len(),
        points.iter().flat_map(|p| p.d_mm.iter().copied()),
    );
    let at_w = a.transpose() * weight;
    let qxx = (&at_w * &a)
        .cholesky()
        .map(|c| c.inverse())
        .ok_or_else(|| AnalysisError::Singular {
            what: "normal equations of the block motion".into(),
        })?;
    let x = &qxx * (&at_w * &d);
    let v = &a * &x - &d;
    let vtpv = (v.transpose() * weight * &v)[(0, 0)];
    let redundancy = 3 * points.len() - u;
    let rigid = redundancy == 0
        || vtpv <= redundancy as f64 * f_quantile(confidence, redundancy as f64, f64::INFINITY);
    let cov = Matrix3::from_fn(|r, c| qxx[(r, c)]);
    Ok(BlockMotion {
        model: if u == 6 {
            BlockModel::Rigid
        } else {
            BlockModel::Translation
        },
        points: points.iter().map(|p| p.name.clone()).collect(),
        translation_mm: [x[0], x[1], x[2]],
        covariance_mm2: cov.into(),
        rotation_mrad: (u == 6).then(|| [x[3], x[4], x[5]]),
        sigma_rotation_mrad: (u == 6).then(|| {
            [
                qxx[(3, 3)].max(0.0).sqrt(),
                qxx[(4, 4)].max(0.0).sqrt(),
                qxx[(5, 5)].max(0.0).sqrt(),
            ]
        }),
        test_statistic: vtpv,
        redundancy,
        rigid,
    })
}
