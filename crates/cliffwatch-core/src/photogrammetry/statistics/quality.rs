//! Quality indexes of the paper (§4.1): RMSE of adjusted points against true or check points after a
//! 7-parameter similarity (Helmert) fit ("index 3") and after a 12-parameter 3-D affine fit ("index 4").
//!
//! Coordinates go in as metres, RMSEs come out as millimetres, `[x, y, z, xyz]` with
//! `xyz = √((x² + y² + z²)/3)` (the paper's convention). Pure functions, typed errors, no panics.
//!
//! The similarity fit is Umeyama's closed form (SVD of the cross-covariance, reflection excluded);
//! the affine fit is linear least squares. Both work on centred coordinates, so site frames with
//! UTM-sized coordinates lose no precision.

use nalgebra::{Matrix3, Vector3};
use thiserror::Error;

/// Why a fit could not be computed.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum QualityError {
    /// The two point lists differ in length.
    #[error("{adjusted} adjusted points but {truth} truth points")]
    LengthMismatch {
        /// Number of adjusted points.
        adjusted: usize,
        /// Number of truth points.
        truth: usize,
    },
    /// Not enough points for the fit.
    #[error("{got} points; the fit needs at least {needed}")]
    TooFewPoints {
        /// Points given.
        got: usize,
        /// Points needed.
        needed: usize,
    },
    /// A coordinate is NaN or infinite.
    #[error("point {index} has a coordinate that is not finite")]
    NotFinite {
        /// Index of the offending point (in either list).
        index: usize,
    },
    /// The points do not determine the transformation (coincident, collinear, or coplanar for the
    /// affine fit).
    #[error("the points do not determine the {0} transformation (degenerate configuration)")]
    Degenerate(&'static str),
}

/// A 3-D similarity (Helmert) transformation `p' = scale · rotation · p + translation`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Similarity {
    /// Scale factor (dimensionless).
    pub scale: f64,
    /// Proper rotation matrix (row-major, determinant +1).
    pub rotation: [[f64; 3]; 3],
    /// Translation in the units of the coordinates (m).
    pub translation: [f64; 3],
}

impl Similarity {
    /// The identity transformation.
    pub fn identity() -> Self {
        Similarity {
            scale: 1.0,
            rotation: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            translation: [0.0; 3],
        }
    }

    /// Transforms a point: `scale · rotation · p + translation` (same units as the input).
    pub fn apply(&self, p: [f64; 3]) -> [f64; 3] {
        let r = &self.rotation;
        let mut out = [0.0; 3];
        for (i, o) in out.iter_mut().enumerate() {
            *o = self.scale * (r[i][0] * p[0] + r[i][1] * p[1] + r[i][2] * p[2])
                + self.translation[i];
        }
        out
    }

    /// Transforms a 3 × 3 covariance of a point (any units²): `scale² · R C Rᵀ`.
    pub fn apply_covariance(&self, c: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
        let r = mat3(&self.rotation);
        let m = r * mat3(c) * r.transpose() * (self.scale * self.scale);
        to_array3(&m)
    }
}

/// A 3-D affine transformation `p' = matrix · p + translation` (12 parameters).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Affine3 {
    /// Linear part (row-major).
    pub matrix: [[f64; 3]; 3],
    /// Translation in the units of the coordinates (m).
    pub translation: [f64; 3],
}

impl Affine3 {
    /// Transforms a point: `matrix · p + translation`.
    pub fn apply(&self, p: [f64; 3]) -> [f64; 3] {
        let a = &self.matrix;
        let mut out = [0.0; 3];
        for (i, o) in out.iter_mut().enumerate() {
            *o = a[i][0] * p[0] + a[i][1] * p[1] + a[i][2] * p[2] + self.translation[i];
        }
        out
    }
}

/// A fit with its residuals `truth − T(adjusted)` per point, in the input units (m).
#[derive(Debug, Clone, PartialEq)]
pub struct Fit<T> {
    /// The fitted transformation (adjusted → truth).
    pub transform: T,
    /// Residual vector per point, `truth − T(adjusted)`, in m.
    pub residuals: Vec<[f64; 3]>,
}

fn mat3(a: &[[f64; 3]; 3]) -> Matrix3<f64> {
    Matrix3::from_fn(|i, j| a[i][j])
}

fn to_array3(m: &Matrix3<f64>) -> [[f64; 3]; 3] {
    let mut out = [[0.0; 3]; 3];
    for (i, row) in out.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = m[(i, j)];
        }
    }
    out
}

fn check(adjusted: &[[f64; 3]], truth: &[[f64; 3]], needed: usize) -> Result<(), QualityError> {
    if adjusted.len() != truth.len() {
        return Err(QualityError::LengthMismatch {
            adjusted: adjusted.len(),
            truth: truth.len(),
        });
    }
    if adjusted.len() < needed {
        return Err(QualityError::TooFewPoints {
            got: adjusted.len(),
            needed,
        });
    }
    for (index, (a, t)) in adjusted.iter().zip(truth).enumerate() {
        if !a.iter().chain(t.iter()).all(|v| v.is_finite()) {
            return Err(QualityError::NotFinite { index });
        }
    }
    Ok(())
}

fn centroid(p: &[[f64; 3]]) -> Vector3<f64> {
    let mut c = Vector3::zeros();
    for q in p {
        c += Vector3::new(q[0], q[1], q[2]);
    }
    c / p.len() as f64
}

fn centred(p: &[[f64; 3]], c: &Vector3<f64>) -> Vec<Vector3<f64>> {
    p.iter()
        .map(|q| Vector3::new(q[0] - c[0], q[1] - c[1], q[2] - c[2]))
        .collect()
}

/// Least-squares similarity fit (Umeyama 1991) of `adjusted` onto `truth` (m): minimises
/// `Σ |truth − (s R adjusted + t)|²`. Needs ≥ 3 non-collinear points.
pub fn fit_similarity(
    adjusted: &[[f64; 3]],
    truth: &[[f64; 3]],
) -> Result<Fit<Similarity>, QualityError> {
    check(adjusted, truth, 3)?;
    let n = adjusted.len() as f64;
    let ca = centroid(adjusted);
    let ct = centroid(truth);
    let a = centred(adjusted, &ca);
    let b = centred(truth, &ct);
    let mut sigma = Matrix3::zeros();
    let mut var_a = 0.0;
    for (ai, bi) in a.iter().zip(&b) {
        sigma += bi * ai.transpose();
        var_a += ai.norm_squared();
    }
    sigma /= n;
    var_a /= n;
    if var_a <= 0.0 || var_a.is_nan() {
        return Err(QualityError::Degenerate("similarity"));
    }
    let svd = sigma.svd(true, true);
    let (Some(u), Some(v_t)) = (svd.u, svd.v_t) else {
        return Err(QualityError::Degenerate("similarity"));
    };
    let mut d = svd.singular_values;
    let mut sv: Vec<f64> = d.iter().copied().collect();
    sv.sort_by(|x, y| y.total_cmp(x));
    // Collinear (or coincident) points: the second singular value vanishes.
    if sv[1].is_nan() || sv[1] <= 1e-12 * sv[0] {
        return Err(QualityError::Degenerate("similarity"));
    }
    let mut s = Matrix3::identity();
    if (u.determinant() * v_t.determinant()) < 0.0 {
        // Flip the axis of the smallest singular value.
        let k = d.imin();
        s[(k, k)] = -1.0;
    }
    let r = u * s * v_t;
    for k in 0..3 {
        d[k] *= s[(k, k)];
    }
    let scale = d.sum() / var_a;
    let t = ct - scale * r * ca;
    let residuals = a
        .iter()
        .zip(&b)
        .map(|(ai, bi)| {
            let e = bi - scale * r * ai;
            [e[0], e[1], e[2]]
        })
        .collect();
    Ok(Fit {
        transform: Similarity {
            scale,
            rotation: to_array3(&r),
            translation: [t[0], t[1], t[2]],
        },
        residuals,
    })
}

/// Least-squares 12-parameter affine fit of `adjusted` onto `truth` (m). Needs ≥ 4 points that are
/// not coplanar.
pub fn fit_affine(adjusted: &[[f64; 3]], truth: &[[f64; 3]]) -> Result<Fit<Affine3>, QualityError> {
    check(adjusted, truth, 4)?;
    let ca = centroid(adjusted);
    let ct = centroid(truth);
    let a = centred(adjusted, &ca);
    let b = centred(truth, &ct);
    // Normal equations on centred coordinates: the translation decouples.
    let mut n = Matrix3::zeros();
    let mut rhs = Matrix3::zeros(); // column k: Σ a · b_k
    for (ai, bi) in a.iter().zip(&b) {
        n += ai * ai.transpose();
        rhs += ai * bi.transpose();
    }
    let eig = n.symmetric_eigen();
    let max = eig.eigenvalues.max();
    let min = eig.eigenvalues.min();
    if !(max > 0.0 && min > 1e-14 * max) {
        return Err(QualityError::Degenerate("affine"));
    }
    let Some(inv) = n.try_inverse() else {
        return Err(QualityError::Degenerate("affine"));
    };
    // Solution X (3×3) with b ≈ Xᵀ a, i.e. matrix = Xᵀ.
    let m = (inv * rhs).transpose();
    let t = ct - m * ca;
    let residuals = a
        .iter()
        .zip(&b)
        .map(|(ai, bi)| {
            let e = bi - m * ai;
            [e[0], e[1], e[2]]
        })
        .collect();
    Ok(Fit {
        transform: Affine3 {
            matrix: to_array3(&m),
            translation: [t[0], t[1], t[2]],
        },
        residuals,
    })
}

/// RMSE per axis of residuals given in m, as `[x, y, z, xyz]` in mm with `xyz = √((x²+y²+z²)/3)`.
pub fn rmse_mm(residuals_m: &[[f64; 3]]) -> [f64; 4] {
    if residuals_m.is_empty() {
        return [0.0; 4];
    }
    let n = residuals_m.len() as f64;
    let mut out = [0.0; 4];
    for k in 0..3 {
        let ss: f64 = residuals_m.iter().map(|r| r[k] * r[k]).sum();
        out[k] = 1000.0 * (ss / n).sqrt();
    }
    out[3] = ((out[0] * out[0] + out[1] * out[1] + out[2] * out[2]) / 3.0).sqrt();
    out
}

/// The paper's index 3: RMSE `[x, y, z, xyz]` in mm of `truth − T(adjusted)` after a least-squares
/// similarity fit; inputs in m, paired by index.
pub fn index3_rmse_mm(adjusted: &[[f64; 3]], truth: &[[f64; 3]]) -> Result<[f64; 4], QualityError> {
    Ok(rmse_mm(&fit_similarity(adjusted, truth)?.residuals))
}

/// The paper's index 4: RMSE `[x, y, z, xyz]` in mm after a least-squares 12-parameter affine fit;
/// inputs in m, paired by index. Fails on coplanar points.
pub fn index4_rmse_mm(adjusted: &[[f64; 3]], truth: &[[f64; 3]]) -> Result<[f64; 4], QualityError> {
    Ok(rmse_mm(&fit_affine(adjusted, truth)?.residuals))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rot(axis: [f64; 3], angle: f64) -> Matrix3<f64> {
        *nalgebra::Rotation3::from_axis_angle(
            &nalgebra::Unit::new_normalize(Vector3::new(axis[0], axis[1], axis[2])),
            angle,
        )
        .matrix()
    }

    fn cloud() -> Vec<[f64; 3]> {
        // Deterministic, non-coplanar.
        (0..15)
            .map(|i| {
                let f = i as f64;
                [
                    (f * 1.7).sin() * 3.0,
                    (f * 0.9).cos() * 2.0 + f * 0.1,
                    (f * 2.3).sin() * 0.8,
                ]
            })
            .collect()
    }

    fn transform(p: &[[f64; 3]], s: f64, r: &Matrix3<f64>, t: [f64; 3]) -> Vec<[f64; 3]> {
        p.iter()
            .map(|q| {
                let v = s * r * Vector3::new(q[0], q[1], q[2]);
                [v[0] + t[0], v[1] + t[1], v[2] + t[2]]
            })
            .collect()
    }

    #[test]
    fn recovers_a_constructed_similarity() {
        let truth = cloud();
        let r = rot([0.3, -1.0, 0.5], 2.1);
        // adjusted = inverse transform of truth; the fit must return the forward one.
        let s = 1.0 / 0.87;
        let adjusted = transform(&truth, s, &r.transpose(), [10.0, -4.0, 2.5]);
        let fit = fit_similarity(&adjusted, &truth).unwrap();
        let back: Vec<_> = adjusted.iter().map(|p| fit.transform.apply(*p)).collect();
        for (b, t) in back.iter().zip(&truth) {
            for k in 0..3 {
                assert!((b[k] - t[k]).abs() < 1e-12, "{b:?} vs {t:?}");
            }
        }
        assert!((fit.transform.scale - 0.87).abs() < 1e-12);
        let rr = mat3(&fit.transform.rotation);
        assert!((rr - r).abs().max() < 1e-12);
        assert!((rr.determinant() - 1.0).abs() < 1e-12);
        let idx = index3_rmse_mm(&adjusted, &truth).unwrap();
        assert!(idx.iter().all(|v| *v < 1e-9), "{idx:?}");
    }

    #[test]
    fn similarity_never_returns_a_reflection() {
        let truth = cloud();
        let mirrored: Vec<_> = truth.iter().map(|p| [-p[0], p[1], p[2]]).collect();
        let fit = fit_similarity(&mirrored, &truth).unwrap();
        assert!((mat3(&fit.transform.rotation).determinant() - 1.0).abs() < 1e-12);
        assert!(rmse_mm(&fit.residuals)[3] > 100.0);
    }

    #[test]
    fn utm_sized_coordinates_keep_precision() {
        let local = cloud();
        let r = rot([0.0, 0.0, 1.0], 0.7);
        let enu = transform(&local, 1.0, &r, [500_000.0, 3_900_000.0, 250.0]);
        // A known 1 mm perturbation of one coordinate survives the fit (no catastrophic loss).
        let mut adjusted = local.clone();
        adjusted[3][2] += 0.001;
        let a = index3_rmse_mm(&adjusted, &local).unwrap();
        let b = index3_rmse_mm(&adjusted, &enu).unwrap();
        assert!((a[3] - b[3]).abs() < 1e-6, "{a:?} {b:?}");
    }

    #[test]
    fn identical_sets_and_the_papers_overall_column() {
        let truth = vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
        ];
        let fit = fit_similarity(&truth, &truth).unwrap();
        assert!((fit.transform.scale - 1.0).abs() < 1e-14);
        assert!(rmse_mm(&fit.residuals).iter().all(|v| *v < 1e-12));
        // The paper's overall column: √((x² + y² + z²)/3).
        let r = rmse_mm(&[[0.0009334, 0.0005566, 0.0022348]]);
        assert!((r[3] - 1.4347).abs() < 1e-4, "{r:?}");
    }

    #[test]
    fn recovers_a_constructed_affine() {
        let truth = cloud();
        let m = Matrix3::new(1.1, 0.2, -0.1, 0.05, 0.9, 0.3, -0.2, 0.1, 1.3);
        let mi = m.try_inverse().unwrap();
        let adjusted = transform(&truth, 1.0, &mi, [3.0, 2.0, 1.0]);
        let fit = fit_affine(&adjusted, &truth).unwrap();
        assert!((mat3(&fit.transform.matrix) - m).abs().max() < 1e-10);
        for (a, t) in adjusted.iter().zip(&truth) {
            let b = fit.transform.apply(*a);
            for k in 0..3 {
                assert!((b[k] - t[k]).abs() < 1e-10);
            }
        }
        assert!(index4_rmse_mm(&adjusted, &truth).unwrap()[3] < 1e-7);
        // An affine distortion is not a similarity: index 3 sees it, index 4 does not.
        assert!(index3_rmse_mm(&adjusted, &truth).unwrap()[3] > 1.0);
    }

    #[test]
    fn index4_never_exceeds_index3() {
        let truth = cloud();
        let noisy: Vec<_> = truth
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let e = 1e-3 * ((i as f64) * 12.9898).sin();
                [p[0] + e, p[1] - 0.5 * e, p[2] + 0.3 * e]
            })
            .collect();
        let i3 = index3_rmse_mm(&noisy, &truth).unwrap();
        let i4 = index4_rmse_mm(&noisy, &truth).unwrap();
        assert!(i4[3] <= i3[3] + 1e-12, "{i3:?} {i4:?}");
        assert!(i3[3] > 0.0);
    }

    #[test]
    fn covariance_rotates_with_the_fit() {
        let r = rot([1.0, 2.0, 3.0], 0.4);
        let sim = Similarity {
            scale: 2.0,
            rotation: to_array3(&r),
            translation: [0.0; 3],
        };
        let c = [[1.0, 0.0, 0.0], [0.0, 4.0, 0.0], [0.0, 0.0, 9.0]];
        let cc = mat3(&sim.apply_covariance(&c));
        assert!((cc.trace() - 4.0 * 14.0).abs() < 1e-12);
        assert_eq!(
            Similarity::identity().apply([1.0, 2.0, 3.0]),
            [1.0, 2.0, 3.0]
        );
    }

    #[test]
    fn bad_input_is_a_typed_error() {
        let p = cloud();
        assert!(matches!(
            index3_rmse_mm(&p[..4], &p[..5]),
            Err(QualityError::LengthMismatch { .. })
        ));
        assert!(matches!(
            index3_rmse_mm(&p[..2], &p[..2]),
            Err(QualityError::TooFewPoints { .. })
        ));
        let mut nan = p.clone();
        nan[1][1] = f64::NAN;
        assert!(matches!(
            index3_rmse_mm(&nan, &p),
            Err(QualityError::NotFinite { index: 1 })
        ));
        let line: Vec<_> = (0..5).map(|i| [i as f64, 2.0 * i as f64, 0.0]).collect();
        assert!(matches!(
            index3_rmse_mm(&line, &line),
            Err(QualityError::Degenerate(_))
        ));
        let plane: Vec<_> = (0..6).map(|i| [i as f64, (i * i) as f64, 0.0]).collect();
        assert!(matches!(
            index4_rmse_mm(&plane, &plane),
            Err(QualityError::Degenerate(_))
        ));
        let same = vec![[1.0, 1.0, 1.0]; 4];
        assert!(index3_rmse_mm(&same, &same).is_err());
    }
}
