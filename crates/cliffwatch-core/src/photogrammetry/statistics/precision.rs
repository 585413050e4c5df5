//! Precision of the adjusted unknowns from the inverse of the normal equations (cofactors Q), the
//! redundancy numbers of the observations, and the S-transformation of the free network's point
//! covariances to the inner constraints (minimum trace): `Q_S = S Q Sᵀ`, `S = I − G (GᵀG)⁻¹ Gᵀ`.

use faer::Mat;
use nalgebra::{Matrix2, Matrix3, SMatrix, Vector3};

use crate::photogrammetry::model::bundle::{Bundle, Obs, LOCAL, POINT0};
use crate::photogrammetry::model::dual::Dual;
use crate::photogrammetry::solve::normal_equations::{Normals, PARALLEL_MIN_OBSERVATIONS};
use rayon::prelude::*;

/// Points per block of the datum projection's parallel sum (see `Cofactors::datum_projection`).
const DATUM_BLOCK_POINTS: usize = 256;

type G = SMatrix<f64, 3, 7>;
type M7 = SMatrix<f64, 7, 7>;

/// S⁻¹ restricted to the local camera columns of one image's observations (see
/// [`Cofactors::image_block`]).
pub struct ImageBlock {
    /// (global column, local lane) of each local column; the first `n` are used.
    cols: [(usize, usize); 14],
    n: usize,
    /// S⁻¹[cols, cols].
    q: [[f64; 14]; 14],
}

/// Cofactor blocks of the final solution (a-priori scale; multiply by the variance factor).
pub struct Cofactors {
    normals: Normals,
    /// S⁻¹: cofactors of the image and interior unknowns.
    pub qcc: Mat<f64>,
    vinv: Vec<Matrix3<f64>>,
    /// Raw diagonal point blocks Q_ii (before the datum projection), computed once.
    qpp: Vec<Matrix3<f64>>,
    /// Per point i, `Σ_x S⁻¹[c, c_x] W_i,x` for each of its coupling columns c (aligned with
    /// `normals.w[i].cols`): shared by Q_ii and the cofactors of its observations.
    qw: Vec<Vec<Vector3<f64>>>,
    /// Datum projection for the free network: (G_i per point, C = (GᵀG)⁻¹, H_i = Q G, M = GᵀQG).
    datum: Option<(Vec<G>, M7, Vec<G>, M7)>,
}

impl Cofactors {
    /// Inverts normal equations already built at the bundle's state (those of the last, negligible
    /// step of the adjustment). `free_network` applies the S-transform to the inner constraints
    /// (about the centroid of the points) to every point cofactor block.
    pub fn from_normals(b: &Bundle, normals: Normals, free_network: bool) -> Option<Self> {
        let reduced = b.reduce(&normals, 0.0)?;
        let nc = reduced.rhs.len();
        let qcc = if nc > 0 {
            crate::photogrammetry::solve::dense::inverse(
                &crate::photogrammetry::solve::dense::cholesky(&reduced.s)?,
            )
        } else {
            Mat::zeros(0, 0)
        };
        let mut cof = Cofactors {
            normals,
            qcc,
            vinv: reduced.vinv,
            qpp: Vec::new(),
            qw: Vec::new(),
            datum: None,
        };
        let blocks: Vec<(Matrix3<f64>, Vec<Vector3<f64>>)> = if let Some(d) = &reduced.dense {
            let qw = crate::photogrammetry::solve::dense_schur::cofactor_product(&cof.qcc, &d.w);
            (0..b.points.len())
                .map(|i| cof.diagonal_block_from(i, &qw))
                .collect()
        } else if b.obs.len() < PARALLEL_MIN_OBSERVATIONS {
            (0..b.points.len()).map(|i| cof.diagonal_block(i)).collect()
        } else {
            (0..b.points.len())
                .into_par_iter()
                .map(|i| cof.diagonal_block(i))
                .collect()
        };
        (cof.qpp, cof.qw) = blocks.into_iter().unzip();
        if free_network {
            cof.datum =
                Some(cof.datum_projection(&b.points, b.obs.len() >= PARALLEL_MIN_OBSERVATIONS)?);
        }
        Some(cof)
    }

    fn datum_projection(
        &self,
        points: &[Vector3<f64>],
        parallel: bool,
    ) -> Option<(Vec<G>, M7, Vec<G>, M7)> {
        let n = points.len() as f64;
        let centroid = points.iter().fold(Vector3::zeros(), |a, p| a + p) / n;
        let extent = (points
            .iter()
            .map(|p| (p - centroid).norm_squared())
            .sum::<f64>()
            / n)
            .sqrt()
            .max(1e-9);
        let gs: Vec<G> = points
            .iter()
            .map(|p| {
                let x = (p - centroid) / extent;
                G::from_row_slice(&[
                    1.0, 0.0, 0.0, 0.0, x.z, -x.y, x.x, //
                    0.0, 1.0, 0.0, -x.z, 0.0, x.x, x.y, //
                    0.0, 0.0, 1.0, x.y, -x.x, 0.0, x.z,
                ])
            })
            .collect();
        let gtg: M7 = gs.iter().map(|g| g.transpose() * g).sum();
        let c = gtg.try_inverse()?;
        // B = Σ_j W_j V_j⁻¹ G_j (nc × 7), T = S⁻¹ B.
        let nc = self.qcc.nrows();
        let add_points = |mut bm: Vec<[f64; 7]>, (j, g): (usize, &G)| {
            let vg = self.vinv[j] * g;
            let w = &self.normals.w[j];
            for (a, &ca) in w.cols.iter().enumerate() {
                let row = w.rows[a].transpose() * vg;
                for k in 0..7 {
                    bm[ca][k] += row[k];
                }
            }
            bm
        };
        let bm: Vec<[f64; 7]> = if parallel {
            // Fixed blocks of points summed in order, so that the result does not depend on how
            // the threads shared the work: the same network gives the same σ on every run.
            let partials: Vec<Vec<[f64; 7]>> = gs
                .par_chunks(DATUM_BLOCK_POINTS)
                .enumerate()
                .map(|(ci, block)| {
                    let first = ci * DATUM_BLOCK_POINTS;
                    block
                        .iter()
                        .enumerate()
                        .map(|(k, g)| (first + k, g))
                        .fold(vec![[0.0f64; 7]; nc], add_points)
                })
                .collect();
            let mut sum = vec![[0.0f64; 7]; nc];
            for part in &partials {
                for (x, y) in sum.iter_mut().zip(part) {
                    for k in 0..7 {
                        x[k] += y[k];
                    }
                }
            }
            sum
        } else {
            gs.iter()
                .enumerate()
                .fold(vec![[0.0f64; 7]; nc], add_points)
        };
        // S⁻¹ is symmetric: its row r is its column r, read contiguously.
        let row_of_t = |r: usize| {
            let q = self.qcc.col_as_slice(r);
            let mut tr = [0.0f64; 7];
            for (qs, bs) in q.iter().zip(&bm) {
                for k in 0..7 {
                    tr[k] += qs * bs[k];
                }
            }
            tr
        };
        let t: Vec<[f64; 7]> = if parallel {
            (0..nc).into_par_iter().map(row_of_t).collect()
        } else {
            (0..nc).map(row_of_t).collect()
        };
        let h_of = |(i, g): (usize, &G)| {
            let mut inner = *g;
            let w = &self.normals.w[i];
            for (a, &ca) in w.cols.iter().enumerate() {
                for k in 0..7 {
                    for r in 0..3 {
                        inner[(r, k)] += w.rows[a][r] * t[ca][k];
                    }
                }
            }
            self.vinv[i] * inner
        };
        let hs: Vec<G> = if parallel {
            gs.par_iter().enumerate().map(h_of).collect()
        } else {
            gs.iter().enumerate().map(h_of).collect()
        };
        let m: M7 = gs.iter().zip(&hs).map(|(g, h)| g.transpose() * h).sum();
        Some((gs, c, hs, m))
    }

    /// Raw diagonal block Q_ii of point i (before the datum projection) and its `S⁻¹ W_i` products
    /// (see the field `qw`).
    fn diagonal_block(&self, i: usize) -> (Matrix3<f64>, Vec<Vector3<f64>>) {
        let w = &self.normals.w[i];
        let n = w.cols.len();
        // qw[y] = Σ_x S⁻¹[c_x, c_y] W_x, summed over x in order; S⁻¹ is symmetric, so row c_x over
        // the run is a slice of its column c_x and each step is a plain (vectorized) update.
        let mut acc = [vec![0.0; n], vec![0.0; n], vec![0.0; n]];
        for (&cx, r) in w.cols.iter().zip(&w.rows) {
            let qc = self.qcc.col_as_slice(cx);
            let mut s = 0;
            while s < n {
                let (g, e) = (w.cols[s], w.run_end[s]);
                let q = &qc[g..g + (e - s)];
                let [a0, a1, a2] = &mut acc;
                let (a0, a1, a2) = (&mut a0[s..e], &mut a1[s..e], &mut a2[s..e]);
                for k in 0..q.len() {
                    a0[k] += q[k] * r.x;
                    a1[k] += q[k] * r.y;
                    a2[k] += q[k] * r.z;
                }
                s = e;
            }
        }
        let qw: Vec<Vector3<f64>> = (0..n)
            .map(|y| Vector3::new(acc[0][y], acc[1][y], acc[2][y]))
            .collect();
        self.block_of(i, qw)
    }

    /// Q_ii = V⁻¹ + V⁻¹ Wᵢᵀ S⁻¹ Wᵢ V⁻¹ of point i from its `S⁻¹ W_i` products `qw`, returned with them.
    fn block_of(&self, i: usize, qw: Vec<Vector3<f64>>) -> (Matrix3<f64>, Vec<Vector3<f64>>) {
        let inner = qw
            .iter()
            .zip(&self.normals.w[i].rows)
            .fold(Matrix3::zeros(), |m, (t, r)| m + t * r.transpose());
        let q = self.vinv[i] * inner * self.vinv[i] + self.vinv[i];
        (q, qw)
    }

    /// [`Cofactors::diagonal_block`] from `Q W` of all points (see
    /// [`crate::photogrammetry::solve::dense_schur::cofactor_product`]).
    fn diagonal_block_from(
        &self,
        i: usize,
        qw_all: &Mat<f64>,
    ) -> (Matrix3<f64>, Vec<Vector3<f64>>) {
        let w = &self.normals.w[i];
        let cols = [0, 1, 2].map(|k| qw_all.col_as_slice(3 * i + k));
        let qw: Vec<Vector3<f64>> = w
            .cols
            .iter()
            .map(|&c| Vector3::new(cols[0][c], cols[1][c], cols[2][c]))
            .collect();
        self.block_of(i, qw)
    }

    /// Raw cofactor block Q_ab of points a and b (before the datum projection).
    fn raw_point_block(&self, a: usize, b: usize) -> Matrix3<f64> {
        if a == b && !self.qpp.is_empty() {
            return self.qpp[a];
        }
        let (wa, wb) = (&self.normals.w[a], &self.normals.w[b]);
        // Σ_x Σ_y Q(cx, cy) wa_x wb_yᵀ, one column of Q at a time.
        let mut inner = Matrix3::zeros();
        for (y, &cy) in wb.cols.iter().enumerate() {
            let q = self.qcc.col_as_slice(cy);
            let mut t = Vector3::zeros();
            for (x, &cx) in wa.cols.iter().enumerate() {
                t += q[cx] * wa.rows[x];
            }
            inner += t * wb.rows[y].transpose();
        }
        let mut q = self.vinv[a] * inner * self.vinv[b];
        if a == b {
            q += self.vinv[a];
        }
        q
    }

    /// Cofactor block of points a and b (m², a-priori scale) in the datum of the solution.
    pub fn point_block(&self, a: usize, b: usize) -> Matrix3<f64> {
        let q = self.raw_point_block(a, b);
        match &self.datum {
            None => q,
            Some((gs, c, hs, m)) => {
                q - gs[a] * c * hs[b].transpose() - hs[a] * c * gs[b].transpose()
                    + gs[a] * c * m * c * gs[b].transpose()
            }
        }
    }

    /// The cofactor blocks (m², a-priori scale, datum of the solution) of every pair of the points
    /// `chosen`, row by row: element `a * chosen.len() + b` is [`Cofactors::point_block`] of
    /// `chosen[a]` and `chosen[b]`. Forms `S⁻¹ W_b` once per point (camera columns × 3) instead of
    /// once per pair, and the datum terms `G_a C` and `(H_a − G_a C M) C` once per point, so n points
    /// cost O(n · columns²) + O(n² · columns) rather than O(n² · columns²).
    pub fn point_blocks(&self, chosen: &[usize]) -> Vec<Matrix3<f64>> {
        let n = chosen.len();
        let nc = self.qcc.nrows();
        // U_b = S⁻¹ W_b: for each camera column, the 3-vector Σ_y S⁻¹[c, c_y] W_b,y.
        let u: Vec<Vec<Vector3<f64>>> = chosen
            .iter()
            .map(|&b| {
                let w = &self.normals.w[b];
                let mut acc = [vec![0.0; nc], vec![0.0; nc], vec![0.0; nc]];
                for (&cy, r) in w.cols.iter().zip(&w.rows) {
                    let q = self.qcc.col_as_slice(cy);
                    let [a0, a1, a2] = &mut acc;
                    for (k, &qk) in q.iter().enumerate() {
                        a0[k] += qk * r.x;
                        a1[k] += qk * r.y;
                        a2[k] += qk * r.z;
                    }
                }
                (0..nc)
                    .map(|k| Vector3::new(acc[0][k], acc[1][k], acc[2][k]))
                    .collect()
            })
            .collect();
        let raw = |a: usize, b: usize| {
            let (pa, pb) = (chosen[a], chosen[b]);
            if pa == pb && !self.qpp.is_empty() {
                return self.qpp[pa];
            }
            let wa = &self.normals.w[pa];
            let inner = wa
                .cols
                .iter()
                .zip(&wa.rows)
                .fold(Matrix3::zeros(), |m, (&cx, r)| m + r * u[b][cx].transpose());
            let mut q = self.vinv[pa] * inner * self.vinv[pb];
            if pa == pb {
                q += self.vinv[pa];
            }
            q
        };
        // Q_ab − G_a C H_bᵀ − H_a C G_bᵀ + G_a C M C G_bᵀ = Q_ab − (G_a C) H_bᵀ − (H_a C − G_a C M C) G_bᵀ.
        let datum: Option<Vec<(G, G, G, G)>> = self.datum.as_ref().map(|(gs, c, hs, m)| {
            chosen
                .iter()
                .map(|&p| {
                    let gc = gs[p] * c;
                    (gc, hs[p] * c - gc * m * c, gs[p], hs[p])
                })
                .collect()
        });
        let mut out = vec![Matrix3::zeros(); n * n];
        for a in 0..n {
            for b in a..n {
                let mut q = raw(a, b);
                if let Some(d) = &datum {
                    let ((gc_a, k_a, _, _), (_, _, g_b, h_b)) = (&d[a], &d[b]);
                    q -= gc_a * h_b.transpose() + k_a * g_b.transpose();
                }
                out[a * n + b] = q;
                out[b * n + a] = q.transpose();
            }
        }
        out
    }

    /// Camera part of `N⁻¹ [bc; bp]` for sparse right-hand sides (global column or point index and
    /// value): `S⁻¹ (b_c − Σ W V⁻¹ b_p)`.
    pub fn solve_cameras(&self, bc: &[(usize, f64)], bp: &[(usize, Vector3<f64>)]) -> Vec<f64> {
        let n = &self.normals;
        let mut rhs: Vec<(usize, f64)> = bc.to_vec();
        for &(i, b) in bp {
            let vb = self.vinv[i] * b;
            let w = &n.w[i];
            for (a, &ca) in w.cols.iter().enumerate() {
                rhs.push((ca, -w.rows[a].dot(&vb)));
            }
        }
        let mut dc = vec![0.0; self.qcc.nrows()];
        for (s, r) in rhs {
            if r != 0.0 {
                for (d, q) in dc.iter_mut().zip(self.qcc.col_as_slice(s)) {
                    *d += q * r;
                }
            }
        }
        dc
    }

    /// Point `i`'s part of the solution whose camera part is `cams` and point right-hand side the
    /// sparse `bp` (ascending by point index, one entry per point): `V_i⁻¹ (b_p,i − W_i x_c)`.
    pub fn point_of(&self, cams: &[f64], bp: &[(usize, Vector3<f64>)], i: usize) -> Vector3<f64> {
        let w = &self.normals.w[i];
        // `bp` ascends by point index (one entry per point).
        let mut b = match bp.binary_search_by_key(&i, |(p, _)| *p) {
            Ok(k) => bp[k].1,
            Err(_) => Vector3::zeros(),
        };
        for (a, &ca) in w.cols.iter().enumerate() {
            b -= w.rows[a] * cams[ca];
        }
        self.vinv[i] * b
    }

    /// Every point's part of that solution (see [`Cofactors::point_of`]).
    pub fn points_of(&self, cams: &[f64], bp: &[(usize, Vector3<f64>)]) -> Vec<Vector3<f64>> {
        let n = &self.normals;
        let mut dense = vec![Vector3::zeros(); n.v.len()];
        for &(i, v) in bp {
            dense[i] += v;
        }
        let point = |i: usize| {
            let w = &n.w[i];
            let mut b = dense[i];
            for (a, &ca) in w.cols.iter().enumerate() {
                b -= w.rows[a] * cams[ca];
            }
            self.vinv[i] * b
        };
        if n.v.len() < PARALLEL_MIN_OBSERVATIONS / 10 {
            (0..n.v.len()).map(point).collect()
        } else {
            (0..n.v.len()).into_par_iter().map(point).collect()
        }
    }

    /// Cofactor of interior parameter at global column `col`.
    pub fn camera_cofactor(&self, col: usize) -> f64 {
        self.qcc[(col, col)]
    }

    /// a Q aᵀ of the x and y equations of an observation (2 × 2, mm² at a-priori scale): the
    /// cofactor of its adjusted (predicted) value. Datum-invariant, so the raw cofactors serve.
    pub fn predicted_cofactor(&self, b: &Bundle, o: &Obs) -> Matrix2<f64> {
        let cam = b.image_camera[o.image];
        let block = self.image_block(o.image, &b.interior_lanes()[cam]);
        self.predicted_cofactor_of(o, &b.jacobian(o), &block)
    }

    /// S⁻¹ restricted to the local camera columns of an image's observations (its six, then its
    /// camera's free interior parameters, see [`Bundle::interior_lanes`]): the same for all of them.
    pub fn image_block(&self, image: usize, interior_lanes: &[(usize, usize)]) -> ImageBlock {
        let mut cols = [(0usize, 0usize); 14];
        for (l, c) in cols.iter_mut().enumerate().take(6) {
            *c = (6 * image + l, l);
        }
        let n = 6 + interior_lanes.len();
        cols[6..n].copy_from_slice(interior_lanes);
        let mut q = [[0.0f64; 14]; 14];
        for (x, &(gx, _)) in cols[..n].iter().enumerate() {
            let col = self.qcc.col_as_slice(gx);
            for (y, &(gy, _)) in cols[..n].iter().enumerate() {
                q[x][y] = col[gy];
            }
        }
        ImageBlock { cols, n, q }
    }

    /// [`Cofactors::predicted_cofactor`] from the observation's Jacobian `f` and its image's
    /// [`Cofactors::image_block`].
    pub fn predicted_cofactor_of(
        &self,
        o: &Obs,
        f: &[Dual<LOCAL>; 2],
        block: &ImageBlock,
    ) -> Matrix2<f64> {
        let n = block.n;
        let cols = &block.cols[..n];
        let qsub = &block.q;
        let i = o.point;
        let w = &self.normals.w[i];
        let qpp = self.qpp[i];
        let vinv = self.vinv[i];
        // S⁻¹[g, ·] W_i for each local column g, kept per point for the columns the point couples
        // with (an inactive observation's image may not be one of them). The image's six columns
        // are consecutive among the point's when it holds them: one search for the six.
        let image_run = w
            .sorted
            .then(|| w.cols.binary_search(&(6 * o.image)).ok())
            .flatten()
            .filter(|&a| a + 5 < w.cols.len() && w.cols[a + 5] == 6 * o.image + 5);
        let mut sw = [Vector3::zeros(); 14];
        for (x, &(g, _)) in cols.iter().enumerate() {
            let found = match image_run {
                Some(a0) if x < 6 => Some(a0 + x),
                _ if w.sorted => w.cols.binary_search(&g).ok(),
                _ => w.cols.iter().position(|&c| c == g),
            };
            sw[x] = match found {
                Some(a) => self.qw[i][a],
                None => {
                    // Q is symmetric: row g is column g.
                    let q = self.qcc.col_as_slice(g);
                    w.cols
                        .iter()
                        .zip(&w.rows)
                        .fold(Vector3::zeros(), |t, (&ca, r)| t + q[ca] * r)
                }
            };
        }
        // Per row k: the point part j_p, the local camera part j, (Σ_x j_x S⁻¹W_x), V⁻¹ j_p and
        // S⁻¹ j (local columns only).
        let mut jp = [Vector3::zeros(); 2];
        let mut j = [[0.0f64; 14]; 2];
        let mut cross = [Vector3::zeros(); 2];
        let mut vj = [Vector3::zeros(); 2];
        let mut qj = [[0.0f64; 14]; 2];
        for (k, fk) in f.iter().enumerate() {
            jp[k] = Vector3::new(fk.d[POINT0], fk.d[POINT0 + 1], fk.d[POINT0 + 2]);
            vj[k] = vinv * jp[k];
            for x in 0..n {
                j[k][x] = fk.d[cols[x].1];
                cross[k] += j[k][x] * sw[x];
            }
            for x in 0..n {
                let row = &qsub[x];
                qj[k][x] = (0..n).map(|y| row[y] * j[k][y]).sum();
            }
        }
        // a_k Q a_lᵀ = j_pkᵀ Q_pp j_pl + j_k Q_cp j_pl + j_l Q_cp j_pk + j_k S⁻¹ j_l, with
        // Q_cp = −S⁻¹ W V⁻¹, so j_k Q_cp j_pl = −(Σ_x j_kx S⁻¹W_x) · (V⁻¹ j_pl).
        let entry = |k: usize, l: usize| {
            let camera: f64 = (0..n).map(|x| j[k][x] * qj[l][x]).sum();
            jp[k].dot(&(qpp * jp[l])) - cross[k].dot(&vj[l]) - cross[l].dot(&vj[k]) + camera
        };
        let xy = entry(0, 1);
        Matrix2::new(entry(0, 0), xy, xy, entry(1, 1))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::photogrammetry::test_support::bundle;
    use nalgebra::DMatrix;

    /// The datum projection of the free network comes out the same summed over the points on the
    /// thread pool as in one pass.
    #[test]
    fn datum_projection_is_the_same_in_parallel() {
        let b = bundle(12, 40, 3);
        let cof = Cofactors::from_normals(&b, b.normals(), false).expect("positive definite");
        let (g1, c1, h1, m1) = cof.datum_projection(&b.points, false).expect("regular");
        let (g2, c2, h2, m2) = cof.datum_projection(&b.points, true).expect("regular");
        // Summed in another order: equal to rounding, relative to the largest element.
        let differ = |a: &[f64], b: &[f64]| {
            let scale = a.iter().fold(0.0f64, |m, x| m.max(x.abs()));
            let d = a
                .iter()
                .zip(b)
                .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
            d / scale.max(1e-300)
        };
        assert!(m1.norm() > 0.0);
        assert_eq!(differ(c1.as_slice(), c2.as_slice()), 0.0);
        assert!(differ(m1.as_slice(), m2.as_slice()) < 1e-10);
        for (x, y) in g1.iter().zip(&g2).chain(h1.iter().zip(&h2)) {
            assert!(differ(x.as_slice(), y.as_slice()) < 1e-10);
        }
    }

    /// The blocks of a set of points formed together equal those formed pair by pair, with and
    /// without the datum projection, for a dense network and a sparse one.
    #[test]
    fn point_blocks_equal_point_block_pair_by_pair() {
        for (nimg, np, per_point) in [(4, 7, 4), (12, 40, 3)] {
            let b = bundle(nimg, np, per_point);
            for free in [false, true] {
                let cof = Cofactors::from_normals(&b, b.normals(), free).expect("regular");
                let chosen: Vec<usize> = (0..np).rev().step_by(2).chain([1]).collect();
                let blocks = cof.point_blocks(&chosen);
                let n = chosen.len();
                assert_eq!(blocks.len(), n * n);
                // Summed in another order: equal to rounding, relative to the blocks before the
                // datum projection (which cancels most of them).
                let scale = (0..np)
                    .map(|i| cof.raw_point_block(i, i).norm())
                    .fold(0.0f64, f64::max);
                for (a, &pa) in chosen.iter().enumerate() {
                    for (k, &pb) in chosen.iter().enumerate() {
                        let d = (blocks[a * n + k] - cof.point_block(pa, pb)).norm();
                        assert!(
                            d <= 1e-10 * scale,
                            "{nimg}×{np} free {free}: {pa},{pb} off by {d:e} of {scale:e}"
                        );
                    }
                }
            }
        }
    }

    /// a Q aᵀ of every observation, the point cofactor blocks and the camera cofactors equal those
    /// of the dense inverse of the whole normal matrix (gauge included), for a network reduced as a
    /// dense product (all points in all images) and one reduced point by point (each point in 3 of
    /// 12 images).
    #[test]
    fn cofactors_equal_the_dense_inverse() {
        for (nimg, np, per_point) in [(4, 7, 4), (12, 40, 3)] {
            let b = bundle(nimg, np, per_point);
            let n = b.normals();
            assert_eq!(
                crate::photogrammetry::solve::dense_schur::is_dense(&n, b.obs.len()),
                per_point == nimg
            );
            let nc = n.bc.len();
            let dim = nc + 3 * np;
            let mut full = DMatrix::<f64>::zeros(dim, dim);
            for r in 0..nc {
                for c in 0..nc {
                    full[(r, c)] = n.u[(r, c)];
                }
            }
            for i in 0..np {
                for r in 0..3 {
                    for c in 0..3 {
                        full[(nc + 3 * i + r, nc + 3 * i + c)] = n.v[i][(r, c)];
                    }
                    full[(nc + 3 * i + r, nc + 3 * i + r)] += b.gauge;
                }
                for (&col, row) in n.w[i].cols.iter().zip(&n.w[i].rows) {
                    for k in 0..3 {
                        full[(col, nc + 3 * i + k)] = row[k];
                        full[(nc + 3 * i + k, col)] = row[k];
                    }
                }
            }
            let q = full.clone().try_inverse().expect("invertible");
            let cof = Cofactors::from_normals(&b, n, false).expect("positive definite");
            let scale = q.diagonal().amax();
            let lanes = b.interior_lanes();
            for (k, o) in b.obs.iter().enumerate() {
                let f = b.jacobian(o);
                let got = cof.predicted_cofactor(&b, o);
                let rows = f.each_ref().map(|fk| {
                    let mut a = vec![0.0; dim];
                    for l in 0..6 {
                        a[6 * o.image + l] = fk.d[l];
                    }
                    for &(g, lane) in &lanes[0] {
                        a[g] = fk.d[lane];
                    }
                    for m in 0..3 {
                        a[nc + 3 * o.point + m] = fk.d[POINT0 + m];
                    }
                    nalgebra::DVector::from_vec(a)
                });
                for r in 0..2 {
                    for c in 0..2 {
                        let want = (rows[r].transpose() * &q * &rows[c])[0];
                        let scale = (got[(0, 0)] * got[(1, 1)]).sqrt();
                        assert!(
                            (got[(r, c)] - want).abs() <= 1e-7 * scale.max(1e-12),
                            "{nimg}×{np}, observation {k} ({r}, {c}): {} vs {want}",
                            got[(r, c)]
                        );
                    }
                }
            }
            for i in (0..np).step_by(3) {
                let block = cof.point_block(i, i);
                for r in 0..3 {
                    for c in 0..3 {
                        let want = q[(nc + 3 * i + r, nc + 3 * i + c)];
                        assert!((block[(r, c)] - want).abs() <= 1e-7 * scale);
                    }
                }
            }
            for c in 0..nc {
                let want = q[(c, c)];
                assert!((cof.camera_cofactor(c) - want).abs() <= 1e-7 * want.abs());
            }
        }
    }
}
