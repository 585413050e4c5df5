//! The bundle state in the working frame and the observation equations of both models: residuals and
//! exact Jacobians (by [`Dual`] numbers) of one image observation.

use nalgebra::{Matrix3, Vector3};

use super::camera::brown_correct;
use super::dual::{Dual, Scalar};
use super::rotation::perturbed;
use crate::photogrammetry::adjust::cancel::Cancel;
use crate::photogrammetry::model::Model;
use crate::photogrammetry::model::{central, orthogonal};

/// The adjustment's unknowns and observations in the working frame.
#[derive(Debug, Clone)]
pub struct Bundle {
    /// Projection model.
    pub model: Model,
    /// Zbar of the orthogonal model (m, working frame; 0 at the centroid of the start points).
    pub zbar: f64,
    /// Exterior unknowns per image.
    pub images: Vec<ImageState>,
    /// Camera index per image.
    pub image_camera: Vec<usize>,
    /// Interior parameters per camera `[c, x0, y0, k1, k2, k3, p1, p2]`.
    pub interior: Vec<[f64; 8]>,
    /// Which interior parameters are unknowns, per camera.
    pub free: Vec<[bool; 8]>,
    /// A-priori σ of an image coordinate per camera (mm).
    pub sigma: Vec<f64>,
    /// Point coordinates (m, working frame).
    pub points: Vec<Vector3<f64>>,
    /// Observations.
    pub obs: Vec<Obs>,
    /// Observation indices per point.
    pub point_obs: Vec<Vec<usize>>,
    /// Control coordinates (m, working frame) and σ (m) per point, as weighted observations.
    pub control: Vec<Option<(Vector3<f64>, f64)>>,
    /// Weight of the tiny prior on point increments that fixes the free network's datum defect during
    /// the iteration (0 when control points fix the datum).
    pub gauge: f64,
    /// A-priori value and σ of interior parameters (weighted pseudo-observations), per camera.
    pub interior_prior: Vec<[Option<(f64, f64)>; 8]>,
    /// Whether the adjustment is still wanted: the iteration stops at its next step once cancelled.
    pub cancel: Cancel,
}

/// Local Jacobian columns of one observation: 0..6 image, 6..14 interior parameter k, 14..17 point.
pub const LOCAL: usize = 17;
/// First local column of the interior parameters.
pub const INTERIOR0: usize = 6;
/// First local column of the point coordinates.
pub const POINT0: usize = 14;

/// Exterior unknowns of one image (working frame): the rotation (updated multiplicatively) and three
/// more numbers: (m, A4, A8) in the orthogonal model, Xo (m) in the central model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImageState {
    /// Rotation R (camera = R (X − Xo)).
    pub rotation: Matrix3<f64>,
    /// (m, A4, A8) or Xo.
    pub p: [f64; 3],
}

/// One observation in the adjustment.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Obs {
    /// Image index.
    pub image: usize,
    /// Point index.
    pub point: usize,
    /// Measured image coordinates (mm).
    pub meas: [f64; 2],
    /// Whether it takes part (false once dropped as a blunder).
    pub active: bool,
    /// Robust weight factor (1 in the final adjustment; below 1 while gross errors are screened).
    pub weight: f64,
    /// A-priori weight relative to its camera's σ: (camera σ / the observation's own σ)², 1 for
    /// an observation without a σ of its own.
    pub prior_weight: f64,
}

/// Residual (corrected measurement − model, mm) of the generic model, eq (5)+(9) or eq (2).
#[allow(clippy::too_many_arguments)]
pub fn residual<T: Scalar>(
    model: Model,
    rows: &[[T; 3]; 3],
    p: &[T; 3],
    interior: &[T; 8],
    x: &[T; 3],
    meas: [f64; 2],
    zbar: f64,
) -> [T; 2] {
    let corrected = brown_correct([T::from(meas[0]), T::from(meas[1])], interior);
    residual_corrected(model, rows, p, interior[0], x, corrected, zbar)
}

/// Residual from an already corrected measurement (mm).
pub fn residual_corrected<T: Scalar>(
    model: Model,
    rows: &[[T; 3]; 3],
    p: &[T; 3],
    c: T,
    x: &[T; 3],
    corrected: [T; 2],
    zbar: f64,
) -> [T; 2] {
    let f = match model {
        Model::Orthogonal => orthogonal::project(rows, p[0], p[1], p[2], c, zbar, x),
        Model::Central => central::project(rows, p, c, x),
    };
    [corrected[0] - f[0], corrected[1] - f[1]]
}

/// Residual of one observation (mm).
pub fn residual_value(
    model: Model,
    image: &ImageState,
    interior: &[f64; 8],
    x: &Vector3<f64>,
    meas: [f64; 2],
    zbar: f64,
) -> [f64; 2] {
    let rows = perturbed::<f64>(&image.rotation, [0.0; 3]);
    residual(
        model,
        &rows,
        &image.p,
        interior,
        &[x.x, x.y, x.z],
        meas,
        zbar,
    )
}

/// Residual and its Jacobian (local columns, see [`LOCAL`]) with respect to the image unknowns, the
/// interior parameters marked `free`, and the point.
pub fn residual_jacobian(
    model: Model,
    image: &ImageState,
    interior: &[f64; 8],
    free: &[bool; 8],
    x: &Vector3<f64>,
    meas: [f64; 2],
    zbar: f64,
) -> [Dual<LOCAL>; 2] {
    if model == Model::Orthogonal && !free[1..].iter().any(|&f| f) {
        return orthogonal_jacobian(image, interior, free[0], x, meas, zbar);
    }
    let v = Dual::<LOCAL>::variable;
    let rows = perturbed(&image.rotation, [v(0.0, 0), v(0.0, 1), v(0.0, 2)]);
    let p = [v(image.p[0], 3), v(image.p[1], 4), v(image.p[2], 5)];
    let mut inner = [Dual::from(0.0); 8];
    for k in 0..8 {
        inner[k] = if free[k] {
            v(interior[k], INTERIOR0 + k)
        } else {
            Dual::from(interior[k])
        };
    }
    let xd = [v(x.x, POINT0), v(x.y, POINT0 + 1), v(x.z, POINT0 + 2)];
    if free[1..].iter().any(|&f| f) {
        residual(model, &rows, &p, &inner, &xd, meas, zbar)
    } else {
        // Distortion and principal point held: correct the measurement once, in plain numbers.
        let c = brown_correct(meas, interior);
        residual_corrected(
            model,
            &rows,
            &p,
            inner[0],
            &xd,
            [c[0].into(), c[1].into()],
            zbar,
        )
    }
}

/// [`residual_jacobian`] of the orthogonal model with the distortion and principal point held, from the
/// hand-derived Jacobian [`orthogonal::project_jacobian`] (the dual numbers cost five times more).
fn orthogonal_jacobian(
    image: &ImageState,
    interior: &[f64; 8],
    c_free: bool,
    x: &Vector3<f64>,
    meas: [f64; 2],
    zbar: f64,
) -> [Dual<LOCAL>; 2] {
    let corrected = brown_correct(meas, interior);
    let [m, a4, a8] = image.p;
    let (f, jac) = orthogonal::project_jacobian(&image.rotation, m, a4, a8, interior[0], zbar, x);
    let mut out = [Dual::from(0.0); 2];
    for e in 0..2 {
        out[e].v = corrected[e] - f[e];
        let (d, j) = (&mut out[e].d, &jac[e]);
        for k in 0..6 {
            d[k] = -j[k];
        }
        if c_free {
            d[INTERIOR0] = -j[6];
        }
        for k in 0..3 {
            d[POINT0 + k] = -j[7 + k];
        }
    }
    out
}
