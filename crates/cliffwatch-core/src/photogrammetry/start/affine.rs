//! Affine resection (eqs 1, 5 with (x, y) taken as (x_a, y_a)): the linear first step of the start
//! values, needing only four known points per image and no camera position or angle. Constraints
//! (10)–(11) are then enforced by the nearest orthogonal pair of rows (eqs 12–14 give the rotation).
//!
//! Planar point sets (a flat face, a calibration plate) leave A3/A7 undetermined in the unconstrained
//! fit: the in-plane coefficients are solved and the out-of-plane ones recovered from (10)–(11), which
//! gives two mirror solutions; both are returned and the caller keeps the one the perspective fits.

use nalgebra::{DMatrix, DVector, Matrix3, Vector3};

use crate::photogrammetry::model::rotation::{from_rows, orthonormal_rows};

/// An affine camera `x = a·X + a4`, `y = b·X + a8` (mm; X in m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AffineImage {
    /// (A1, A2, A3).
    pub a: Vector3<f64>,
    /// (A5, A6, A7).
    pub b: Vector3<f64>,
    /// A4 (mm).
    pub a4: f64,
    /// A8 (mm).
    pub a8: f64,
}

/// A start orientation: rotation rows (r1, r2, r3 = r1 × r2), scale m and shifts (mm) after (10)–(11).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ConstrainedAffine {
    /// Rotation with rows r1, r2, r3.
    pub rotation: Matrix3<f64>,
    /// Scale m (mm per m).
    pub m: f64,
    /// A4 (mm).
    pub a4: f64,
    /// A8 (mm).
    pub a8: f64,
}

impl AffineImage {
    /// Predicted image coordinates (mm) of X (m).
    pub fn apply(&self, x: &Vector3<f64>) -> [f64; 2] {
        [self.a.dot(x) + self.a4, self.b.dot(x) + self.a8]
    }

    /// Enforces constraints (10)–(11): nearest orthonormal rows of equal length.
    pub fn constrained(&self) -> Option<ConstrainedAffine> {
        let (r1, r2, m) = orthonormal_rows(self.a, self.b)?;
        Some(ConstrainedAffine {
            rotation: from_rows(r1, r2),
            m,
            a4: self.a4,
            a8: self.a8,
        })
    }
}

/// Singular values (descending) and the right singular vectors of centred points, for the planarity test.
fn principal_axes(points: &[Vector3<f64>]) -> (Vector3<f64>, [Vector3<f64>; 3], [f64; 3]) {
    let n = points.len() as f64;
    let centroid = points.iter().fold(Vector3::zeros(), |a, p| a + p) / n;
    let mut cov = Matrix3::zeros();
    for p in points {
        let d = p - centroid;
        cov += d * d.transpose();
    }
    let eig = cov.symmetric_eigen();
    let mut order = [0usize, 1, 2];
    order.sort_by(|&i, &j| eig.eigenvalues[j].total_cmp(&eig.eigenvalues[i]));
    let axes = order.map(|i| eig.eigenvectors.column(i).into_owned());
    let sv = order.map(|i| eig.eigenvalues[i].max(0.0).sqrt());
    (centroid, axes, sv)
}

/// True when the points are so nearly coplanar (smallest over largest principal spread below `ratio`)
/// that the unconstrained affine resection cannot separate the out-of-plane coefficients.
pub fn is_planar(points: &[Vector3<f64>], ratio: f64) -> bool {
    let (_, _, sv) = principal_axes(points);
    sv[0] <= 0.0 || sv[2] / sv[0] < ratio
}

fn lstsq(a: &DMatrix<f64>, b: &DVector<f64>) -> Option<DVector<f64>> {
    lstsq_pair(a, b, b).map(|(x, _)| x)
}

/// Least-squares solutions of `a x = bx` and `a y = by` from one SVD of `a`; None when `a` is
/// rank-deficient (condition beyond 10¹²) or not finite.
fn lstsq_pair(
    a: &DMatrix<f64>,
    bx: &DVector<f64>,
    by: &DVector<f64>,
) -> Option<(DVector<f64>, DVector<f64>)> {
    if !(a
        .iter()
        .chain(bx.iter())
        .chain(by.iter())
        .all(|v| v.is_finite()))
    {
        return None;
    }
    let svd = a.clone().try_svd(true, true, f64::EPSILON, 200)?;
    let smax = svd.singular_values.max();
    if svd.singular_values.min() <= smax * 1e-12 {
        return None;
    }
    let mut b = DMatrix::zeros(a.nrows(), 2);
    b.set_column(0, bx);
    b.set_column(1, by);
    let x = svd.solve(&b, 0.0).ok()?;
    Some((x.column(0).into_owned(), x.column(1).into_owned()))
}

/// Unconstrained affine resection from ≥ 4 non-coplanar points: linear least squares for A1..A8.
pub fn resect(points: &[Vector3<f64>], xy: &[[f64; 2]]) -> Option<AffineImage> {
    if points.len() < 4 {
        return None;
    }
    let (centroid, _, _) = principal_axes(points);
    let n = points.len();
    let mut a = DMatrix::zeros(n, 4);
    let mut bx = DVector::zeros(n);
    let mut by = DVector::zeros(n);
    for (i, (p, o)) in points.iter().zip(xy).enumerate() {
        let d = p - centroid;
        a.set_row(i, &nalgebra::RowVector4::new(d.x, d.y, d.z, 1.0));
        bx[i] = o[0];
        by[i] = o[1];
    }
    let (sx, sy) = lstsq_pair(&a, &bx, &by)?;
    let av = Vector3::new(sx[0], sx[1], sx[2]);
    let bv = Vector3::new(sy[0], sy[1], sy[2]);
    Some(AffineImage {
        a: av,
        b: bv,
        a4: sx[3] - av.dot(&centroid),
        a8: sy[3] - bv.dot(&centroid),
    })
}

/// How well the data determine the out-of-plane tilt of an affine camera: the larger over the two rows
/// of |γ| / σ(γ), where γ is the coefficient along the normal of the points' best-fit plane in an
/// unconstrained fit. Near zero, the sign of the tilt (the mirror root) is not determined by the image.
pub fn tilt_significance(points: &[Vector3<f64>], xy: &[[f64; 2]]) -> f64 {
    let n = points.len();
    if n < 5 {
        return 0.0;
    }
    let (centroid, axes, _) = principal_axes(points);
    let mut a = DMatrix::zeros(n, 4);
    let mut bx = DVector::zeros(n);
    let mut by = DVector::zeros(n);
    for (i, (p, o)) in points.iter().zip(xy).enumerate() {
        let d = p - centroid;
        a.set_row(
            i,
            &nalgebra::RowVector4::new(d.dot(&axes[0]), d.dot(&axes[1]), d.dot(&axes[2]), 1.0),
        );
        bx[i] = o[0];
        by[i] = o[1];
    }
    let Some(inv) = (a.transpose() * &a).try_inverse() else {
        return 0.0;
    };
    let mut best: f64 = 0.0;
    for b in [&bx, &by] {
        let Some(sol) = lstsq(&a, b) else { return 0.0 };
        let rss = (&a * &sol - b).norm_squared();
        let s2 = rss / (n - 4) as f64;
        let sigma = (s2 * inv[(2, 2)]).sqrt();
        if sigma > 0.0 {
            best = best.max(sol[2].abs() / sigma);
        } else {
            return f64::INFINITY;
        }
    }
    best
}

/// Resection of a (nearly) planar point set: in-plane affine fit, then the out-of-plane components
/// γ1, γ2 of the two rows from (10) `γ1γ2 = −p` and (11) `γ1² − γ2² = q`. Returns the two mirror
/// solutions (already constrained).
pub fn resect_planar(points: &[Vector3<f64>], xy: &[[f64; 2]]) -> Option<[ConstrainedAffine; 2]> {
    if points.len() < 3 {
        return None;
    }
    let (centroid, axes, _) = principal_axes(points);
    let (u, v, nrm) = (axes[0], axes[1], axes[2]);
    let n = points.len();
    let mut a = DMatrix::zeros(n, 3);
    let mut bx = DVector::zeros(n);
    let mut by = DVector::zeros(n);
    for (i, (p, o)) in points.iter().zip(xy).enumerate() {
        let d = p - centroid;
        a.set_row(i, &nalgebra::RowVector3::new(d.dot(&u), d.dot(&v), 1.0));
        bx[i] = o[0];
        by[i] = o[1];
    }
    let (sx, sy) = lstsq_pair(&a, &bx, &by)?;
    let (al1, be1, al2, be2) = (sx[0], sx[1], sy[0], sy[1]);
    let p = al1 * al2 + be1 * be2;
    let q = (al2 * al2 + be2 * be2) - (al1 * al1 + be1 * be1);
    // γ1² = s solves s² − q s − p² = 0 (positive root).
    let s = 0.5 * (q + (q * q + 4.0 * p * p).sqrt());
    let (g1, g2) = if s > 1e-300 {
        let g1 = s.sqrt();
        (g1, -p / g1)
    } else {
        (0.0, (-q).max(0.0).sqrt())
    };
    let make = |sign: f64| -> Option<ConstrainedAffine> {
        let ra = al1 * u + be1 * v + sign * g1 * nrm;
        let rb = al2 * u + be2 * v + sign * g2 * nrm;
        let affine = AffineImage {
            a: ra,
            b: rb,
            a4: sx[2] - ra.dot(&centroid),
            a8: sy[2] - rb.dot(&centroid),
        };
        affine.constrained()
    };
    Some([make(1.0)?, make(-1.0)?])
}

/// Affine intersection: least squares for X from ≥ 2 affine images (2 equations each).
pub fn intersect(cams: &[(AffineImage, [f64; 2])]) -> Option<Vector3<f64>> {
    if cams.len() < 2 {
        return None;
    }
    let mut n = Matrix3::zeros();
    let mut b = Vector3::zeros();
    for (cam, o) in cams {
        n += cam.a * cam.a.transpose() + cam.b * cam.b.transpose();
        b += cam.a * (o[0] - cam.a4) + cam.b * (o[1] - cam.a8);
    }
    n.try_inverse().map(|inv| inv * b)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::photogrammetry::model::rotation::rodrigues;

    fn cloud(planar: bool) -> Vec<Vector3<f64>> {
        (0..8)
            .map(|i| {
                let f = i as f64;
                let z = if planar { 0.0 } else { (f * 1.3).sin() };
                Vector3::new((f * 0.7).cos() * 2.0, (f * 1.1).sin() * 1.5, z)
            })
            .collect()
    }

    #[test]
    fn resection_recovers_an_exact_affine_camera() {
        let r = rodrigues(Vector3::new(0.2, -0.3, 0.1));
        let (m, a4, a8) = (40.0, 1.5, -2.0);
        let pts = cloud(false);
        let xy: Vec<[f64; 2]> = pts
            .iter()
            .map(|p| {
                [
                    m * r.row(0).dot(&p.transpose()) + a4,
                    m * r.row(1).dot(&p.transpose()) + a8,
                ]
            })
            .collect();
        let cam = resect(&pts, &xy).unwrap().constrained().unwrap();
        assert!((cam.m - m).abs() < 1e-9);
        assert!((cam.rotation - r).norm() < 1e-9);
        assert!((cam.a4 - a4).abs() < 1e-9 && (cam.a8 - a8).abs() < 1e-9);
    }

    #[test]
    fn planar_resection_returns_the_true_solution_among_two_mirrors() {
        let r = rodrigues(Vector3::new(0.25, 0.3, -0.2));
        let (m, a4, a8) = (25.0, 0.3, 0.7);
        let pts = cloud(true);
        assert!(is_planar(&pts, 0.03));
        let xy: Vec<[f64; 2]> = pts
            .iter()
            .map(|p| {
                [
                    m * r.row(0).dot(&p.transpose()) + a4,
                    m * r.row(1).dot(&p.transpose()) + a8,
                ]
            })
            .collect();
        let sols = resect_planar(&pts, &xy).unwrap();
        let best = sols
            .iter()
            .map(|s| (s.rotation - r).norm())
            .fold(f64::INFINITY, f64::min);
        assert!(best < 1e-9, "{best}");
        assert!(sols.iter().all(|s| (s.m - m).abs() < 1e-9));
    }
}
