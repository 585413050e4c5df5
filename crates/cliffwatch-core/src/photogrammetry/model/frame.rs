//! The working frame (`docs/model.md`): the site frame shifted to the centroid of the
//! points and rotated so that its Z axis is the mean viewing axis r3 of the cameras. Eq (9) divides by
//! a33·c, so the adjustment must run where a33 ≈ 1 whatever the site frame (E, N, Up at a cliff gives
//! a33 ≈ 0 with horizontal viewing).

use nalgebra::{Matrix3, Vector3};

/// A rigid transformation site → working frame: `X_w = rotation · (X − origin)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WorkingFrame {
    /// Rows are the working axes expressed in the site frame.
    pub rotation: Matrix3<f64>,
    /// Origin of the working frame in site coordinates (m).
    pub origin: Vector3<f64>,
}

impl WorkingFrame {
    /// The frame whose Z axis is the normalized mean of the cameras' r3 rows and whose X axis is the mean
    /// r1 made orthogonal to it; origin at `origin`. Falls back to the site axes when the means vanish.
    pub fn from_axes(r1s: &[Vector3<f64>], r3s: &[Vector3<f64>], origin: Vector3<f64>) -> Self {
        let mean = |v: &[Vector3<f64>]| v.iter().fold(Vector3::zeros(), |a, b| a + b);
        let e3 = mean(r3s).try_normalize(1e-12).unwrap_or(Vector3::z());
        let m1 = mean(r1s);
        let e1 = (m1 - e3 * m1.dot(&e3))
            .try_normalize(1e-12)
            .or_else(|| {
                let t = if e3.x.abs() < 0.9 {
                    Vector3::x()
                } else {
                    Vector3::y()
                };
                (t - e3 * t.dot(&e3)).try_normalize(1e-12)
            })
            .unwrap_or(Vector3::x());
        let e2 = e3.cross(&e1);
        WorkingFrame {
            rotation: Matrix3::from_rows(&[e1.transpose(), e2.transpose(), e3.transpose()]),
            origin,
        }
    }

    /// Site → working coordinates (m).
    pub fn to_working(&self, x: Vector3<f64>) -> Vector3<f64> {
        self.rotation * (x - self.origin)
    }

    /// Working → site coordinates (m).
    pub fn to_site(&self, x: Vector3<f64>) -> Vector3<f64> {
        self.rotation.transpose() * x + self.origin
    }

    /// A covariance (3 × 3) from working to site axes.
    pub fn covariance_to_site(&self, q: &Matrix3<f64>) -> Matrix3<f64> {
        self.rotation.transpose() * q * self.rotation
    }

    /// A camera rotation R (camera = R (X − Xo)) from site to working axes: R_w = R · rotationᵀ.
    pub fn rotation_to_working(&self, r: &Matrix3<f64>) -> Matrix3<f64> {
        r * self.rotation.transpose()
    }

    /// A camera rotation from working to site axes.
    pub fn rotation_to_site(&self, r_w: &Matrix3<f64>) -> Matrix3<f64> {
        r_w * self.rotation
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn horizontal_viewing_in_enu_becomes_z_toward_the_cameras() {
        // Cameras looking north (−r3 = +N), so r3 = −N = (0, −1, 0).
        let r3 = vec![Vector3::new(0.1, -1.0, 0.0), Vector3::new(-0.1, -1.0, 0.0)];
        let r1 = vec![Vector3::new(1.0, 0.0, 0.0), Vector3::new(1.0, 0.1, 0.0)];
        let f = WorkingFrame::from_axes(&r1, &r3, Vector3::new(500_000.0, 3_900_000.0, 200.0));
        let z = f.rotation.row(2).transpose();
        assert!((z - Vector3::new(0.0, -1.0, 0.0)).norm() < 1e-12);
        let p = Vector3::new(500_001.0, 3_900_002.0, 203.0);
        assert!((f.to_site(f.to_working(p)) - p).norm() < 1e-9);
        assert!((f.rotation.determinant() - 1.0).abs() < 1e-12);
    }
}

/// A similarity transformation `X' = s Q X + t` (Q a rotation, s a scale, t in m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Similarity {
    /// Scale.
    pub scale: f64,
    /// Rotation.
    pub rotation: Matrix3<f64>,
    /// Translation in m.
    pub translation: Vector3<f64>,
}

impl Similarity {
    /// Applies the transformation to a point (m).
    pub fn apply(&self, x: &Vector3<f64>) -> Vector3<f64> {
        self.scale * (self.rotation * x) + self.translation
    }
}

/// Least-squares similarity (Umeyama 1991) mapping `from` onto `to`. Its optimum satisfies the inner
/// constraints Gᵀ (X' − to) = 0, so applying it to a free-network solution with `to` = the approximate
/// coordinates gives the minimum-norm datum.
pub fn similarity_fit(from: &[Vector3<f64>], to: &[Vector3<f64>]) -> Option<Similarity> {
    let n = from.len();
    if n < 3 || to.len() != n {
        return None;
    }
    let mf = from.iter().fold(Vector3::zeros(), |a, b| a + b) / n as f64;
    let mt = to.iter().fold(Vector3::zeros(), |a, b| a + b) / n as f64;
    let mut cov = Matrix3::zeros();
    let mut var_from = 0.0;
    for (f, t) in from.iter().zip(to) {
        let df = f - mf;
        cov += (t - mt) * df.transpose();
        var_from += df.norm_squared();
    }
    if var_from <= 0.0 {
        return None;
    }
    if !cov.iter().all(|v| v.is_finite()) {
        return None;
    }
    let svd = cov.try_svd(true, true, f64::EPSILON, 200)?;
    let (u, v_t) = (svd.u?, svd.v_t?);
    let mut d = Matrix3::identity();
    if (u * v_t).determinant() < 0.0 {
        d[(2, 2)] = -1.0;
    }
    let rotation = u * d * v_t;
    let trace: f64 = (0..3).map(|k| svd.singular_values[k] * d[(k, k)]).sum();
    let scale = trace / var_from;
    let translation = mt - scale * (rotation * mf);
    Some(Similarity {
        scale,
        rotation,
        translation,
    })
}
