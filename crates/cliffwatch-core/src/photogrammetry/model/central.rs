//! The central-perspective (collinearity) model, eq (2): `x = −c r1·(X−Xo) / r3·(X−Xo)`,
//! `y = −c r2·(X−Xo) / r3·(X−Xo)`, for the corrected image coordinates (Brown model in
//! [`super::camera`]). Unknowns per image: three rotation increments and Xo.

use nalgebra::{Matrix3, Vector3};

use super::dual::Scalar;

/// Exterior orientation of one image in the central model (working frame).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CentralImage {
    /// Rotation R (camera = R (X − Xo)).
    pub rotation: Matrix3<f64>,
    /// Projection centre in m.
    pub center: Vector3<f64>,
}

/// Collinearity, eq (2): corrected image coordinates (mm) of the point `x` (m).
pub fn project<T: Scalar>(rot: &[[T; 3]; 3], center: &[T; 3], c: T, x: &[T; 3]) -> [T; 2] {
    let d = [x[0] - center[0], x[1] - center[1], x[2] - center[2]];
    let dot = |r: &[T; 3]| r[0] * d[0] + r[1] * d[1] + r[2] * d[2];
    let w = dot(&rot[2]);
    [-(c * dot(&rot[0])) / w, -(c * dot(&rot[1])) / w]
}
