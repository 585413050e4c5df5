//! Small linear algebra shared by the analysis: a symmetric matrix's inverse and rank, and a
//! displacement's length with its σ.

use nalgebra::{DMatrix, Matrix3, Vector3};

/// Eigenvalues of a symmetric matrix at or below this share of its largest count as zero
/// ([`sym_inverse`]'s pseudo-inverse, and the directions it leaves without weight).
pub(crate) const NULL_RELATIVE: f64 = 1e-12;

/// Inverse of a symmetric matrix and its rank: Cholesky when positive definite, else the eigen
/// pseudo-inverse (eigenvalues at or below [`NULL_RELATIVE`] × the largest count as zero).
pub(crate) fn sym_inverse(s: &DMatrix<f64>) -> Option<(DMatrix<f64>, usize)> {
    if s.nrows() == 0 {
        return Some((s.clone(), 0));
    }
    if let Some(ch) = s.clone().cholesky() {
        return Some((ch.inverse(), s.nrows()));
    }
    let eig = s.clone().symmetric_eigen();
    let max = eig.eigenvalues.iter().cloned().fold(0.0, f64::max);
    if !(max > 0.0) {
        return None;
    }
    let mut rank = 0;
    let inv_vals = eig.eigenvalues.map(|l| {
        if l > NULL_RELATIVE * max {
            rank += 1;
            1.0 / l
        } else {
            0.0
        }
    });
    let v = &eig.eigenvectors;
    Some((v * DMatrix::from_diagonal(&inv_vals) * v.transpose(), rank))
}

/// σ of the 3-D length of `d` (mm) given its covariance (mm²).
pub(crate) fn sigma_length(d: &Vector3<f64>, cov: &Matrix3<f64>) -> f64 {
    let n = d.norm();
    if n < 1e-9 {
        return (cov.trace() / 3.0).max(0.0).sqrt();
    }
    let u = d / n;
    (u.transpose() * cov * u)[(0, 0)].max(0.0).sqrt()
}

/// Length of a displacement and its linearised σ (mm).
pub(super) fn length_of(d: &Vector3<f64>, cov: &Matrix3<f64>) -> (f64, f64) {
    (d.norm(), sigma_length(d, cov))
}
