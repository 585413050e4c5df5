//! The normal equations of the bundle as stored: the dense image/interior block, the 3 × 3 point
//! blocks and the sparse couplings between them, and how the work on them is split across
//! threads. Built by [`super::normals`], reduced there or by [`super::dense_schur`].

use faer::Mat;
use nalgebra::{Matrix3, Vector3};

/// Coupling W_i of one point with the image/interior unknowns: sparse rows (global column, 1 × 3).
#[derive(Debug, Clone, Default)]
pub struct Coupling {
    /// Global columns.
    pub cols: Vec<usize>,
    /// The rows of W_i (∂e/∂camera)ᵀ P (∂e/∂point) for those columns.
    pub rows: Vec<Vector3<f64>>,
    /// Whether `cols` ascend (then the Schur complement visits only its lower triangle's pairs).
    pub sorted: bool,
    /// End (exclusive) of the run of consecutive global columns that holds each entry of `cols`:
    /// the Schur complement and the cofactors work run by run.
    pub run_end: Vec<usize>,
}

impl Coupling {
    pub(crate) fn add(&mut self, col: usize, row: Vector3<f64>) {
        if let Some(k) = self.cols.iter().rposition(|&c| c == col) {
            self.rows[k] += row;
        } else {
            self.cols.push(col);
            self.rows.push(row);
        }
    }
}

/// Normal equations `[U W; Wᵀ V] [Δc; Δp] = [bc; bp]` (weights 1/σ²) and the weighted square sum.
#[derive(Debug, Clone)]
pub struct Normals {
    /// Image and interior block (dense).
    pub u: Mat<f64>,
    /// Right-hand side of the image and interior unknowns.
    pub bc: Vec<f64>,
    /// 3 × 3 point blocks.
    pub v: Vec<Matrix3<f64>>,
    /// Right-hand sides of the points.
    pub bp: Vec<Vector3<f64>>,
    /// Couplings per point.
    pub w: Vec<Coupling>,
}

/// Observations below which the normal equations are built on the calling thread only (the rayon
/// pool's overhead would exceed the gain).
pub const PARALLEL_MIN_OBSERVATIONS: usize = 2_000;

/// Points per chunk of parallel work: all of them for small networks, else two chunks per thread
/// of the rayon pool (each chunk carries a dense matrix of the camera unknowns).
pub fn chunk_len(points: usize, observations: usize) -> usize {
    if observations < PARALLEL_MIN_OBSERVATIONS || rayon::current_num_threads() < 2 {
        points.max(1)
    } else {
        points.div_ceil(2 * rayon::current_num_threads()).max(1)
    }
}
