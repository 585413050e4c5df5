//! Dense Cholesky factorization, solve and inverse of the reduced (image and interior) normal
//! equations with faer, single-threaded below [`PARALLEL_MIN_DIM`] unknowns: for the small systems
//! of a monitoring epoch (tens of unknowns) waking the thread pool costs more than the work.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt;
use faer::{Conj, Mat, Par};

/// Order of the system from which faer may use its thread pool.
pub const PARALLEL_MIN_DIM: usize = 256;

/// The parallelism for a system of `n` unknowns.
fn par(n: usize) -> Par {
    if n >= PARALLEL_MIN_DIM {
        faer::get_global_parallelism()
    } else {
        Par::Seq
    }
}

/// Lower Cholesky factor L (A = L Lᵀ) of the symmetric matrix whose lower triangle is `a`; None if
/// it is not positive definite.
pub fn cholesky(a: &Mat<f64>) -> Option<Mat<f64>> {
    let n = a.nrows();
    let mut l = Mat::<f64>::zeros(n, n);
    l.copy_from_triangular_lower(a);
    cholesky_in_place(l)
}

/// [`cholesky`] in the memory of `a` (only its lower triangle is read; the factor is its lower
/// triangle, the upper one is left as it was).
pub fn cholesky_in_place(mut a: Mat<f64>) -> Option<Mat<f64>> {
    let n = a.nrows();
    let p = par(n);
    let mut mem = MemBuffer::new(llt::factor::cholesky_in_place_scratch::<f64>(
        n,
        p,
        Default::default(),
    ));
    let stack = MemStack::new(&mut mem);
    llt::factor::cholesky_in_place(a.as_mut(), Default::default(), p, stack, Default::default())
        .ok()?;
    Some(a)
}

/// Solves A x = b in place (b: one or more columns) from the factor of [`cholesky`].
pub fn solve_in_place(l: &Mat<f64>, b: &mut Mat<f64>) {
    let n = l.nrows();
    let p = par(n);
    let mut mem = MemBuffer::new(llt::solve::solve_in_place_scratch::<f64>(n, b.ncols(), p));
    let stack = MemStack::new(&mut mem);
    llt::solve::solve_in_place_with_conj(l.as_ref(), Conj::No, b.as_mut(), p, stack);
}

/// A⁻¹ (full, symmetric) from the factor of [`cholesky`].
pub fn inverse(l: &Mat<f64>) -> Mat<f64> {
    let n = l.nrows();
    let p = par(n);
    let mut out = Mat::<f64>::zeros(n, n);
    let mut mem = MemBuffer::new(llt::inverse::inverse_scratch::<f64>(n, p));
    let stack = MemStack::new(&mut mem);
    llt::inverse::inverse(out.as_mut(), l.as_ref(), p, stack);
    // faer fills the lower triangle; mirror it.
    for j in 0..n {
        for i in 0..j {
            out[(i, j)] = out[(j, i)];
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inverse_and_solve_of_a_spd_matrix() {
        for n in [1usize, 5, 40, 300] {
            let mut a = Mat::<f64>::zeros(n, n);
            for i in 0..n {
                for j in 0..n {
                    a[(i, j)] = 1.0 / (1.0 + (i as f64 - j as f64).abs());
                }
                a[(i, i)] += n as f64;
            }
            let l = cholesky(&a).expect("positive definite");
            let inv = inverse(&l);
            let prod = &a * &inv;
            for i in 0..n {
                for j in 0..n {
                    let e = if i == j { 1.0 } else { 0.0 };
                    assert!((prod[(i, j)] - e).abs() < 1e-12, "n {n} ({i},{j})");
                }
            }
            let mut b = Mat::<f64>::from_fn(n, 1, |i, _| i as f64);
            solve_in_place(&l, &mut b);
            let back = &a * &b;
            for i in 0..n {
                assert!((back[(i, 0)] - i as f64).abs() < 1e-9 * n as f64);
            }
        }
        // In place, with garbage above the diagonal (the reduction leaves U's values there).
        let n = 40;
        let mut a = Mat::<f64>::zeros(n, n);
        for i in 0..n {
            for j in 0..=i {
                a[(i, j)] = 1.0 / (1.0 + (i as f64 - j as f64).abs());
            }
            a[(i, i)] += n as f64;
            for j in i + 1..n {
                a[(i, j)] = 1e30;
            }
        }
        let full = Mat::<f64>::from_fn(n, n, |i, j| a[(i.max(j), i.min(j))]);
        let l = cholesky_in_place(a).expect("positive definite");
        let mut b = Mat::<f64>::from_fn(n, 1, |i, _| i as f64);
        solve_in_place(&l, &mut b);
        let back = &full * &b;
        for i in 0..n {
            assert!((back[(i, 0)] - i as f64).abs() < 1e-9 * n as f64);
        }
        let mut bad = Mat::<f64>::identity(3, 3);
        bad[(2, 2)] = -1.0;
        assert!(cholesky(&bad).is_none());
    }
}
