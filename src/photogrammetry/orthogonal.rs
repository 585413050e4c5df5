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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::photogrammetry::rotation::{perturbed, rodrigues};

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
}
