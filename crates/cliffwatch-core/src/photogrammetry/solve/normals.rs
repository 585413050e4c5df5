//! Normal equations of the bundle and their reduction by the Schur complement over the 3 × 3 point
//! blocks: `S = U − Σ_i W_i V_i⁻¹ W_iᵀ`, a dense system in the image and interior unknowns (faer
//! Cholesky), then back-substitution for the points.

use faer::Mat;
use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;

use super::camera_blocks::CameraBlocks;
use super::normal_equations::{chunk_len, Coupling, Normals, PARALLEL_MIN_OBSERVATIONS};
use crate::photogrammetry::model::bundle::{
    residual, residual_jacobian, residual_value, Bundle, Obs, INTERIOR0, LOCAL, POINT0,
};
use crate::photogrammetry::model::dual::Dual;
use crate::photogrammetry::model::rotation::perturbed;

/// The reduced system and what back-substitution needs.
pub struct Reduced {
    /// S = U − Σ W V⁻¹ Wᵀ (damped).
    pub s: Mat<f64>,
    /// Reduced right-hand side.
    pub rhs: Vec<f64>,
    /// (V_i + damping + gauge)⁻¹.
    pub vinv: Vec<Matrix3<f64>>,
    /// W and W V⁻¹ as dense matrices, when the reduction ran as matrix products.
    pub dense: Option<super::dense_schur::DenseCouplings>,
}

impl Bundle {
    /// Number of image and interior unknowns (the reduced system's size).
    pub fn camera_unknowns(&self) -> usize {
        6 * self.images.len() + self.interior_columns().iter().flatten().flatten().count()
    }

    /// Global column of each free interior parameter, per camera.
    pub fn interior_columns(&self) -> Vec<[Option<usize>; 8]> {
        let mut next = 6 * self.images.len();
        self.free
            .iter()
            .map(|f| {
                let mut cols = [None; 8];
                for k in 0..8 {
                    if f[k] {
                        cols[k] = Some(next);
                        next += 1;
                    }
                }
                cols
            })
            .collect()
    }

    /// Weighted square sum vᵀPv of the current state (observations and control).
    pub fn cost(&self) -> f64 {
        // The rotation matrix of every image once, not per observation.
        let rows: Vec<[[f64; 3]; 3]> = self
            .images
            .iter()
            .map(|im| perturbed::<f64>(&im.rotation, [0.0; 3]))
            .collect();
        let part = |obs: &[Obs]| {
            let mut cost = 0.0;
            for o in obs.iter().filter(|o| o.active) {
                let cam = self.image_camera[o.image];
                let x = &self.points[o.point];
                let e = residual(
                    self.model,
                    &rows[o.image],
                    &self.images[o.image].p,
                    &self.interior[cam],
                    &[x.x, x.y, x.z],
                    o.meas,
                    self.zbar,
                );
                let p = o.weight * o.prior_weight / (self.sigma[cam] * self.sigma[cam]);
                cost += p * (e[0] * e[0] + e[1] * e[1]);
            }
            cost
        };
        // Fixed chunks summed in order, so that the result does not depend on the thread schedule.
        let mut cost: f64 = if self.obs.len() < PARALLEL_MIN_OBSERVATIONS {
            part(&self.obs)
        } else {
            let parts: Vec<f64> = self.obs.par_chunks(COST_CHUNK).map(part).collect();
            parts.iter().sum()
        };
        for (x, c) in self.points.iter().zip(&self.control) {
            if let Some((xc, s)) = c {
                cost += (x - xc).norm_squared() / (s * s);
            }
        }
        for (cam, priors) in self.interior_prior.iter().enumerate() {
            for k in 0..8 {
                if let (true, Some((v, s))) = (self.free[cam][k], priors[k]) {
                    cost += ((self.interior[cam][k] - v) / s).powi(2);
                }
            }
        }
        cost
    }

    /// Sum of the traces of the point blocks V_i of the normal equations (1/m², a-priori weights),
    /// without building them.
    pub fn point_block_trace(&self) -> f64 {
        let mut sum = 0.0;
        for o in self.obs.iter().filter(|o| o.active) {
            let cam = self.image_camera[o.image];
            let p = o.weight * o.prior_weight / (self.sigma[cam] * self.sigma[cam]);
            for fk in &self.jacobian(o) {
                sum += p
                    * (fk.d[POINT0].powi(2) + fk.d[POINT0 + 1].powi(2) + fk.d[POINT0 + 2].powi(2));
            }
        }
        for c in self.control.iter().flatten() {
            sum += 3.0 / (c.1 * c.1);
        }
        sum
    }

    /// Number of interior pseudo-observations in force (priors on free parameters).
    pub fn prior_count(&self) -> usize {
        self.interior_prior
            .iter()
            .zip(&self.free)
            .map(|(p, f)| (0..8).filter(|&k| f[k] && p[k].is_some()).count())
            .sum()
    }

    /// Residual (mm) of observation `o` at the current state (see [`residual_value`]).
    pub fn residual_of(&self, o: &Obs) -> [f64; 2] {
        residual_value(
            self.model,
            &self.images[o.image],
            &self.interior[self.image_camera[o.image]],
            &self.points[o.point],
            o.meas,
            self.zbar,
        )
    }

    /// Residual (mm) and Jacobian of observation `o` at the current state (see [`residual_jacobian`]).
    pub fn jacobian(&self, o: &Obs) -> [Dual<LOCAL>; 2] {
        let cam = self.image_camera[o.image];
        residual_jacobian(
            self.model,
            &self.images[o.image],
            &self.interior[cam],
            &self.free[cam],
            &self.points[o.point],
            o.meas,
            self.zbar,
        )
    }

    /// Global column and local Jacobian lane of each free interior parameter, per camera.
    pub fn interior_lanes(&self) -> Vec<Vec<(usize, usize)>> {
        self.interior_columns()
            .iter()
            .map(|c| {
                (0..8)
                    .filter_map(|k| c[k].map(|g| (g, INTERIOR0 + k)))
                    .collect()
            })
            .collect()
    }

    /// Builds the normal equations at the current state. U is accumulated block by block (see
    /// [`CameraBlocks`]) and written into the dense, symmetric U at the end. Large networks are built
    /// in chunks of points on the rayon pool, each with its own blocks, summed at the end.
    pub fn normals(&self) -> Normals {
        let mut n = Normals {
            u: Mat::zeros(0, 0),
            bc: Vec::new(),
            v: Vec::new(),
            bp: Vec::new(),
            w: Vec::new(),
        };
        self.normals_into(&mut n);
        n
    }

    /// [`Bundle::normals`] into the buffers of earlier normal equations `n` (of this bundle or
    /// another): the couplings' vectors keep their capacity, so that an iteration does not allocate
    /// (and fault in) them anew.
    pub fn normals_into(&self, n: &mut Normals) {
        let nc = self.camera_unknowns();
        let lanes = self.interior_lanes();
        let np = self.points.len();
        let mut w = std::mem::take(&mut n.w);
        w.resize_with(np, Coupling::default);
        let mut v = std::mem::take(&mut n.v);
        v.clear();
        v.resize(np, Matrix3::zeros());
        let mut bp = std::mem::take(&mut n.bp);
        bp.clear();
        bp.resize(np, Vector3::zeros());
        let chunk = chunk_len(np, self.obs.len());
        let interior_cols: Vec<Vec<usize>> = lanes
            .iter()
            .map(|l| l.iter().map(|&(g, _)| g).collect())
            .collect();
        let counts: Vec<usize> = lanes.iter().map(Vec::len).collect();
        let work =
            |ci: usize, v: &mut [Matrix3<f64>], bp: &mut [Vector3<f64>], w: &mut [Coupling]| {
                let mut acc = CameraBlocks::new(&self.image_camera, &counts, nc);
                let mut interior = Coupling::default();
                for (k, ((v, bp), w)) in v.iter_mut().zip(bp).zip(w).enumerate() {
                    self.point_normals(ci * chunk + k, &lanes, &mut acc, v, bp, w, &mut interior);
                }
                acc
            };
        let blocks = if chunk >= np {
            work(0, &mut v, &mut bp, &mut w)
        } else {
            v.par_chunks_mut(chunk)
                .zip(bp.par_chunks_mut(chunk))
                .zip(w.par_chunks_mut(chunk))
                .enumerate()
                .map(|(ci, ((v, bp), w))| work(ci, v, bp, w))
                .reduce_with(CameraBlocks::merge)
                .unwrap_or_else(|| CameraBlocks::new(&self.image_camera, &counts, nc))
        };
        let mut u = std::mem::replace(&mut n.u, Mat::zeros(0, 0));
        blocks.write(&mut u, &self.image_camera, &interior_cols);
        let mut bc = blocks.bc;
        for (cam, cols) in self.interior_columns().iter().enumerate() {
            for k in 0..8 {
                if let (Some(g), Some((v, s))) = (cols[k], self.interior_prior[cam][k]) {
                    let p = 1.0 / (s * s);
                    let e = self.interior[cam][k] - v;
                    u[(g, g)] += p;
                    bc[g] -= p * e;
                }
            }
        }
        *n = Normals { u, bc, v, bp, w };
    }

    /// The share of point `i` in the normal equations: its block `v`, right-hand side `bp` and
    /// coupling `w`, and its observations' terms added to the blocks of U and b_c in `acc`;
    /// `interior` is scratch for its interior couplings.
    #[allow(clippy::too_many_arguments)]
    fn point_normals(
        &self,
        i: usize,
        lanes: &[Vec<(usize, usize)>],
        acc: &mut CameraBlocks,
        v: &mut Matrix3<f64>,
        bp: &mut Vector3<f64>,
        wi: &mut Coupling,
        interior: &mut Coupling,
    ) {
        let mut cols = [(0usize, 0usize); 14];
        let nobs = self.point_obs[i].len();
        wi.cols.clear();
        wi.rows.clear();
        wi.cols.reserve(7 * nobs);
        wi.rows.reserve(7 * nobs);
        // Interior couplings, appended after the image blocks so that the columns ascend.
        interior.cols.clear();
        interior.rows.clear();
        for &oi in &self.point_obs[i] {
            let o = &self.obs[oi];
            if !o.active {
                continue;
            }
            let cam = self.image_camera[o.image];
            let p = o.weight * o.prior_weight / (self.sigma[cam] * self.sigma[cam]);
            let f = self.jacobian(o);
            for (k, col) in cols.iter_mut().enumerate().take(6) {
                *col = (6 * o.image + k, k);
            }
            let n = 6 + lanes[cam].len();
            cols[6..n].copy_from_slice(&lanes[cam]);
            let cols = &cols[..n];
            // Fixed sizes for the usual column counts (c held or free), so that the loops unroll.
            let wrows: [Vector3<f64>; 14] = match n {
                6 => pad(observation_terms::<6>(
                    &f, cols, p, o.image, cam, acc, v, bp,
                )),
                7 => pad(observation_terms::<7>(
                    &f, cols, p, o.image, cam, acc, v, bp,
                )),
                _ => observation_terms::<14>(&f, cols, p, o.image, cam, acc, v, bp),
            };
            for a in 0..6 {
                wi.cols.push(cols[a].0);
                wi.rows.push(wrows[a]);
            }
            for a in 6..n {
                interior.add(cols[a].0, wrows[a]);
            }
        }
        wi.cols.extend_from_slice(&interior.cols);
        wi.rows.extend_from_slice(&interior.rows);
        wi.sorted = wi.cols.windows(2).all(|c| c[0] < c[1]);
        let nw = wi.cols.len();
        wi.run_end.clear();
        wi.run_end.resize(nw, nw);
        for a in (0..nw.saturating_sub(1)).rev() {
            wi.run_end[a] = if wi.cols[a + 1] == wi.cols[a] + 1 {
                wi.run_end[a + 1]
            } else {
                a + 1
            };
        }
        if let Some((xc, s)) = self.control[i] {
            let p = 1.0 / (s * s);
            let e = self.points[i] - xc;
            *v += p * Matrix3::identity();
            *bp -= p * e;
        }
    }

    /// Reduces the normal equations with Marquardt damping λ (diagonal scaled by 1 + λ). Only the
    /// lower triangle of S is formed (all the Cholesky factorization reads); the upper keeps U's.
    /// Large networks are reduced in chunks of points on the rayon pool, each with its own Σ W V⁻¹ Wᵀ.
    pub fn reduce(&self, n: &Normals, lambda: f64) -> Option<Reduced> {
        self.reduce_with(n, lambda, &mut ReduceBuffers::default())
    }

    /// [`Bundle::reduce`] in the dense matrices of `buffers` (kept from an earlier reduction).
    pub fn reduce_with(
        &self,
        n: &Normals,
        lambda: f64,
        buffers: &mut ReduceBuffers,
    ) -> Option<Reduced> {
        if super::dense_schur::is_dense(n, self.obs.len()) {
            return self.reduce_dense(n, lambda, buffers);
        }
        let nc = n.bc.len();
        let np = n.v.len();
        let chunk = chunk_len(np, self.obs.len());
        let work = |ci: usize, s: &mut Mat<f64>| {
            if s.nrows() == nc && s.ncols() == nc {
                s.fill(0.0);
            } else {
                *s = Mat::zeros(nc, nc);
            }
            let mut rhs = vec![0.0; nc];
            let range = ci * chunk..((ci + 1) * chunk).min(np);
            let mut vinv = Vec::with_capacity(range.len());
            let mut scratch = ReduceScratch::default();
            for i in range {
                vinv.push(self.reduce_point(n, i, lambda, s, &mut rhs, &mut scratch)?);
            }
            Some((rhs, vinv))
        };
        let chunks = np.div_ceil(chunk).max(1);
        let partials = &mut buffers.partials;
        partials.resize_with(chunks, || Mat::zeros(0, 0));
        let parts: Vec<Option<ChunkRest>> = if chunks == 1 {
            vec![work(0, &mut partials[0])]
        } else {
            partials
                .par_iter_mut()
                .enumerate()
                .map(|(ci, s)| work(ci, s))
                .collect()
        };
        let mut s = damped_u(n, lambda, buffers.s.take());
        let mut rhs = n.bc.clone();
        let mut vinv = Vec::with_capacity(np);
        for (part, ps) in parts.into_iter().zip(&buffers.partials) {
            let (prhs, pv) = part?;
            for c in 0..nc {
                let (dst, src) = (s.col_as_slice_mut(c), ps.col_as_slice(c));
                for (d, x) in dst[c..].iter_mut().zip(&src[c..]) {
                    *d -= x;
                }
            }
            for (r, x) in rhs.iter_mut().zip(&prhs) {
                *r -= x;
            }
            vinv.extend(pv);
        }
        Some(Reduced {
            s,
            rhs,
            vinv,
            dense: None,
        })
    }

    /// [`Bundle::reduce`] for densely coupled networks (see [`super::dense_schur`]): the same
    /// system, with Σ W V⁻¹ Wᵀ as one matrix product.
    fn reduce_dense(
        &self,
        n: &Normals,
        lambda: f64,
        buffers: &mut ReduceBuffers,
    ) -> Option<Reduced> {
        let vinv = (0..n.v.len())
            .map(|i| self.point_inverse(n, i, lambda))
            .collect::<Option<Vec<_>>>()?;
        let mut rhs = n.bc.clone();
        let dense = super::dense_schur::couplings(n, &vinv, &mut rhs);
        let mut s = damped_u(n, lambda, buffers.s.take());
        super::dense_schur::subtract_product(&mut s, &dense);
        Some(Reduced {
            s,
            rhs,
            vinv,
            dense: Some(dense),
        })
    }

    /// (V_i + damping + gauge)⁻¹ of point i, or None when it is singular.
    #[inline(always)]
    fn point_inverse(&self, n: &Normals, i: usize, lambda: f64) -> Option<Matrix3<f64>> {
        let vi = &n.v[i];
        let mut vd = *vi;
        for k in 0..3 {
            vd[(k, k)] += lambda * vi[(k, k)].max(1e-300) + self.gauge;
        }
        vd.try_inverse()
    }

    /// Adds point i's W V⁻¹ Wᵀ (lower triangle) to `s` and W V⁻¹ b_p to `rhs`; returns the damped
    /// (V + gauge)⁻¹, or None when it is singular. Compiled for AVX2 as well, used where the
    /// processor has it: the same arithmetic element by element (no fused multiply-add), so the
    /// same result, with twice as wide vectors in the innermost loop.
    fn reduce_point(
        &self,
        n: &Normals,
        i: usize,
        lambda: f64,
        s: &mut Mat<f64>,
        rhs: &mut [f64],
        scratch: &mut ReduceScratch,
    ) -> Option<Matrix3<f64>> {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the processor supports AVX2 (checked above); the function is otherwise safe.
            return unsafe { self.reduce_point_avx2(n, i, lambda, s, rhs, scratch) };
        }
        self.reduce_point_body(n, i, lambda, s, rhs, scratch)
    }

    /// [`Bundle::reduce_point`] compiled for AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn reduce_point_avx2(
        &self,
        n: &Normals,
        i: usize,
        lambda: f64,
        s: &mut Mat<f64>,
        rhs: &mut [f64],
        scratch: &mut ReduceScratch,
    ) -> Option<Matrix3<f64>> {
        self.reduce_point_body(n, i, lambda, s, rhs, scratch)
    }

    #[inline(always)]
    fn reduce_point_body(
        &self,
        n: &Normals,
        i: usize,
        lambda: f64,
        s: &mut Mat<f64>,
        rhs: &mut [f64],
        scratch: &mut ReduceScratch,
    ) -> Option<Matrix3<f64>> {
        let inv = self.point_inverse(n, i, lambda)?;
        let wi = &n.w[i];
        let nw = wi.cols.len();
        // (W V⁻¹) by components, so that the update of a run of consecutive columns vectorizes.
        let wv = &mut scratch.wv;
        for c in wv.iter_mut() {
            c.clear();
        }
        for r in &wi.rows {
            let z = inv * r;
            for (c, zk) in wv.iter_mut().zip(z.iter()) {
                c.push(*zk);
            }
        }
        for (a, &ca) in wi.cols.iter().enumerate() {
            rhs[ca] += wv[0][a] * n.bp[i].x + wv[1][a] * n.bp[i].y + wv[2][a] * n.bp[i].z;
        }
        // S[ca, cb] += (W V⁻¹)_a · W_b for ca ≥ cb, column by column (subtracted by the caller).
        for (b, &cb) in wi.cols.iter().enumerate() {
            let rb = wi.rows[b];
            let col = s.col_as_slice_mut(cb);
            if wi.sorted {
                let mut a = b;
                while a < nw {
                    let end = wi.run_end[a];
                    let g = wi.cols[a];
                    add_run(
                        &mut col[g..g + (end - a)],
                        [&wv[0][a..end], &wv[1][a..end], &wv[2][a..end]],
                        [rb.x, rb.y, rb.z],
                    );
                    a = end;
                }
            } else {
                for (a, &ca) in wi.cols.iter().enumerate() {
                    if ca >= cb {
                        col[ca] += wv[0][a] * rb.x + wv[1][a] * rb.y + wv[2][a] * rb.z;
                    }
                }
            }
        }
        Some(inv)
    }

    /// Solves the damped normal equations: (Δ camera unknowns, Δ points). None if not positive
    /// definite or not finite. Works in the dense matrices of `buffers`, which keep them for the
    /// next solve.
    pub fn solve(
        &self,
        n: &Normals,
        lambda: f64,
        buffers: &mut ReduceBuffers,
    ) -> Option<(Vec<f64>, Vec<Vector3<f64>>)> {
        let r = self.reduce_with(n, lambda, buffers)?;
        let nc = r.rhs.len();
        let mut dc = Mat::<f64>::zeros(nc, 1);
        for k in 0..nc {
            dc[(k, 0)] = r.rhs[k];
        }
        if nc > 0 {
            let l = super::dense::cholesky_in_place(r.s)?;
            super::dense::solve_in_place(&l, &mut dc);
            buffers.s = Some(l);
        }
        let dcv: Vec<f64> = (0..nc).map(|k| dc[(k, 0)]).collect();
        if dcv.iter().any(|v| !v.is_finite()) {
            return None;
        }
        let dp: Vec<Vector3<f64>> = (0..n.v.len())
            .map(|i| {
                let wi = &n.w[i];
                let mut b = n.bp[i];
                for (a, &ca) in wi.cols.iter().enumerate() {
                    b -= wi.rows[a] * dcv[ca];
                }
                r.vinv[i] * b
            })
            .collect();
        if dp.iter().flatten().any(|v| !v.is_finite()) {
            return None;
        }
        Some((dcv, dp))
    }

    /// Applies an update (rotations multiplicatively).
    pub fn apply(&mut self, dc: &[f64], dp: &[Vector3<f64>]) {
        for (j, im) in self.images.iter_mut().enumerate() {
            let d = &dc[6 * j..6 * j + 6];
            im.rotation = crate::photogrammetry::model::rotation::update(
                &im.rotation,
                Vector3::new(d[0], d[1], d[2]),
            );
            for k in 0..3 {
                im.p[k] += d[3 + k];
            }
        }
        let icols = self.interior_columns();
        for (cam, cols) in icols.iter().enumerate() {
            for k in 0..8 {
                if let Some(g) = cols[k] {
                    self.interior[cam][k] += dc[g];
                }
            }
        }
        for (x, d) in self.points.iter_mut().zip(dp) {
            *x += d;
        }
    }
}

/// `dst[k] += z[0][k] r[0] + z[1][k] r[1] + z[2][k] r[2]` over a run of consecutive columns of the
/// Schur complement: the innermost loop of [`Bundle::reduce`], written over slices of one length so
/// that it vectorizes.
#[inline(always)]
fn add_run(dst: &mut [f64], z: [&[f64]; 3], r: [f64; 3]) {
    let n = dst.len();
    let (z0, z1, z2) = (&z[0][..n], &z[1][..n], &z[2][..n]);
    for k in 0..n {
        dst[k] += z0[k] * r[0] + z1[k] * r[1] + z2[k] * r[2];
    }
}

/// One observation's terms of the normal equations from its Jacobian rows `f` (local columns
/// `cols`, at most N; weight `p`): JᵀPJ and JᵀPe of its image and interior columns added to `acc`,
/// its point block and right-hand side to `v` and `bp`; returns its coupling rows
/// (∂e/∂column)ᵀ P ∂e/∂point, one per local column.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn observation_terms<const N: usize>(
    f: &[Dual<LOCAL>; 2],
    cols: &[(usize, usize)],
    p: f64,
    image: usize,
    cam: usize,
    acc: &mut CameraBlocks,
    v: &mut Matrix3<f64>,
    bp: &mut Vector3<f64>,
) -> [Vector3<f64>; N] {
    let n = cols.len();
    let mut wrows = [Vector3::zeros(); N];
    // The observation's two rows summed in a local lower triangle first, then added to U once.
    let mut jtj = [[0.0f64; N]; N];
    let mut jte = [0.0f64; N];
    for fk in f {
        let e = fk.v;
        let jp = Vector3::new(fk.d[POINT0], fk.d[POINT0 + 1], fk.d[POINT0 + 2]);
        *v += p * jp * jp.transpose();
        *bp -= p * e * jp;
        let d: [f64; N] = std::array::from_fn(|a| if a < n { fk.d[cols[a].1] } else { 0.0 });
        for a in 0..N {
            let pja = p * d[a];
            jte[a] += pja * e;
            for b in 0..=a {
                jtj[a][b] += pja * d[b];
            }
            wrows[a] += pja * jp;
        }
    }
    acc.add(image, cam, &jtj, &jte, cols);
    wrows
}

/// Rows of a smaller local column count padded to the largest.
fn pad<const N: usize>(rows: [Vector3<f64>; N]) -> [Vector3<f64>; 14] {
    let mut out = [Vector3::zeros(); 14];
    out[..N].copy_from_slice(&rows);
    out
}

/// U with Marquardt damping λ on its diagonal (scaled by the diagonal, floored at 1e-14 of its
/// largest element), in the memory of `buffer` when it has the size.
fn damped_u(n: &Normals, lambda: f64, buffer: Option<Mat<f64>>) -> Mat<f64> {
    let nc = n.bc.len();
    let mut s = match buffer {
        Some(mut b) if b.nrows() == nc && b.ncols() == nc => {
            b.copy_from(&n.u);
            b
        }
        _ => n.u.clone(),
    };
    let umax = (0..nc).map(|k| n.u[(k, k)]).fold(0.0, f64::max);
    for k in 0..nc {
        let d = n.u[(k, k)].max(umax * 1e-14).max(1e-300);
        s[(k, k)] += lambda * d;
    }
    s
}

/// One chunk's Σ W V⁻¹ b_p and its points' (V + gauge)⁻¹ (its Σ W V⁻¹ Wᵀ is in its buffer).
type ChunkRest = (Vec<f64>, Vec<Matrix3<f64>>);

/// Dense matrices of the reduction kept from one solve to the next (see [`Bundle::solve`]):
/// the chunks' partial sums of Σ W V⁻¹ Wᵀ and S itself (then its Cholesky factor), which would
/// otherwise be allocated, and faulted in, anew for every solve (2.9 MB each for 600 camera
/// unknowns).
#[derive(Default)]
pub struct ReduceBuffers {
    partials: Vec<Mat<f64>>,
    s: Option<Mat<f64>>,
}

/// Buffers reused across the points of [`Bundle::reduce`].
#[derive(Default)]
struct ReduceScratch {
    wv: [Vec<f64>; 3],
}

/// Observations per chunk of the parallel cost evaluation.
const COST_CHUNK: usize = 4096;
