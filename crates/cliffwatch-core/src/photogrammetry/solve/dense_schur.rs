//! The Schur complement of densely coupled networks as matrix products: where the points see most
//! images (a monitoring epoch of a few images, every target in all of them), `Σ_i W_i V_i⁻¹ W_iᵀ`
//! is one product of two dense matrices of the camera unknowns × 3 · points, which faer's blocked
//! kernels form many times faster than the point-by-point updates of [`super::normals`], and the
//! cofactors' `Q_cc W_i` likewise.

use faer::linalg::matmul::matmul;
use faer::linalg::matmul::triangular::{self, BlockStructure};
use faer::{Accum, Mat, Par};
use nalgebra::{Matrix3, Vector3};

use super::normal_equations::{Normals, PARALLEL_MIN_OBSERVATIONS};

/// Mean share of the camera unknowns that a point couples with, from which the reduction runs as
/// matrix products (below it the products would multiply mostly zeros).
pub const DENSE_COUPLING: f64 = 0.5;

/// Whether the couplings of `n` (a network of `observations` observations) are dense enough for
/// the products. Only where the point-by-point reduction would run on one thread: from
/// [`PARALLEL_MIN_OBSERVATIONS`] on it runs in parallel chunks and the products, single-threaded,
/// would not be faster.
pub fn is_dense(n: &Normals, observations: usize) -> bool {
    let nc = n.bc.len();
    let np = n.w.len();
    if nc == 0 || np == 0 || observations >= PARALLEL_MIN_OBSERVATIONS {
        return false;
    }
    let entries: usize = n.w.iter().map(|w| w.cols.len()).sum();
    entries as f64 >= DENSE_COUPLING * (nc * np) as f64
}

/// The couplings W (camera unknowns × 3 · points; columns 3i..3i+3 are W_i) and W V⁻¹ alike.
pub struct DenseCouplings {
    /// W: rows are camera unknowns, columns 3i + k the k-th point coordinate of point i.
    pub w: Mat<f64>,
    /// W V⁻¹ (V_i⁻¹ the damped inverse of each point block).
    pub wv: Mat<f64>,
}

/// Builds W and W V⁻¹ from the couplings and the point inverses `vinv`, and subtracts
/// `W V⁻¹ b_p` from `rhs` (the reduction of [`Bundle::reduce`](crate::photogrammetry::model::bundle::Bundle::reduce) for dense couplings).
pub fn couplings(n: &Normals, vinv: &[Matrix3<f64>], rhs: &mut [f64]) -> DenseCouplings {
    let nc = n.bc.len();
    let np = n.w.len();
    let mut w = Mat::<f64>::zeros(nc, 3 * np);
    let mut wv = Mat::<f64>::zeros(nc, 3 * np);
    for (i, (wi, inv)) in n.w.iter().zip(vinv).enumerate() {
        for (&ca, r) in wi.cols.iter().zip(&wi.rows) {
            // Row a of W_i V_i⁻¹ is (V_i⁻¹ r)ᵀ (V_i symmetric).
            let z: Vector3<f64> = inv * r;
            rhs[ca] -= z.dot(&n.bp[i]);
            for k in 0..3 {
                w[(ca, 3 * i + k)] += r[k];
                wv[(ca, 3 * i + k)] += z[k];
            }
        }
    }
    DenseCouplings { w, wv }
}

/// `s ← s − W V⁻¹ Wᵀ` on the lower triangle of `s` (the upper is left as it is).
pub fn subtract_product(s: &mut Mat<f64>, d: &DenseCouplings) {
    triangular::matmul(
        s.as_mut(),
        BlockStructure::TriangularLower,
        Accum::Add,
        d.wv.as_ref(),
        BlockStructure::Rectangular,
        d.w.transpose(),
        BlockStructure::Rectangular,
        -1.0,
        Par::Seq,
    );
}

/// `Q W` (camera unknowns × 3 · points) for the symmetric cofactor matrix `q` of the camera
/// unknowns: row c of columns 3i..3i+3 is `Σ_x Q[c, c_x] W_i,x`, what the cofactors of point i and
/// its observations need.
pub fn cofactor_product(q: &Mat<f64>, w: &Mat<f64>) -> Mat<f64> {
    let mut out = Mat::<f64>::zeros(q.nrows(), w.ncols());
    matmul(
        out.as_mut(),
        Accum::Replace,
        q.as_ref(),
        w.as_ref(),
        1.0,
        Par::Seq,
    );
    out
}

#[cfg(test)]
mod tests {
    use super::super::normal_equations::Coupling;
    use super::*;

    /// The products equal the point-by-point sums they replace.
    #[test]
    fn products_equal_point_sums() {
        let nc = 7;
        let np = 4;
        let mut w = Vec::new();
        let mut vinv = Vec::new();
        let mut bp = Vec::new();
        for i in 0..np {
            let cols: Vec<usize> = (0..nc).filter(|c| (c + i) % 3 != 0).collect();
            let rows: Vec<Vector3<f64>> = cols
                .iter()
                .map(|&c| Vector3::new(c as f64 + 0.5, i as f64 - 1.0, (c * i) as f64 * 0.1))
                .collect();
            w.push(Coupling {
                run_end: vec![0; cols.len()],
                sorted: true,
                cols,
                rows,
            });
            let a = Matrix3::new(2.0, 0.1, 0.0, 0.3, 1.5, 0.2, 0.0, 0.1, 3.0 + i as f64);
            vinv.push(a * a.transpose());
            bp.push(Vector3::new(1.0, -2.0, 0.5 * i as f64));
        }
        let n = Normals {
            u: Mat::zeros(nc, nc),
            bc: vec![0.0; nc],
            v: vec![Matrix3::identity(); np],
            bp,
            w,
        };
        let mut rhs = vec![0.0; nc];
        let d = couplings(&n, &vinv, &mut rhs);
        let mut s = Mat::<f64>::zeros(nc, nc);
        subtract_product(&mut s, &d);
        let q = Mat::<f64>::from_fn(nc, nc, |r, c| 1.0 / (1.0 + r as f64 + c as f64));
        let qw = cofactor_product(&q, &d.w);
        let mut want = Mat::<f64>::zeros(nc, nc);
        let mut want_rhs = vec![0.0; nc];
        for i in 0..np {
            let wi = &n.w[i];
            for (a, &ca) in wi.cols.iter().enumerate() {
                let z = vinv[i] * wi.rows[a];
                want_rhs[ca] -= z.dot(&n.bp[i]);
                for (b, &cb) in wi.cols.iter().enumerate() {
                    want[(ca, cb)] -= z.dot(&wi.rows[b]);
                }
                for row in 0..nc {
                    for k in 0..3 {
                        let v = qw[(row, 3 * i + k)];
                        let sum: f64 = (0..wi.cols.len())
                            .map(|x| q[(row, wi.cols[x])] * wi.rows[x][k])
                            .sum();
                        assert!((v - sum).abs() < 1e-12 * (1.0 + sum.abs()));
                    }
                }
            }
        }
        for r in 0..nc {
            assert!((rhs[r] - want_rhs[r]).abs() < 1e-12 * (1.0 + want_rhs[r].abs()));
            for c in 0..=r {
                assert!(
                    (s[(r, c)] - want[(r, c)]).abs() < 1e-12 * (1.0 + want[(r, c)].abs()),
                    "({r},{c}): {} vs {}",
                    s[(r, c)],
                    want[(r, c)]
                );
            }
        }
    }
}
