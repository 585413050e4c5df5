//! Datum of an epoch: the S-transformation of the coordinate differences onto datum points.
//!
//! Every epoch is a free-network adjustment, so its coordinates carry an arbitrary small similarity
//! (shift, rotation, scale of ~mm) relative to the reference epoch. The differences `d = x_cur − x_ref` are
//! transformed by `d' = d − G (GᵀWG)⁻¹ GᵀW d_S` (the S-transformation of Baarda 1973; see Caspary 1987,
//! *Concepts of Network and Deformation Analysis*, ch. 5, and Niemeier 2008, *Ausgleichungsrechnung*, ch. 12):
//! `G` holds the linearised Helmert rows at the reference coordinates, `W` weights only the datum points.
//! - Stable points known: `W = Σ_dS⁻¹`, the inverse covariance of their differences (both epochs).
//! - No stable point: iterative weighted similarity transformation, IWST (Chen 1983; Chen, Chrzanowski &
//!   Secord 1990), which minimises Σ|d'_j|/σ_j: weights `1/(σ_j · max(|d'_j|, ε σ_j))` iterated, so that moving
//!   points do not drag the datum.
//!
//! The covariance of the transformed differences is propagated in full:
//! `Σ'_ij = Σ_ij − G_i A Σ_Sj − (G_j A Σ_Si)ᵀ + G_i A Σ_SS Aᵀ G_jᵀ` with `A = (GᵀWG)⁻¹GᵀW`, per
//! point (i = j) and between the points of a block. Cross covariances come from the joint
//! covariances of both epochs where given, else they are taken as zero. The reference epoch's
//! errors alone, propagated the same way, give the share every epoch has in common.
//! Units inside: coordinates (for G) in m, differences in mm, covariances in mm².

use std::collections::HashMap;

use nalgebra::{DMatrix, DVector, Matrix3, SMatrix, SVector, Vector3};

use super::epoch::{DatumTransformation, EpochCoordinates};
use super::error::AnalysisError;
use super::linalg::{sym_inverse, NULL_RELATIVE};

/// Coordinate differences of the points common to two epochs, with everything needed for the covariances.
#[derive(Debug, Clone)]
pub(crate) struct Differences {
    /// Names of the common points.
    pub names: Vec<String>,
    /// Reference coordinates in m.
    pub xyz_m: Vec<Vector3<f64>>,
    /// Differences current − reference in mm.
    pub d_mm: Vec<Vector3<f64>>,
    /// Covariance of each difference in mm² (sum of both epochs).
    pub cov_mm2: Vec<Matrix3<f64>>,
    /// The reference epoch's share of `cov_mm2` (mm²).
    ref_cov_mm2: Vec<Matrix3<f64>>,
    /// For each common point, its index in the reference / current joint covariance.
    joint_ref: Vec<Option<usize>>,
    joint_cur: Vec<Option<usize>>,
    ref_matrix: Option<(usize, Vec<f64>)>,
    cur_matrix: Option<(usize, Vec<f64>)>,
}

fn check_finite(what: &str, xs: impl IntoIterator<Item = f64>) -> Result<(), AnalysisError> {
    if xs.into_iter().all(f64::is_finite) {
        Ok(())
    } else {
        Err(AnalysisError::NonFinite {
            what: what.to_string(),
        })
    }
}

/// A joint covariance in mm²: (dimension, row-major elements).
type JointMatrix = Option<(usize, Vec<f64>)>;

fn joint_index(
    epoch: &EpochCoordinates,
) -> Result<(HashMap<&str, usize>, JointMatrix), AnalysisError> {
    match &epoch.joint {
        None => Ok((HashMap::new(), None)),
        Some(j) => {
            let n = 3 * j.points.len();
            if j.matrix_m2.len() != n * n {
                return Err(AnalysisError::BadJointCovariance {
                    len: j.matrix_m2.len(),
                    expected: n * n,
                });
            }
            check_finite(
                &format!("joint covariance of epoch {}", epoch.epoch),
                j.matrix_m2.iter().copied(),
            )?;
            let idx = j
                .points
                .iter()
                .enumerate()
                .map(|(i, p)| (p.as_str(), i))
                .collect();
            Ok((
                idx,
                Some((n, j.matrix_m2.iter().map(|v| v * 1e6).collect())),
            ))
        }
    }
}

impl Differences {
    /// Matches the points of both epochs by name (in the order of the current epoch).
    pub fn new(
        reference: &EpochCoordinates,
        current: &EpochCoordinates,
    ) -> Result<Self, AnalysisError> {
        let by_name: HashMap<&str, usize> = reference
            .points
            .iter()
            .enumerate()
            .map(|(i, p)| (p.name.as_str(), i))
            .collect();
        let (jr, ref_matrix) = joint_index(reference)?;
        let (jc, cur_matrix) = joint_index(current)?;
        let mut out = Differences {
            names: vec![],
            xyz_m: vec![],
            d_mm: vec![],
            cov_mm2: vec![],
            ref_cov_mm2: vec![],
            joint_ref: vec![],
            joint_cur: vec![],
            ref_matrix,
            cur_matrix,
        };
        for c in &current.points {
            let Some(&ri) = by_name.get(c.name.as_str()) else {
                continue;
            };
            let r = &reference.points[ri];
            for (p, e) in [(c, current.epoch), (r, reference.epoch)] {
                check_finite(
                    &format!("point {} of epoch {e}", p.name),
                    p.xyz_m
                        .iter()
                        .chain(p.covariance_m2.iter().flatten())
                        .copied(),
                )?;
            }
            let xr = Vector3::from(r.xyz_m);
            let xc = Vector3::from(c.xyz_m);
            let cm = |m: &[[f64; 3]; 3]| Matrix3::from_fn(|i, j| 0.5 * (m[i][j] + m[j][i]) * 1e6);
            out.names.push(c.name.clone());
            out.xyz_m.push(xr);
            out.d_mm.push((xc - xr) * 1e3);
            out.cov_mm2
                .push(cm(&c.covariance_m2) + cm(&r.covariance_m2));
            out.ref_cov_mm2.push(cm(&r.covariance_m2));
            out.joint_ref.push(jr.get(c.name.as_str()).copied());
            out.joint_cur.push(jc.get(c.name.as_str()).copied());
        }
        Ok(out)
    }

    /// The same differences with the reference epoch's errors alone (its covariances and joint
    /// covariance): propagated by the datum's transformation ([`transform_all`],
    /// [`transformed_joint`]) they give the share of each displacement's covariance that every
    /// epoch analysed against this reference has in common.
    pub fn reference_only(&self) -> Differences {
        Differences {
            names: self.names.clone(),
            xyz_m: self.xyz_m.clone(),
            d_mm: self.d_mm.clone(),
            cov_mm2: self.ref_cov_mm2.clone(),
            ref_cov_mm2: self.ref_cov_mm2.clone(),
            joint_ref: self.joint_ref.clone(),
            joint_cur: vec![None; self.names.len()],
            ref_matrix: self.ref_matrix.clone(),
            cur_matrix: None,
        }
    }

    /// Number of common points.
    pub fn len(&self) -> usize {
        self.names.len()
    }

    /// Whether point i has cross covariances with other points.
    pub fn in_joint(&self, i: usize) -> bool {
        self.joint_ref[i].is_some() || self.joint_cur[i].is_some()
    }

    /// Covariance block (mm²) between the differences of points i and j.
    pub fn cross(&self, i: usize, j: usize) -> Matrix3<f64> {
        if i == j {
            return self.cov_mm2[i];
        }
        let mut m = Matrix3::zeros();
        for (idx, mat) in [
            (&self.joint_ref, &self.ref_matrix),
            (&self.joint_cur, &self.cur_matrix),
        ] {
            if let (Some(a), Some(b), Some((n, v))) = (idx[i], idx[j], mat) {
                for r in 0..3 {
                    for c in 0..3 {
                        m[(r, c)] += v[(3 * a + r) * n + 3 * b + c];
                    }
                }
            }
        }
        m
    }
}

/// Helmert rows (3 × u) of a point at `p` (m, relative to the centroid): translation, rotation about X,
/// Y, Z (in mm per m = mrad), scale (mm per m).
pub(crate) fn helmert_rows(p: &Vector3<f64>, u: usize) -> DMatrix<f64> {
    let (x, y, z) = (p.x, p.y, p.z);
    #[rustfmt::skip]
    let full = [
        [1.0, 0.0, 0.0, 0.0, z, -y, x],
        [0.0, 1.0, 0.0, -z, 0.0, x, y],
        [0.0, 0.0, 1.0, y, -x, 0.0, z],
    ];
    DMatrix::from_fn(3, u, |r, c| full[r][c])
}

/// How the datum was defined.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DatumMethod {
    /// S-transformation onto the (congruent) stable points, weighted by their covariance.
    StablePoints,
    /// Iterative weighted similarity transformation over all common points.
    Iwst,
}

/// A fitted datum: the transformation parameters and the matrix `A = (GᵀWG)⁻¹GᵀW` over the datum points.
#[derive(Debug, Clone)]
pub(crate) struct DatumFit {
    /// Indices (into [`Differences`]) of the datum points.
    pub datum: Vec<usize>,
    /// Centroid of the datum points (m) the Helmert rows refer to.
    pub centroid: Vector3<f64>,
    /// Parameters (mm, mrad, mm/m).
    pub params: DVector<f64>,
    /// u × 3m.
    pub a: DMatrix<f64>,
    /// Weighted sum of squared residuals vᵀWv (the congruence statistic Ω when W = Σ⁻¹).
    pub omega: f64,
    /// Rank of W minus u: degrees of freedom of Ω.
    pub redundancy: usize,
    /// u.
    pub u: usize,
}

fn centroid(diffs: &Differences, datum: &[usize]) -> Vector3<f64> {
    let mut c = Vector3::zeros();
    for &i in datum {
        c += diffs.xyz_m[i];
    }
    c / datum.len().max(1) as f64
}

fn design(
    diffs: &Differences,
    datum: &[usize],
    c: &Vector3<f64>,
    u: usize,
) -> (DMatrix<f64>, DVector<f64>) {
    let m = datum.len();
    let mut g = DMatrix::zeros(3 * m, u);
    let mut d = DVector::zeros(3 * m);
    for (k, &i) in datum.iter().enumerate() {
        g.view_mut((3 * k, 0), (3, u))
            .copy_from(&helmert_rows(&(diffs.xyz_m[i] - c), u));
        for r in 0..3 {
            d[3 * k + r] = diffs.d_mm[i][r];
        }
    }
    (g, d)
}

/// Joint covariance (mm²) of the differences of the datum points.
pub(crate) fn datum_covariance(diffs: &Differences, datum: &[usize]) -> DMatrix<f64> {
    let m = datum.len();
    let mut s = DMatrix::zeros(3 * m, 3 * m);
    for (k, &i) in datum.iter().enumerate() {
        for (l, &j) in datum.iter().enumerate() {
            if k == l || (diffs.in_joint(i) && diffs.in_joint(j)) {
                s.view_mut((3 * k, 3 * l), (3, 3))
                    .copy_from(&diffs.cross(i, j));
            }
        }
    }
    s
}

/// θ = (GᵀWG)⁻¹GᵀW d and A = (GᵀWG)⁻¹GᵀW.
fn solve(
    g: &DMatrix<f64>,
    w: &DMatrix<f64>,
    d: &DVector<f64>,
) -> Result<(DVector<f64>, DMatrix<f64>), AnalysisError> {
    let gtw = g.transpose() * w;
    let n = &gtw * g;
    let ch = n.cholesky().ok_or_else(|| AnalysisError::Singular {
        what: "the datum points do not determine the transformation (collinear or too few)".into(),
    })?;
    let a = ch.solve(&gtw);
    let p = &a * d;
    Ok((p, a))
}

/// Share of a direction outside the Helmert motions (`‖(I − P_G) v‖`, v a unit eigenvector)
/// below which it counts as one of them: 5e-7 to 2e-4 where it was one (the eigenvector of a
/// rounding-level eigenvalue is itself known to about that).
const IN_HELMERT_SPAN: f64 = 1e-2;

/// Weight, relative to the largest of `w`, given to a direction of the differences without
/// variance that is a Helmert motion (about the inverse of the smallest eigenvalue a Cholesky
/// factor of such a covariance kept: 1e-8 of the largest).
const EXACT_WEIGHT: f64 = 1e8;

/// The weights of the transformation's fit: `w` (the pseudo-inverse of the differences'
/// covariance `cov`), with every direction of `cov` without variance that is a Helmert motion
/// weighted as known exactly. Such a direction arises when a rigid motion moves the datum
/// points alone (a rotation about the line through collinear monitored points, under a free
/// network's inner constraints): its differences are exact, but the pseudo-inverse gives them
/// no weight, GᵀWG is then singular up to rounding and the fit took the rounding for a
/// rotation of tens of mrad (a stable point 0.3 m off, a false "stable point moved"). A
/// Cholesky inverse of the same covariance, when rounding left its eigenvalue positive, gave
/// the right answer by weighting it ~1e8 times: so does this, whichever the sign. Also returns
/// how many directions it weighted so.
fn fit_weights(cov: &DMatrix<f64>, w: &DMatrix<f64>, g: &DMatrix<f64>) -> (DMatrix<f64>, usize) {
    let eig = cov.clone().symmetric_eigen();
    let max = eig.eigenvalues.iter().cloned().fold(0.0, f64::max);
    let Some(gtg) = (g.transpose() * g).cholesky() else {
        return (w.clone(), 0);
    };
    let w_max = w.diagonal().iter().cloned().fold(0.0, f64::max);
    let mut out = w.clone();
    let mut exact = 0;
    for (k, &l) in eig.eigenvalues.iter().enumerate() {
        // The directions the pseudo-inverse `w` left without weight.
        if l > NULL_RELATIVE * max {
            continue;
        }
        let v = eig.eigenvectors.column(k);
        let in_span = g * gtg.solve(&(g.transpose() * v));
        if (v - in_span).norm() < IN_HELMERT_SPAN {
            out += (v * v.transpose()) * (EXACT_WEIGHT * w_max);
            exact += 1;
        }
    }
    (out, exact)
}

/// S-transformation onto `datum` weighted by the inverse covariance of their differences.
pub(crate) fn fit_weighted(
    diffs: &Differences,
    datum: &[usize],
    kind: DatumTransformation,
) -> Result<DatumFit, AnalysisError> {
    let u = kind.parameters();
    if datum.len() < kind.min_points() {
        return Err(AnalysisError::TooFewDatumPoints {
            found: datum.len(),
            needed: kind.min_points(),
        });
    }
    let c = centroid(diffs, datum);
    let (g, d) = design(diffs, datum, &c, u);
    let cov = datum_covariance(diffs, datum);
    let (w, rank) = sym_inverse(&cov).ok_or_else(|| AnalysisError::Singular {
        what: "covariance of the datum points' differences".into(),
    })?;
    // Directions known exactly are observations too: each spends the parameter it fixes.
    let ((p, a), exact) = if rank < 3 * datum.len() {
        let (w_fit, exact) = fit_weights(&cov, &w, &g);
        (solve(&g, &w_fit, &d)?, exact)
    } else {
        (solve(&g, &w, &d)?, 0)
    };
    let v = &d - &g * &p;
    let omega = (v.transpose() * &w * &v)[(0, 0)];
    Ok(DatumFit {
        datum: datum.to_vec(),
        centroid: c,
        params: p,
        a,
        omega,
        redundancy: (rank + exact).saturating_sub(u),
        u,
    })
}

/// IWST over `datum`: L1 (Σ|d'|/σ) fit by iteratively reweighted least squares.
pub(crate) fn fit_iwst(
    diffs: &Differences,
    datum: &[usize],
    kind: DatumTransformation,
    max_iterations: usize,
) -> Result<DatumFit, AnalysisError> {
    let u = kind.parameters();
    if datum.len() < kind.min_points() {
        return Err(AnalysisError::TooFewDatumPoints {
            found: datum.len(),
            needed: kind.min_points(),
        });
    }
    let c = centroid(diffs, datum);
    let (g, d) = design(diffs, datum, &c, u);
    let sigma: Vec<f64> = datum
        .iter()
        .flat_map(|&i| (0..3).map(move |r| diffs.cov_mm2[i][(r, r)].max(1e-18).sqrt()))
        .collect();
    let n = d.len();
    let mut w = DVector::from_fn(n, |j, _| 1.0 / (sigma[j] * sigma[j]));
    let mut p = DVector::zeros(u);
    let mut last = None;
    for _ in 0..max_iterations.max(1) {
        // GᵀW with W diagonal: scale the columns of Gᵀ (no dense 3m × 3m matrix).
        let mut gtw = g.transpose();
        for (j, mut col) in gtw.column_iter_mut().enumerate() {
            col *= w[j];
        }
        let ch = (&gtw * &g)
            .cholesky()
            .ok_or_else(|| AnalysisError::Singular {
                what: "the datum points do not determine the transformation (collinear or too few)"
                    .into(),
            })?;
        // θ = (GᵀWG)⁻¹ GᵀW d; A itself only for the weights of the last iteration.
        let p_new = ch.solve(&(&gtw * &d));
        let change = (&p_new - &p).amax();
        p = p_new;
        last = Some((ch, gtw));
        let v = &d - &g * &p;
        for j in 0..n {
            w[j] = 1.0 / (sigma[j] * v[j].abs().max(1e-3 * sigma[j]));
        }
        if change < 1e-4 {
            break;
        }
    }
    let a = last.map_or_else(|| DMatrix::zeros(u, n), |(ch, gtw)| ch.solve(&gtw));
    Ok(DatumFit {
        datum: datum.to_vec(),
        centroid: c,
        params: p,
        a,
        omega: f64::NAN,
        redundancy: 0,
        u,
    })
}

/// The covariance propagation of the S-transformation `d'_i = d_i − G_i θ`, `θ = A d_S`
/// (Caspary 1987 §5.3): `Σ_ij' = Σ_ij − G_i A Σ_Sj − (G_j A Σ_Si)ᵀ + G_i A Σ_SS Aᵀ G_jᵀ`, with `S`
/// the datum points. [`transform_all`] takes the 3 × 3 blocks of every point,
/// [`transformed_joint`] the full covariance of a few.
struct Propagation<'a> {
    diffs: &'a Differences,
    fit: &'a DatumFit,
    /// A split in u × 3 blocks per datum point, padded with zero rows to 7 × 3.
    a_blocks: Vec<SMatrix<f64, 7, 3>>,
    /// P = A Σ_SS Aᵀ (u × u, padded with zeros to 7 × 7).
    p: SMatrix<f64, 7, 7>,
    /// Positions (in the datum) of the datum points with cross covariances.
    joint: Vec<usize>,
    /// Position in the datum of each datum point (index into `diffs`).
    pos_in_datum: HashMap<usize, usize>,
}

/// Helmert rows G_i of a point (3 × u, padded with zero columns to 3 × 7), and A Σ_Si (u × 3,
/// padded likewise): what [`Propagation::block`] needs of a point.
type PointTerms = (SMatrix<f64, 3, 7>, SMatrix<f64, 7, 3>);

impl<'a> Propagation<'a> {
    fn new(diffs: &'a Differences, fit: &'a DatumFit) -> Self {
        let (u, m) = (fit.u, fit.datum.len());
        let a_blocks: Vec<SMatrix<f64, 7, 3>> = (0..m)
            .map(|k| SMatrix::from_fn(|r, c| if r < u { fit.a[(r, 3 * k + c)] } else { 0.0 }))
            .collect();
        // P = A Σ_SS Aᵀ, exploiting block sparsity.
        let mut p = SMatrix::<f64, 7, 7>::zeros();
        let joint: Vec<usize> = (0..m).filter(|&k| diffs.in_joint(fit.datum[k])).collect();
        for (ab, &i) in a_blocks.iter().zip(&fit.datum) {
            p += ab * diffs.cov_mm2[i] * ab.transpose();
        }
        for &k in &joint {
            let mut row = SMatrix::<f64, 7, 3>::zeros();
            for &l in &joint {
                if k != l {
                    row += a_blocks[l] * diffs.cross(fit.datum[l], fit.datum[k]);
                }
            }
            p += row * a_blocks[k].transpose();
        }
        let pos_in_datum = fit.datum.iter().enumerate().map(|(k, &i)| (i, k)).collect();
        Propagation {
            diffs,
            fit,
            a_blocks,
            p,
            joint,
            pos_in_datum,
        }
    }

    /// Helmert rows G_i (3 × u, padded) of point i.
    fn g(&self, i: usize) -> SMatrix<f64, 3, 7> {
        let rows = helmert_rows(&(self.diffs.xyz_m[i] - self.fit.centroid), self.fit.u);
        SMatrix::from_fn(|r, c| if c < self.fit.u { rows[(r, c)] } else { 0.0 })
    }

    /// A Σ_Si (u × 3, padded): the covariance of the parameters with the difference of point i.
    fn a_sigma(&self, i: usize) -> SMatrix<f64, 7, 3> {
        let (diffs, fit) = (self.diffs, self.fit);
        let mut asi = SMatrix::<f64, 7, 3>::zeros();
        if diffs.in_joint(i) {
            for &k in &self.joint {
                asi += self.a_blocks[k] * diffs.cross(fit.datum[k], i);
            }
            if let Some(&k) = self.pos_in_datum.get(&i) {
                if !diffs.in_joint(fit.datum[k]) {
                    asi += self.a_blocks[k] * diffs.cov_mm2[i];
                }
            }
        } else if let Some(&k) = self.pos_in_datum.get(&i) {
            asi += self.a_blocks[k] * diffs.cov_mm2[i];
        }
        asi
    }

    /// G_i and A Σ_Si of point i.
    fn terms(&self, i: usize) -> PointTerms {
        (self.g(i), self.a_sigma(i))
    }

    /// Σ_ij' (3 × 3) from the Helmert rows and A Σ_S of both points.
    fn block(
        &self,
        (i, (gi, asi)): (usize, &PointTerms),
        (j, (gj, asj)): (usize, &PointTerms),
    ) -> Matrix3<f64> {
        let gpg = gi * self.p * gj.transpose();
        self.diffs.cross(i, j) - gi * asj - (gj * asi).transpose() + gpg
    }
}

/// Transformed difference (mm) and its covariance (mm²) of every common point.
pub(crate) fn transform_all(
    diffs: &Differences,
    fit: &DatumFit,
) -> Vec<(Vector3<f64>, Matrix3<f64>)> {
    let prop = Propagation::new(diffs, fit);
    let params = SVector::<f64, 7>::from_fn(|r, _| if r < fit.u { fit.params[r] } else { 0.0 });
    (0..diffs.len())
        .map(|i| {
            let terms = prop.terms(i);
            let d = diffs.d_mm[i] - terms.0 * params;
            let cov = prop.block((i, &terms), (i, &terms));
            (d, 0.5 * (cov + cov.transpose()))
        })
        .collect()
}

/// The joint covariance (mm², 3k × 3k, symmetric) of the transformed differences of the points
/// `members` (indices into `diffs`, k of them), in their order: the cross-covariances the datum
/// and the epochs' joint covariances put between them.
pub(crate) fn transformed_joint(
    diffs: &Differences,
    fit: &DatumFit,
    members: &[usize],
) -> DMatrix<f64> {
    let prop = Propagation::new(diffs, fit);
    let parts: Vec<(usize, PointTerms)> = members.iter().map(|&i| (i, prop.terms(i))).collect();
    let k = members.len();
    let mut out = DMatrix::<f64>::zeros(3 * k, 3 * k);
    for (a, (i, ti)) in parts.iter().enumerate() {
        for (b, (j, tj)) in parts.iter().enumerate().skip(a) {
            let c = prop.block((*i, ti), (*j, tj));
            for r in 0..3 {
                for col in 0..3 {
                    out[(3 * a + r, 3 * b + col)] = c[(r, col)];
                    out[(3 * b + col, 3 * a + r)] = c[(r, col)];
                }
            }
        }
    }
    out
}
