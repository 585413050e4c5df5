//! Rotations: Rodrigues' formula, small-angle perturbation for the adjustment, and the nearest pair of
//! orthogonal rows of equal length (constraints (10)–(11) of the orthogonal projection model).

use nalgebra::{Matrix2x3, Matrix3, Vector3};

use super::dual::Scalar;

/// Rotation matrix of the rotation vector `omega` (axis × angle in rad), Rodrigues' formula.
pub fn rodrigues(omega: Vector3<f64>) -> Matrix3<f64> {
    let theta = omega.norm();
    let k = if theta > 0.0 {
        omega / theta
    } else {
        Vector3::zeros()
    };
    let kx = k.cross_matrix();
    Matrix3::identity() + kx * theta.sin() + kx * kx * (1.0 - theta.cos())
}

/// Applies the adjustment's rotation update: `R ← exp([δ]×) R` (the convention of [`perturbed`]).
pub fn update(r: &Matrix3<f64>, delta: Vector3<f64>) -> Matrix3<f64> {
    let out = rodrigues(delta) * r;
    // Both factors are rotations, so the product is one to rounding; one Newton–Schulz step of the
    // polar decomposition, R (3I − RᵀR) / 2, takes the rounding drift of many iterations back
    // (quadratically: an error ε in RᵀR becomes O(ε²)) at the cost of two 3 × 3 products, where an
    // SVD took 25 times more.
    out * (Matrix3::identity() * 3.0 - out.transpose() * out) * 0.5
}

/// `(I + [δ]×) R0` as rows of generic scalars: equal to `exp([δ]×) R0` to first order, which is all the
/// Jacobian needs at δ = 0.
pub fn perturbed<T: Scalar>(r0: &Matrix3<f64>, delta: [T; 3]) -> [[T; 3]; 3] {
    let mut out = [[T::from(0.0); 3]; 3];
    for col in 0..3 {
        let v = [
            T::from(r0[(0, col)]),
            T::from(r0[(1, col)]),
            T::from(r0[(2, col)]),
        ];
        // δ × v
        let cross = [
            delta[1] * v[2] - delta[2] * v[1],
            delta[2] * v[0] - delta[0] * v[2],
            delta[0] * v[1] - delta[1] * v[0],
        ];
        for row in 0..3 {
            out[row][col] = v[row] + cross[row];
        }
    }
    out
}

/// The nearest pair of orthonormal rows (polar factor of the 2 × 3 matrix `[a; b]`) and the common
/// length m: enforces eqs (10) `a·b = 0` and (11) `|a| = |b|` on affine rows. Returns (r1, r2, m).
pub fn orthonormal_rows(
    a: Vector3<f64>,
    b: Vector3<f64>,
) -> Option<(Vector3<f64>, Vector3<f64>, f64)> {
    if !(a.iter().chain(b.iter()).all(|v| v.is_finite())) {
        return None;
    }
    let m = Matrix2x3::from_rows(&[a.transpose(), b.transpose()]);
    let svd = m.try_svd(true, true, f64::EPSILON, 200)?;
    let u = svd.u?;
    let v_t = svd.v_t?;
    let q = u * v_t;
    let scale = 0.5 * (svd.singular_values[0] + svd.singular_values[1]);
    if !(scale.is_finite() && scale > 0.0) {
        return None;
    }
    let r1 = Vector3::new(q[(0, 0)], q[(0, 1)], q[(0, 2)]);
    let r2 = Vector3::new(q[(1, 0)], q[(1, 1)], q[(1, 2)]);
    Some((r1, r2, scale))
}

/// The rotation with rows r1, r2, r3 = r1 × r2 (a proper rotation; eqs 12–14 pick this root).
pub fn from_rows(r1: Vector3<f64>, r2: Vector3<f64>) -> Matrix3<f64> {
    let r3 = r1.cross(&r2);
    Matrix3::from_rows(&[r1.transpose(), r2.transpose(), r3.transpose()])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rodrigues_is_a_proper_rotation_about_its_axis() {
        let omega = Vector3::new(0.3, -0.2, 0.9);
        let r = rodrigues(omega);
        assert!((r * r.transpose() - Matrix3::identity()).norm() < 1e-14);
        assert!((r.determinant() - 1.0).abs() < 1e-14);
        assert!((r * omega - omega).norm() < 1e-14);
    }

    /// Ten thousand updates stay a rotation, and the same rotation as their product.
    #[test]
    fn many_updates_stay_orthonormal() {
        let mut r = rodrigues(Vector3::new(0.2, -1.1, 0.4));
        let mut composed = r;
        for k in 0..10_000 {
            let delta = Vector3::new(1e-3 * (k % 7) as f64, -2e-3, 5e-4 * (k % 3) as f64);
            r = update(&r, delta);
            composed = rodrigues(delta) * composed;
        }
        assert!((r * r.transpose() - Matrix3::identity()).norm() < 1e-14);
        assert!((r.determinant() - 1.0).abs() < 1e-14);
        assert!((r - composed).norm() < 1e-11);
        // A perturbed start is pulled back to a rotation in one step.
        let mut off = rodrigues(Vector3::new(0.3, 0.1, -0.2));
        off[(0, 1)] += 1e-7;
        let back = update(&off, Vector3::zeros());
        assert!((back * back.transpose() - Matrix3::identity()).norm() < 1e-13);
    }

    #[test]
    fn orthonormal_rows_recover_a_scaled_rotation() {
        let r = rodrigues(Vector3::new(0.1, 0.7, -0.4));
        let a = 3.0 * r.row(0).transpose() + Vector3::new(1e-3, 0.0, 0.0);
        let b = 3.0 * r.row(1).transpose();
        let (r1, r2, m) = orthonormal_rows(a, b).unwrap();
        assert!((m - 3.0).abs() < 1e-3);
        assert!(r1.dot(&r2).abs() < 1e-14);
        assert!((r1.norm() - 1.0).abs() < 1e-14 && (r2.norm() - 1.0).abs() < 1e-14);
        assert!((r1 - r.row(0).transpose()).norm() < 1e-3);
    }
}
