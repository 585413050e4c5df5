//! Blunder detection by data snooping (Baarda): normalized residuals `w = v / (σ √q_vv)` with the
//! a-priori σ; the observation with the largest |w| beyond the critical value is dropped and the
//! adjustment repeated, one at a time.

use super::bundle::residual_value;
use super::normals::Bundle;
use super::precision::Cofactors;

/// Normalized residuals (w_x, w_y) of an active observation; for an inactive one, its misclosure
/// against the solution over the σ of that misclosure (`q = σ² + a Q aᵀ`).
pub fn normalized_residual(b: &Bundle, q: &Cofactors, o_index: usize) -> [f64; 2] {
    let o = &b.obs[o_index];
    let cam = b.image_camera[o.image];
    let e = residual_value(
        b.model,
        &b.images[o.image],
        &b.interior[cam],
        &b.points[o.point],
        o.meas,
        b.zbar,
    );
    let s2 = b.sigma[cam] * b.sigma[cam];
    let aqa = q.predicted_cofactor(b, o);
    let mut w = [0.0; 2];
    for k in 0..2 {
        let var = if o.active {
            (s2 - aqa[k]).max(s2 * 1e-12)
        } else {
            s2 + aqa[k]
        };
        w[k] = e[k] / var.sqrt();
    }
    w
}

/// Active observations per image and per point: what decides whether one more may be dropped.
#[derive(Debug, Clone)]
pub struct ActiveCounts {
    /// Active observations per image.
    pub per_image: Vec<usize>,
    /// Active observations (images) per point.
    pub per_point: Vec<usize>,
}

impl ActiveCounts {
    /// Counts the active observations of the bundle.
    pub fn of(b: &Bundle) -> Self {
        let mut c = ActiveCounts {
            per_image: vec![0; b.images.len()],
            per_point: vec![0; b.points.len()],
        };
        for o in b.obs.iter().filter(|o| o.active) {
            c.per_image[o.image] += 1;
            c.per_point[o.point] += 1;
        }
        c
    }

    /// Whether dropping observation `o_index` keeps the network determinable: its point stays in ≥ 2
    /// images and its image keeps ≥ 4 observations.
    pub fn droppable(&self, b: &Bundle, o_index: usize) -> bool {
        let o = &b.obs[o_index];
        self.per_point[o.point] > 2 && self.per_image[o.image] > 4
    }

    /// Records that observation `o_index` was deactivated.
    pub fn drop(&mut self, b: &Bundle, o_index: usize) {
        let o = &b.obs[o_index];
        self.per_point[o.point] -= 1;
        self.per_image[o.image] -= 1;
    }
}
