//! The orthogonal projection model of Ono & Hattori in the working frame.
//!
//! Per image the generalized parameters A1..A8 (eqs 1, 5) obey constraints (10) A1A5 + A2A6 + A3A7 = 0
//! and (11) A1² + A2² + A3² = A5² + A6² + A7². The adjustment eliminates both constraints by writing
//! `(A1, A2, A3) = m r1`, `(A5, A6, A7) = m r2` with a rotation R = (r1; r2; r3) and a scale m: six
//! unknowns per image (three rotation increments, m, A4, A8) instead of eight with two Lagrange
//! multipliers. It uses the closed-form forward model (eq 9 inverted), which is exact, so the
//! estimate is rigorous in image space and σ0 is in image mm.

use nalgebra::{Matrix3, Vector3};

use super::dual::Scalar;

/// Exterior parameters of one image in the orthogonal projection model (working frame, m and mm).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OrthoImage {
    /// Rows r1, r2, r3 (eqs 12–14); r3 = r1 × r2.
    pub rotation: Matrix3<f64>,
    /// Scale m = |(A1, A2, A3)| in image mm per object m.
    pub m: f64,
    /// Shift A4 in image mm.
    pub a4: f64,
    /// Shift A8 in image mm.
    pub a8: f64,
}

impl OrthoImage {
    /// The generalized parameters A1..A8 of eq (5) (mm per m for A1–A3, A5–A7; mm for A4, A8).
    pub fn generalized(&self) -> [f64; 8] {
        let r = &self.rotation;
        [
            self.m * r[(0, 0)],
            self.m * r[(0, 1)],
            self.m * r[(0, 2)],
            self.a4,
            self.m * r[(1, 0)],
            self.m * r[(1, 1)],
            self.m * r[(1, 2)],
            self.a8,
        ]
    }

    /// Projection centre Xo (m, working frame) from eqs (6), (12)–(14):
    /// `H = −a33 c / m`, `Zo = Zbar − H`, `r1·Xo = −A4/m`, `r2·Xo = −A8/m`.
    pub fn center(&self, c: f64, zbar: f64) -> Option<Vector3<f64>> {
        let r = &self.rotation;
        let h = -r[(2, 2)] * c / self.m;
        let zo = zbar - h;
        let a = Matrix3::new(
            r[(0, 0)],
            r[(0, 1)],
            r[(0, 2)],
            r[(1, 0)],
            r[(1, 1)],
            r[(1, 2)],
            0.0,
            0.0,
            1.0,
        );
        a.try_inverse()
            .map(|inv| inv * Vector3::new(-self.a4 / self.m, -self.a8 / self.m, zo))
    }

    /// The orthogonal parameters of a central-perspective orientation (inverse of [`OrthoImage::center`]).
    pub fn from_center(rotation: Matrix3<f64>, center: Vector3<f64>, c: f64, zbar: f64) -> Self {
        let zo = center.z;
        let h = zbar - zo;
        let m = -rotation[(2, 2)] * c / h;
        let r1 = rotation.row(0).transpose();
        let r2 = rotation.row(1).transpose();
        OrthoImage {
            rotation,
            m,
            a4: -m * r1.dot(&center),
            a8: -m * r2.dot(&center),
        }
    }
}

/// Closed-form forward model: image coordinates (mm) of the working-frame point `x` (m).
///
/// eq (5): `x_a = m r1·X + A4`, `y_a = m r2·X + A8`; eq (6): `H = −a33 c/m`, `Zo = Zbar − H`;
/// eq (9) inverted: `K = (Z − Zo)/H`, `u = 1 + (a13 x_a + a23 y_a)/(K a33 c)`, `x = x_a/(K u)`,
/// `y = y_a/(K u)`. `K u` is computed as `K + (a13 x_a + a23 y_a)/(a33 c)`, which is the same and
/// stays finite where K passes through zero.
pub fn project<T: Scalar>(
    rot: &[[T; 3]; 3],
    m: T,
    a4: T,
    a8: T,
    c: T,
    zbar: f64,
    x: &[T; 3],
) -> [T; 2] {
    let dot = |r: &[T; 3]| r[0] * x[0] + r[1] * x[1] + r[2] * x[2];
    let xa = m * dot(&rot[0]) + a4;
    let ya = m * dot(&rot[1]) + a8;
    let (a13, a23, a33) = (rot[0][2], rot[1][2], rot[2][2]);
    let h = -(a33 * c) / m;
    let zo = T::from(zbar) - h;
    let k = (x[2] - zo) / h;
    let ku = k + (a13 * xa + a23 * ya) / (a33 * c);
    [xa / ku, ya / ku]
}

/// Columns of [`project_jacobian`]: rotation increments δ (rad, the convention of
/// `super::rotation::perturbed`), m, A4, A8, c, then the point X, Y, Z.
pub const JACOBIAN_COLUMNS: usize = 10;

/// The closed-form forward model (eq 9 inverted, as in [`project`]) and its exact Jacobian, derived by
/// hand for speed: this is the innermost loop of the adjustment. Image coordinates in mm; columns
/// as in [`JACOBIAN_COLUMNS`]. Checked against the dual-number derivatives of [`project`] in the tests.
///
/// Written with `q = R X`, `v = (a13, a23, a33)` (the third column of R) and `g = a33 c`, the model is
/// `x = x_a / D`, `y = y_a / D` with `D = 1 + (a13 x_a + a23 y_a − m (Z − Zbar)) / g`, since
/// `K = 1 − m (Z − Zbar)/g` by eq (6).
pub fn project_jacobian(
    rotation: &Matrix3<f64>,
    m: f64,
    a4: f64,
    a8: f64,
    c: f64,
    zbar: f64,
    x: &Vector3<f64>,
) -> ([f64; 2], [[f64; JACOBIAN_COLUMNS]; 2]) {
    const M: usize = 3;
    const C: usize = 6;
    const X: usize = 7;
    let r = rotation;
    let q = r * x;
    let xa = m * q[0] + a4;
    let ya = m * q[1] + a8;
    let v = [r[(0, 2)], r[(1, 2)], r[(2, 2)]];
    let g = v[2] * c;
    let z = x[2] - zbar;
    let num = v[0] * xa + v[1] * ya - m * z;
    let d = 1.0 + num / g;
    let (fx, fy) = (xa / d, ya / d);
    // d(δ × w)/dδ for w = q (rows of R X) and w = v (third column of R).
    let cross_rows = |w: [f64; 3]| [[0.0, w[2], -w[1]], [-w[2], 0.0, w[0]], [w[1], -w[0], 0.0]];
    let dq = cross_rows([q[0], q[1], q[2]]);
    let dv = cross_rows(v);
    let mut dxa = [0.0; JACOBIAN_COLUMNS];
    let mut dya = [0.0; JACOBIAN_COLUMNS];
    for k in 0..3 {
        dxa[k] = m * dq[0][k];
        dya[k] = m * dq[1][k];
        dxa[X + k] = m * r[(0, k)];
        dya[X + k] = m * r[(1, k)];
    }
    dxa[M] = q[0];
    dya[M] = q[1];
    dxa[M + 1] = 1.0;
    dya[M + 2] = 1.0;
    // dD = (d num − (num/g) dg) / g.
    let ratio = num / g;
    let mut dd = [0.0; JACOBIAN_COLUMNS];
    for k in 0..JACOBIAN_COLUMNS {
        dd[k] = v[0] * dxa[k] + v[1] * dya[k];
    }
    for k in 0..3 {
        dd[k] += dv[0][k] * xa + dv[1][k] * ya - ratio * c * dv[2][k];
    }
    dd[M] -= z;
    dd[X + 2] -= m;
    dd[C] -= ratio * v[2];
    let mut jac = [[0.0; JACOBIAN_COLUMNS]; 2];
    for k in 0..JACOBIAN_COLUMNS {
        let ddk = dd[k] / g;
        jac[0][k] = (dxa[k] - fx * ddk) / d;
        jac[1][k] = (dya[k] - fy * ddk) / d;
    }
    ([fx, fy], jac)
}

#[cfg(test)]
mod tests {
    use super::super::rotation::{perturbed, rodrigues};
    use super::*;

    /// The closed form reproduces collinearity (eq 2) to rounding, as the spec page states.
    #[test]
    fn closed_form_equals_collinearity() {
        let r = rodrigues(Vector3::new(0.05, -0.3, 0.02));
        let xo = Vector3::new(-3.0, 0.5, 10.0);
        let c = 300.0;
        let zbar = 0.12;
        let img = OrthoImage::from_center(r, xo, c, zbar);
        let back = img.center(c, zbar).unwrap();
        assert!((back - xo).norm() < 1e-12);
        let rows = perturbed(&r, [0.0; 3]);
        for p in [[0.1, 0.7, 0.0], [-0.3, 0.1, 0.35], [0.4, 0.15, 0.25]] {
            let d = Vector3::from(p) - xo;
            let w = r.row(2).dot(&d.transpose());
            let x_c = -c * r.row(0).dot(&d.transpose()) / w;
            let y_c = -c * r.row(1).dot(&d.transpose()) / w;
            let [x, y] = project(&rows, img.m, img.a4, img.a8, c, zbar, &p);
            assert!(
                (x - x_c).abs() < 1e-12 && (y - y_c).abs() < 1e-12,
                "{x} {x_c} {y} {y_c}"
            );
        }
    }

    /// The hand-derived Jacobian equals the dual-number derivatives of the same model.
    #[test]
    fn hand_jacobian_equals_dual_numbers() {
        use super::super::dual::Dual;
        for (i, omega) in [[0.05, -0.3, 0.02], [1.2, 0.4, -2.0], [-0.01, 0.02, 3.0]]
            .iter()
            .enumerate()
        {
            let r = rodrigues(Vector3::from(*omega));
            let xo = Vector3::new(-3.0 + i as f64, 0.5, 10.0 + 40.0 * i as f64);
            let (c, zbar) = (300.0 + 50.0 * i as f64, 0.12);
            let img = OrthoImage::from_center(r, xo, c, zbar);
            let p = Vector3::new(0.4, -0.15 * i as f64, 0.25);
            let v = Dual::<10>::variable;
            let rows = perturbed(&r, [v(0.0, 0), v(0.0, 1), v(0.0, 2)]);
            let xd = [v(p.x, 7), v(p.y, 8), v(p.z, 9)];
            let f = project(
                &rows,
                v(img.m, 3),
                v(img.a4, 4),
                v(img.a8, 5),
                v(c, 6),
                zbar,
                &xd,
            );
            let (value, jac) = project_jacobian(&r, img.m, img.a4, img.a8, c, zbar, &p);
            for e in 0..2 {
                assert!((value[e] - f[e].v).abs() <= 1e-12 * f[e].v.abs().max(1.0));
                for k in 0..JACOBIAN_COLUMNS {
                    let tol = 1e-10 * f[e].d[k].abs().max(1e-3);
                    assert!(
                        (jac[e][k] - f[e].d[k]).abs() <= tol,
                        "row {e} column {k}: {} vs {}",
                        jac[e][k],
                        f[e].d[k]
                    );
                }
            }
        }
    }
}
