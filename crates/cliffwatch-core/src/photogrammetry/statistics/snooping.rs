//! Blunder detection by data snooping (Baarda): normalized residuals `w = v / (σ √q_vv)` with the
//! a-priori σ; the observation with the largest |w| beyond the critical value is dropped and the
//! adjustment repeated, one at a time.

use nalgebra::{Matrix2, Vector2, Vector3};

use super::precision::{Cofactors, ImageBlock};
use crate::photogrammetry::model::bundle::{Bundle, Obs, LOCAL, POINT0};
use crate::photogrammetry::model::dual::Dual;
use crate::photogrammetry::solve::normal_equations::PARALLEL_MIN_OBSERVATIONS;
use rayon::prelude::*;

/// Normalized residuals (w_x, w_y) of an active observation, `w = v / √q_vv` per coordinate. For an
/// inactive one, the w it would have once taken back, from its misclosure e against the solution
/// without it and the cofactor of that misclosure `M = σ² I + a Q aᵀ` (2 × 2): with it, `v = σ² M⁻¹ e`
/// and `Q_vv = σ⁴ M⁻¹`, so `w = (M⁻¹ e)_k / √(M⁻¹)_kk`. Testing it this way keeps the backward
/// step consistent with the snooping: an observation taken back because its w is below the
/// critical value has that w once active (`e_k / √M_kk` would not, where x and y correlate).
pub fn normalized_residual(b: &Bundle, q: &Cofactors, o_index: usize) -> [f64; 2] {
    let o = &b.obs[o_index];
    let e = b.residual_of(o);
    normalized(b, q, o_index, e)
}

/// Normalized residuals (see [`normalized_residual`]) of observation `o_index` for the residual `e` (mm).
pub fn normalized(b: &Bundle, q: &Cofactors, o_index: usize, e: [f64; 2]) -> [f64; 2] {
    w_of(b, o_index, e, q.predicted_cofactor(b, &b.obs[o_index]))
}

/// Normalized residuals of observation `o_index` from its residual `e` (mm) and the 2 × 2 cofactor
/// `aqa` of its predicted value (mm², a-priori scale); see [`normalized_residual`].
fn w_of(b: &Bundle, o_index: usize, e: [f64; 2], aqa: Matrix2<f64>) -> [f64; 2] {
    let o = &b.obs[o_index];
    let cam = b.image_camera[o.image];
    let s2 = b.sigma[cam] * b.sigma[cam] / o.prior_weight;
    if o.active {
        return std::array::from_fn(|k| e[k] / (s2 - aqa[(k, k)]).max(s2 * 1e-12).sqrt());
    }
    let m = Matrix2::identity() * s2 + aqa;
    match m.try_inverse() {
        Some(m_inv) => {
            let z = m_inv * Vector2::from(e);
            std::array::from_fn(|k| z[k] / m_inv[(k, k)].sqrt())
        }
        None => std::array::from_fn(|k| e[k] / m[(k, k)].sqrt()),
    }
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

    /// Records that observation `o_index` was activated again.
    pub fn restore(&mut self, b: &Bundle, o_index: usize) {
        let o = &b.obs[o_index];
        self.per_point[o.point] += 1;
        self.per_image[o.image] += 1;
    }
}

/// A vector `N⁻¹ [b_c; b_p]` kept as its camera part and its sparse point right-hand side (the
/// point part follows from them, see [`Cofactors::point_of`]), so that combining such vectors costs
/// the camera unknowns, not every point.
#[derive(Clone, Default)]
struct Solution {
    cams: Vec<f64>,
    /// Point right-hand sides, ascending by point index, one entry per point.
    bp: Vec<(usize, Vector3<f64>)>,
}

impl Solution {
    /// self += f · other (the point right-hand sides merged in one pass).
    fn add_scaled(&mut self, f: f64, other: &Solution) {
        for (x, y) in self.cams.iter_mut().zip(&other.cams) {
            *x += f * y;
        }
        let mut merged = Vec::with_capacity(self.bp.len() + other.bp.len());
        let (mut a, mut b) = (self.bp.iter().peekable(), other.bp.iter().peekable());
        loop {
            match (a.peek(), b.peek()) {
                (Some(&&(i, v)), Some(&&(j, w))) if i == j => {
                    merged.push((i, v + f * w));
                    a.next();
                    b.next();
                }
                (Some(&&(i, v)), Some(&&(j, _))) if i < j => {
                    merged.push((i, v));
                    a.next();
                }
                (_, Some(&&(j, w))) => {
                    merged.push((j, f * w));
                    b.next();
                }
                (Some(&&(i, v)), None) => {
                    merged.push((i, v));
                    a.next();
                }
                (None, None) => break,
            }
        }
        self.bp = merged;
    }
}

/// Whether an observation leaves the linearized problem or comes back into it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Change {
    Remove,
    Restore,
}

/// One observation removed (or restored) in the linearized phase: `U = Q aₖᵀ` (two columns) with Q
/// the cofactors before the change, and `M⁻¹ = (P⁻¹ − aₖ Q aₖᵀ)⁻¹` for a removal,
/// `−(P⁻¹ + aₖ Q aₖᵀ)⁻¹` for a restoration.
struct Modification {
    u: [Solution; 2],
    m_inv: Matrix2<f64>,
}

/// Data snooping between exact re-adjustments. From the exact solution x* (cofactors Q₀), each
/// dropped observation k changes the linearized problem by a rank-2 downdate of the normal
/// equations, whose effect on the others follows from the Sherman–Morrison–Woodbury identity:
/// `Q' = Q + U M⁻¹ Uᵀ` with `U = Q aₖᵀ`, `M = P⁻¹ − aₖ Q aₖᵀ` (the cofactor of its residual), so
/// `aⱼ Q' aⱼᵀ = aⱼ Q aⱼᵀ + (aⱼU) M⁻¹ (aⱼU)ᵀ` and the residuals `eⱼ' = eⱼ + (aⱼU) M⁻¹ eₖ`. Each drop
/// costs one solve with the factored normal equations and a pass over the observations instead of
/// a re-adjustment and a new inverse. An observation taken back is the same update with its weight
/// of the opposite sign (`M = −(P⁻¹ + aₖ Q aₖᵀ)`, a rank-2 update).
pub struct LinearSnooping {
    /// Jacobian rows per observation at x*, only the columns its camera can have.
    rows: JacobianRows,
    /// Current linearized residuals per observation (mm).
    e: Vec<[f64; 2]>,
    /// Current a Q aᵀ (2 × 2, x and y) per observation (mm², a-priori scale).
    aqa: Vec<Matrix2<f64>>,
    lanes: Vec<Vec<(usize, usize)>>,
    modifications: Vec<Modification>,
    /// Accumulated update of the unknowns since x*.
    step: Solution,
    /// Observations followed through the drops (ascending): all of them in networks below
    /// [`TRACK_ALL_BELOW`] observations, else the inactive ones and those whose |w| at x* exceeds
    /// [`TRACK_SHARE`] of the critical value.
    tracked: Vec<usize>,
    /// Points of the tracked observations (ascending), or None when every observation is tracked.
    tracked_points: Option<Vec<usize>>,
}

/// Networks of fewer observations follow every observation through the drops between exact
/// re-adjustments.
pub const TRACK_ALL_BELOW: usize = 20_000;

/// In larger networks, share of the critical value of |w| above which an observation is followed
/// through the drops. A drop changes the other observations' w by their correlation with the
/// dropped one, which is small beyond its point and image in a network of this size; an observation
/// below this share at x* that still crosses the critical value is found by the exact adjustment
/// that ends every round of drops (every w is computed anew there).
pub const TRACK_SHARE: f64 = 0.9;

impl LinearSnooping {
    /// Starts from the exact solution held by the bundle and its cofactors; `critical_w` is the
    /// critical value of |w| (see [`TRACK_SHARE`]).
    pub fn new(b: &Bundle, q: &Cofactors, critical_w: f64) -> Self {
        let parallel = b.obs.len() >= PARALLEL_MIN_OBSERVATIONS;
        let lanes = b.interior_lanes();
        let blocks: Vec<ImageBlock> = (0..b.images.len())
            .map(|j| q.image_block(j, &lanes[b.image_camera[j]]))
            .collect();
        let width = 9 + lanes.iter().map(Vec::len).max().unwrap_or(0);
        let mut rows = JacobianRows {
            width,
            values: vec![0.0; 2 * width * b.obs.len()],
        };
        let mut e = vec![[0.0; 2]; b.obs.len()];
        let mut aqa = vec![Matrix2::zeros(); b.obs.len()];
        // One pass: each observation's Jacobian, its residual, its a Q aᵀ and its compact rows.
        let fill = |o: &Obs, values: &mut [f64], e: &mut [f64; 2], aqa: &mut Matrix2<f64>| {
            let f = b.jacobian(o);
            *e = [f[0].v, f[1].v];
            *aqa = q.predicted_cofactor_of(o, &f, &blocks[o.image]);
            let cam_lanes = &lanes[b.image_camera[o.image]];
            for (r, row) in values.chunks_exact_mut(width).enumerate() {
                JacobianRows::compact(&f[r], cam_lanes, row);
            }
        };
        let chunk = 2 * width;
        if parallel {
            b.obs
                .par_iter()
                .zip(rows.values.par_chunks_mut(chunk))
                .zip(e.par_iter_mut().zip(aqa.par_iter_mut()))
                .for_each(|((o, v), (e, a))| fill(o, v, e, a));
        } else {
            b.obs
                .iter()
                .zip(rows.values.chunks_mut(chunk))
                .zip(e.iter_mut().zip(aqa.iter_mut()))
                .for_each(|((o, v), (e, a))| fill(o, v, e, a));
        }
        let nc = b.camera_unknowns();
        let n = b.obs.len();
        let (tracked, tracked_points) = if n < TRACK_ALL_BELOW {
            ((0..n).collect(), None)
        } else {
            let tracked: Vec<usize> = (0..n)
                .filter(|&k| {
                    let w = w_of(b, k, e[k], aqa[k]);
                    !b.obs[k].active || w[0].abs().max(w[1].abs()) > TRACK_SHARE * critical_w
                })
                .collect();
            let mut points: Vec<usize> = tracked.iter().map(|&k| b.obs[k].point).collect();
            points.sort_unstable();
            points.dedup();
            (tracked, Some(points))
        };
        LinearSnooping {
            rows,
            e,
            aqa,
            lanes,
            modifications: Vec::new(),
            step: Solution {
                cams: vec![0.0; nc],
                bp: Vec::new(),
            },
            tracked,
            tracked_points,
        }
    }

    /// The observations whose w follow the drops (see [`TRACK_SHARE`]); the others' w are those of
    /// x* until the next exact adjustment.
    pub fn tracked(&self) -> &[usize] {
        &self.tracked
    }

    /// Normalized residuals of observation `k` in the current linearized state (see
    /// [`normalized_residual`]).
    pub fn w(&self, b: &Bundle, k: usize) -> [f64; 2] {
        w_of(b, k, self.e[k], self.aqa[k])
    }

    /// Whether observations were removed or restored since x*.
    pub fn modified(&self) -> bool {
        !self.modifications.is_empty()
    }

    /// Normalized residuals of every observation (see [`LinearSnooping::w`]).
    pub fn all_w(&self, b: &Bundle) -> Vec<[f64; 2]> {
        (0..b.obs.len()).map(|k| self.w(b, k)).collect()
    }

    /// The accumulated update of the unknowns since x* (camera unknowns, points); `q` are the
    /// cofactors of x*.
    pub fn step(&self, q: &Cofactors) -> (Vec<f64>, Vec<Vector3<f64>>) {
        let points = q.points_of(&self.step.cams, &self.step.bp);
        (self.step.cams.clone(), points)
    }

    /// Row r of observation j's Jacobian times a vector given by its camera part and the value `p`
    /// at observation j's point.
    fn row_times(&self, b: &Bundle, j: usize, r: usize, cams: &[f64], p: Vector3<f64>) -> f64 {
        let o = &b.obs[j];
        let mut s = 0.0;
        for (l, d) in self.rows.image(j, r).iter().enumerate() {
            s += d * cams[6 * o.image + l];
        }
        let lanes = &self.lanes[b.image_camera[o.image]];
        for (&(g, _), d) in lanes.iter().zip(self.rows.lanes(j, r)) {
            s += d * cams[g];
        }
        let x = self.rows.point(j, r);
        s + x[0] * p.x + x[1] * p.y + x[2] * p.z
    }

    /// Removes observation `k` (still marked active in `b`) from the linearized problem. `q` are the
    /// cofactors of x*. Returns false when its residual has no redundancy left (M singular).
    pub fn drop(&mut self, b: &Bundle, q: &Cofactors, k: usize) -> bool {
        self.change(b, q, k, Change::Remove)
    }

    /// Takes observation `k` (still marked inactive in `b`, and tracked: see
    /// [`LinearSnooping::tracked`]) back into the linearized problem: the same update as
    /// [`LinearSnooping::drop`] with the opposite sign of its weight, `M = −(P⁻¹ + aₖ Q aₖᵀ)`.
    /// `q` are the cofactors of x*. Returns false when M is singular.
    pub fn restore(&mut self, b: &Bundle, q: &Cofactors, k: usize) -> bool {
        self.change(b, q, k, Change::Restore)
    }

    /// The rank-2 change of the normal equations by observation `k` (see [`LinearSnooping`]).
    fn change(&mut self, b: &Bundle, q: &Cofactors, k: usize, change: Change) -> bool {
        let o = &b.obs[k];
        let cam = b.image_camera[o.image];
        let i = o.point;
        // U = Q₀ aₖᵀ + Σ previous U M⁻¹ (aₖ U)ᵀ.
        let mut u: [Solution; 2] = std::array::from_fn(|r| {
            let image = self.rows.image(k, r).iter().enumerate();
            let mut bc: Vec<(usize, f64)> = image.map(|(l, &d)| (6 * o.image + l, d)).collect();
            let lanes = self.lanes[cam].iter().zip(self.rows.lanes(k, r));
            bc.extend(lanes.map(|(&(g, _), &d)| (g, d)));
            let x = self.rows.point(k, r);
            let bp = vec![(i, Vector3::new(x[0], x[1], x[2]))];
            Solution {
                cams: q.solve_cameras(&bc, &bp),
                bp,
            }
        });
        // aₖ times the two columns of a U.
        let a_k = |u: &[Solution; 2]| {
            let mut a = Matrix2::zeros();
            for c in 0..2 {
                let p = q.point_of(&u[c].cams, &u[c].bp, i);
                for r in 0..2 {
                    a[(r, c)] = self.row_times(b, k, r, &u[c].cams, p);
                }
            }
            a
        };
        for rem in &self.modifications {
            let coef = rem.m_inv * a_k(&rem.u).transpose();
            for r in 0..2 {
                for c in 0..2 {
                    let f = coef[(c, r)];
                    if f != 0.0 {
                        u[r].add_scaled(f, &rem.u[c]);
                    }
                }
            }
        }
        let s2 = b.sigma[cam] * b.sigma[cam] / (o.weight * o.prior_weight);
        // Removal: M = P⁻¹ − aₖ Q aₖᵀ, the cofactor of its residual (singular without redundancy).
        // Restoration: the weight changes sign, M = −(P⁻¹ + aₖ Q aₖᵀ), always regular.
        let m = match change {
            Change::Remove => Matrix2::identity() * s2 - a_k(&u),
            Change::Restore => -(Matrix2::identity() * s2 + a_k(&u)),
        };
        let Some(m_inv) = m
            .try_inverse()
            .filter(|_| m.determinant() > 1e-12 * s2 * s2)
        else {
            return false;
        };
        let gain = m_inv * Vector2::from(self.e[k]);
        // U's point part at the points of the tracked observations.
        let points: [Vec<Vector3<f64>>; 2] = std::array::from_fn(|c| match &self.tracked_points {
            None => q.points_of(&u[c].cams, &u[c].bp),
            Some(pts) => {
                let mut v = vec![Vector3::zeros(); b.points.len()];
                for &p in pts {
                    v[p] = q.point_of(&u[c].cams, &u[c].bp, p);
                }
                v
            }
        });
        let this = &*self;
        let update = |j: usize| {
            let p = b.obs[j].point;
            let mut a = Matrix2::zeros();
            for r in 0..2 {
                for c in 0..2 {
                    a[(r, c)] = this.row_times(b, j, r, &u[c].cams, points[c][p]);
                }
            }
            (a * gain, a * m_inv * a.transpose())
        };
        let changes: Vec<(Vector2<f64>, Matrix2<f64>)> =
            if self.tracked.len() < PARALLEL_MIN_OBSERVATIONS {
                self.tracked.iter().map(|&j| update(j)).collect()
            } else {
                self.tracked.par_iter().map(|&j| update(j)).collect()
            };
        for (&j, (de, dq)) in self.tracked.iter().zip(changes) {
            for r in 0..2 {
                self.e[j][r] += de[r];
            }
            self.aqa[j] += dq;
        }
        for c in 0..2 {
            self.step.add_scaled(gain[c], &u[c]);
        }
        self.modifications.push(Modification { u, m_inv });
        true
    }
}

/// The two Jacobian rows of every observation, compact: per row `width` values, its image's six
/// unknowns, then its camera's interior lanes in the order of [`Bundle::interior_lanes`] (unused
/// slots zero), then the three point coordinates last. For the usual c-only self-calibration that
/// is 10 values a row instead of the 18 of a [`Dual`] (1.6 instead of 2.9 MB for 10 000
/// observations).
struct JacobianRows {
    width: usize,
    values: Vec<f64>,
}

impl JacobianRows {
    /// Writes row `f` (local columns, see [`LOCAL`]) of an observation whose camera has the
    /// interior lanes `lanes` into `row` (`width` values).
    fn compact(f: &Dual<LOCAL>, lanes: &[(usize, usize)], row: &mut [f64]) {
        let width = row.len();
        row[..6].copy_from_slice(&f.d[..6]);
        for (m, &(_, lane)) in lanes.iter().enumerate() {
            row[6 + m] = f.d[lane];
        }
        row[width - 3..].copy_from_slice(&f.d[POINT0..POINT0 + 3]);
    }

    /// Row `r` (0: x, 1: y) of observation `k`.
    fn row(&self, k: usize, r: usize) -> &[f64] {
        let start = (2 * k + r) * self.width;
        &self.values[start..start + self.width]
    }

    /// The image's six columns of row `r` of observation `k`.
    fn image(&self, k: usize, r: usize) -> &[f64] {
        &self.row(k, r)[..6]
    }

    /// The interior lanes' columns of row `r` of observation `k`, in the order of its camera's
    /// lanes (and zeros beyond them).
    fn lanes(&self, k: usize, r: usize) -> &[f64] {
        &self.row(k, r)[6..self.width - 3]
    }

    /// The point's three columns of row `r` of observation `k`.
    fn point(&self, k: usize, r: usize) -> &[f64] {
        &self.row(k, r)[self.width - 3..]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::photogrammetry::model::bundle::INTERIOR0;
    use crate::photogrammetry::test_support::bundle;

    /// The compact rows keep every column of the dual Jacobian: a row times a vector is the same
    /// number, to the last bit, for two cameras with different free interior parameters.
    #[test]
    fn compact_rows_multiply_as_the_jacobian() {
        let mut b = bundle(6, 24, 4);
        let c = b.interior[0][0];
        b.interior.push(b.interior[0]);
        b.image_camera = vec![0, 1, 0, 1, 0, 1];
        b.sigma.push(b.sigma[0]);
        let mut free = [[false; 8]; 2];
        let mut prior = [[None; 8]; 2];
        for (cam, params) in [[0, 1].as_slice(), [0, 2, 3].as_slice()].iter().enumerate() {
            for &k in *params {
                free[cam][k] = true;
                prior[cam][k] = Some((b.interior[cam][k], if k == 0 { 0.1 * c } else { 0.01 }));
            }
        }
        b.free = free.to_vec();
        b.interior_prior = prior.to_vec();
        let q = Cofactors::from_normals(&b, b.normals(), false).expect("positive definite");
        let snooping = LinearSnooping::new(&b, &q, 3.3);
        assert_eq!(snooping.rows.width, 6 + 3 + 3);
        let nc = b.camera_unknowns();
        let cams: Vec<f64> = (0..nc).map(|k| (0.37 * k as f64).sin()).collect();
        let lanes = b.interior_lanes();
        for (k, o) in b.obs.iter().enumerate() {
            let p = Vector3::new(0.3, -0.7, 1.1 + k as f64);
            let f = b.jacobian(o);
            for (r, fr) in f.iter().enumerate() {
                let d = &fr.d;
                let mut s = 0.0;
                for l in 0..6 {
                    s += d[l] * cams[6 * o.image + l];
                }
                for &(g, lane) in &lanes[b.image_camera[o.image]] {
                    assert!((INTERIOR0..POINT0).contains(&lane));
                    s += d[lane] * cams[g];
                }
                let expected = s + d[POINT0] * p.x + d[POINT0 + 1] * p.y + d[POINT0 + 2] * p.z;
                assert_eq!(
                    snooping.row_times(&b, k, r, &cams, p),
                    expected,
                    "obs {k}, row {r}"
                );
            }
        }
    }
}
