//! Exact alignment of an epoch onto the reference when their datums differ by more than the linear
//! S-transformation ([`super::datum`]) tolerates.
//!
//! A free network's datum follows its approximate coordinates (inner constraints), and the orthogonal
//! model with a free c does not fix the scale at all: a typo of 20 m in one approximation rotates and
//! scales the whole epoch by degrees and percent, while its shape (and σ0) stay the same. The
//! S-transformation's Helmert rows are linear in the rotation and scale, so such an epoch would leave
//! second-order residues of up to metres as false displacements. Two steps keep the analysis exact:
//! - **coarse**: a closed-form least-squares similarity (Umeyama 1991) of the current epoch onto the
//!   reference over the stable points (all common points when too few are stable), applied when its
//!   second-order effect exceeds [`COARSE_TOLERANCE_M`];
//! - **refine**: the fitted datum's own parameters, applied exactly (rotation by the exponential map)
//!   when their second-order effect exceeds [`FINE_TOLERANCE_M`], and the datum fitted again until
//!   it is below [`EXACT_TOLERANCE_M`].
//!
//! An ordinary epoch (datum differences of about 10⁻⁴) needs neither and is analysed as before.
//! Coordinates in m; the covariances move with the coordinates (Σ' = RᵀΣR / k²).

use std::collections::HashMap;

use nalgebra::{DVector, Matrix3, Rotation3, Vector3};

use super::epoch::{DatumTransformation, EpochCoordinates};
use crate::photogrammetry::model::frame::similarity_fit;
pub(crate) use crate::photogrammetry::model::frame::Similarity;

/// Second-order effect (m) above which the closed-form similarity is applied before the datum fit.
pub(crate) const COARSE_TOLERANCE_M: f64 = 1e-4;
/// Second-order effect (m) above which a fitted datum is applied exactly and fitted again.
pub(crate) const FINE_TOLERANCE_M: f64 = 1e-5;
/// Second-order effect (m) below which an aligned epoch's datum fit counts as exact.
pub(crate) const EXACT_TOLERANCE_M: f64 = 1e-9;

/// The datum's transformations are [`Similarity`]s x ↦ k R x + b (m), taking the reference frame
/// into the current epoch's.
impl Similarity {
    /// The identity.
    pub(crate) fn identity() -> Self {
        Similarity {
            scale: 1.0,
            rotation: Matrix3::identity(),
            translation: Vector3::zeros(),
        }
    }

    /// The exact transformation of linear datum parameters `params` (translation mm, rotations mrad,
    /// scale mm/m; 3, 6 or 7 of them, as in [`super::datum::helmert_rows`]) about `centroid` (m):
    /// x ↦ c + t + k R (x − c) with R = exp([ω]×), k = 1 + s.
    pub(crate) fn from_linear(params: &DVector<f64>, centroid: &Vector3<f64>) -> Self {
        let get = |k: usize| if k < params.len() { params[k] } else { 0.0 };
        let t = Vector3::new(get(0), get(1), get(2)) * 1e-3;
        let omega = Vector3::new(get(3), get(4), get(5)) * 1e-3;
        let rotation = *Rotation3::new(omega).matrix();
        let scale = 1.0 + get(6) * 1e-3;
        Similarity {
            scale,
            rotation,
            translation: centroid + t - scale * rotation * centroid,
        }
    }

    /// `self` after `inner`: x ↦ self(inner(x)).
    pub(crate) fn after(&self, inner: &Similarity) -> Similarity {
        Similarity {
            scale: self.scale * inner.scale,
            rotation: self.rotation * inner.rotation,
            translation: self.scale * self.rotation * inner.translation + self.translation,
        }
    }

    /// Rotation vector (axis × angle, rad): atan2 of the skew and symmetric parts, exact for small
    /// angles too (an arccosine of the trace loses half the digits there).
    pub(crate) fn rotation_vector(&self) -> Vector3<f64> {
        let r = &self.rotation;
        let sine = Vector3::new(
            r[(2, 1)] - r[(1, 2)],
            r[(0, 2)] - r[(2, 0)],
            r[(1, 0)] - r[(0, 1)],
        ) * 0.5;
        let (s, c) = (sine.norm(), (r.trace() - 1.0) * 0.5);
        if s > 0.0 {
            sine * (s.atan2(c) / s)
        } else {
            Vector3::zeros()
        }
    }

    /// Rotation angle in rad.
    pub(crate) fn angle(&self) -> f64 {
        self.rotation_vector().norm()
    }

    /// Largest difference (m) between this transformation and its linearisation, for points within
    /// `extent` m of the centroid: extent · (angle + |k − 1|)², an upper bound of the neglected terms.
    pub(crate) fn second_order_m(&self, extent: f64) -> f64 {
        extent * (self.angle() + (self.scale - 1.0).abs()).powi(2)
    }

    /// Rotation vector (mrad), scale difference (ppm) and the translation of `centroid` (mm): the form
    /// of [`super::epoch_analysis::DatumReport`].
    pub(crate) fn report_form(&self, centroid: &Vector3<f64>) -> ([f64; 3], [f64; 3], f64) {
        let omega = self.rotation_vector() * 1e3;
        let moved = self.scale * self.rotation * centroid + self.translation - centroid;
        let t = moved * 1e3;
        (
            [t.x, t.y, t.z],
            [omega.x, omega.y, omega.z],
            (self.scale - 1.0) * 1e6,
        )
    }
}

/// The least-squares similarity (rigid motion for [`DatumTransformation::Rigid`], translation for
/// [`DatumTransformation::Translation`]) taking `from` onto `to` (m, equal lengths), in closed form
/// (Umeyama 1991, with the reflection excluded). None when the points do not determine it.
pub(crate) fn closed_form(
    from: &[Vector3<f64>],
    to: &[Vector3<f64>],
    kind: DatumTransformation,
) -> Option<Similarity> {
    let n = from.len();
    if n == 0 || n != to.len() {
        return None;
    }
    let mean = |v: &[Vector3<f64>]| v.iter().sum::<Vector3<f64>>() / n as f64;
    let (mf, mt) = (mean(from), mean(to));
    if kind == DatumTransformation::Translation {
        return Some(Similarity {
            translation: mt - mf,
            ..Similarity::identity()
        });
    }
    // Collinear (or coincident) points leave the rotation undetermined.
    let scatter: Matrix3<f64> = from.iter().map(|f| (f - mf) * (f - mf).transpose()).sum();
    let mut spread: Vec<f64> = scatter.symmetric_eigenvalues().iter().copied().collect();
    spread.sort_by(|a, b| b.total_cmp(a));
    if !(spread[1] > 1e-12 * spread[0]) {
        return None;
    }
    let fit = similarity_fit(from, to)?;
    if !(fit.scale > 0.0) || !fit.scale.is_finite() {
        return None;
    }
    // The rotation of the least-squares fit does not depend on its scale.
    Some(match kind {
        DatumTransformation::Similarity => fit,
        _ => Similarity {
            scale: 1.0,
            rotation: fit.rotation,
            translation: mt - fit.rotation * mf,
        },
    })
}

/// The coarse similarity of `current` onto `reference` over the points named in `datum` (all common
/// points when fewer than `kind` needs are given), when its second-order effect exceeds
/// [`COARSE_TOLERANCE_M`]; None otherwise (or when the points do not determine it).
pub(crate) fn coarse(
    reference: &EpochCoordinates,
    current: &EpochCoordinates,
    datum: &[&str],
    kind: DatumTransformation,
) -> Option<Similarity> {
    let at: HashMap<&str, Vector3<f64>> = current
        .points
        .iter()
        .map(|p| (p.name.as_str(), Vector3::from(p.xyz_m)))
        .collect();
    let pairs = |only: Option<&[&str]>| -> (Vec<Vector3<f64>>, Vec<Vector3<f64>>) {
        reference
            .points
            .iter()
            .filter(|p| only.is_none_or(|names| names.contains(&p.name.as_str())))
            .filter_map(|p| Some((Vector3::from(p.xyz_m), *at.get(p.name.as_str())?)))
            .unzip()
    };
    let (mut from, mut to) = pairs(Some(datum));
    if from.len() < kind.min_points() {
        (from, to) = pairs(None);
    }
    let sim = closed_form(&from, &to, kind)?;
    let centre = from.iter().sum::<Vector3<f64>>() / from.len() as f64;
    let extent = from.iter().map(|x| (x - centre).norm()).fold(0.0, f64::max);
    (sim.second_order_m(extent) > COARSE_TOLERANCE_M).then_some(sim)
}

/// `current` brought back through `sim` (which takes the reference frame into the current one):
/// coordinates x' = Rᵀ(x − b)/k, covariances RᵀΣR/k², the joint covariance block by block.
pub(crate) fn undo(current: &EpochCoordinates, sim: &Similarity) -> EpochCoordinates {
    let rt = sim.rotation.transpose();
    let k = sim.scale;
    let cov = |m: &Matrix3<f64>| rt * m * sim.rotation / (k * k);
    let mut out = current.clone();
    for p in &mut out.points {
        let x = rt * (Vector3::from(p.xyz_m) - sim.translation) / k;
        p.xyz_m = x.into();
        let c = cov(&Matrix3::from_fn(|i, j| p.covariance_m2[i][j]));
        p.covariance_m2 = std::array::from_fn(|i| std::array::from_fn(|j| c[(i, j)]));
    }
    if let Some(joint) = &mut out.joint {
        let dim = 3 * joint.points.len();
        if joint.matrix_m2.len() == dim * dim {
            for a in 0..joint.points.len() {
                for b in 0..joint.points.len() {
                    let block =
                        Matrix3::from_fn(|i, j| joint.matrix_m2[(3 * a + i) * dim + 3 * b + j]);
                    let t = cov(&block);
                    for i in 0..3 {
                        for j in 0..3 {
                            joint.matrix_m2[(3 * a + i) * dim + 3 * b + j] = t[(i, j)];
                        }
                    }
                }
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn points() -> Vec<Vector3<f64>> {
        vec![
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(3.0, 0.2, -0.4),
            Vector3::new(-1.0, 2.5, 0.3),
            Vector3::new(0.5, -1.2, 1.1),
            Vector3::new(2.0, 2.0, -0.8),
        ]
    }

    fn truth() -> Similarity {
        Similarity {
            scale: 1.037,
            rotation: *Rotation3::new(Vector3::new(0.3, -0.2, 0.9)).matrix(),
            translation: Vector3::new(12.0, -3.0, 0.5),
        }
    }

    #[test]
    fn the_closed_form_recovers_a_large_similarity() {
        let t = truth();
        let from = points();
        let to: Vec<_> = from
            .iter()
            .map(|x| t.scale * t.rotation * x + t.translation)
            .collect();
        let s = closed_form(&from, &to, DatumTransformation::Similarity).expect("determined");
        assert!((s.scale - t.scale).abs() < 1e-12);
        assert!((s.rotation - t.rotation).norm() < 1e-12);
        assert!((s.translation - t.translation).norm() < 1e-10);
    }

    #[test]
    fn collinear_points_do_not_determine_a_rotation() {
        let from: Vec<_> = (0..4).map(|i| Vector3::new(i as f64, 0.0, 0.0)).collect();
        let to = from.clone();
        assert!(closed_form(&from, &to, DatumTransformation::Rigid).is_none());
    }

    #[test]
    fn linear_parameters_give_the_same_small_transformation() {
        // d = t + ω × (x − c) + s (x − c), the Helmert rows' model, to first order
        let p = DVector::from_vec(vec![1.0, -2.0, 0.5, 0.02, -0.01, 0.03, 0.015]);
        let c = Vector3::new(100.0, 50.0, 10.0);
        let sim = Similarity::from_linear(&p, &c);
        for x in points() {
            let x = x + c;
            let exact = sim.scale * sim.rotation * x + sim.translation - x;
            let r = x - c;
            let linear = (Vector3::new(1.0, -2.0, 0.5)
                + Vector3::new(0.02, -0.01, 0.03).cross(&r)
                + 0.015 * r)
                * 1e-3;
            // second-order terms: r (θ + s)² ≈ 3 m × (5 × 10⁻⁵)² ≈ 10⁻⁸ m
            assert!((exact - linear).norm() < 2e-8, "{exact} vs {linear}");
        }
        let (t, w, s) = sim.report_form(&c);
        assert!((t[0] - 1.0).abs() < 1e-9 && (t[1] + 2.0).abs() < 1e-9);
        assert!((w[2] - 0.03).abs() < 1e-9, "{w:?}");
        assert!((s - 15.0).abs() < 1e-6, "{s}");
    }

    #[test]
    fn undo_brings_back_coordinates_covariances_and_the_joint_covariance() {
        use crate::analysis::{JointCovarianceM2, PointCoordinates};
        let t = truth();
        let cov = |s: f64| {
            [
                [s, 0.3 * s, 0.0],
                [0.3 * s, 2.0 * s, 0.1 * s],
                [0.0, 0.1 * s, s],
            ]
        };
        let plain = EpochCoordinates {
            epoch: 2,
            observed_at: chrono::DateTime::UNIX_EPOCH,
            points: points()
                .iter()
                .enumerate()
                .map(|(i, x)| PointCoordinates {
                    name: format!("P{i}"),
                    xyz_m: (*x).into(),
                    covariance_m2: cov(1e-8 * (i + 1) as f64),
                })
                .collect(),
            joint: Some(JointCovarianceM2 {
                points: vec!["P0".into(), "P1".into()],
                matrix_m2: (0..36)
                    .map(|k| ((k * 7 % 11) as f64 + 1.0) * 1e-9)
                    .collect(),
            }),
        };
        // the same epoch in the datum `t`: x ↦ kRx + b, Σ ↦ k²RΣRᵀ (the joint block by block)
        let rot = |m: &Matrix3<f64>| t.scale * t.scale * t.rotation * m * t.rotation.transpose();
        let mut moved = plain.clone();
        for p in &mut moved.points {
            p.xyz_m = (t.scale * t.rotation * Vector3::from(p.xyz_m) + t.translation).into();
            let c = rot(&Matrix3::from_fn(|i, j| p.covariance_m2[i][j]));
            p.covariance_m2 = std::array::from_fn(|i| std::array::from_fn(|j| c[(i, j)]));
        }
        let j = moved.joint.as_mut().expect("joint");
        let m = nalgebra::DMatrix::from_row_slice(6, 6, &j.matrix_m2);
        let r = nalgebra::DMatrix::from_fn(6, 6, |a, b| {
            if a / 3 == b / 3 {
                t.rotation[(a % 3, b % 3)]
            } else {
                0.0
            }
        });
        let m = t.scale * t.scale * &r * m * r.transpose();
        j.matrix_m2 = m.transpose().as_slice().to_vec();
        let back = undo(&moved, &t);
        for (a, b) in plain.points.iter().zip(&back.points) {
            assert!((Vector3::from(a.xyz_m) - Vector3::from(b.xyz_m)).norm() < 1e-12);
            for i in 0..3 {
                for j in 0..3 {
                    assert!((a.covariance_m2[i][j] - b.covariance_m2[i][j]).abs() < 1e-20);
                }
            }
        }
        let (ja, jb) = (plain.joint.expect("joint"), back.joint.expect("joint"));
        for (a, b) in ja.matrix_m2.iter().zip(&jb.matrix_m2) {
            assert!((a - b).abs() < 1e-20, "{a} vs {b}");
        }
    }

    #[test]
    fn undoing_a_composition_restores_the_points() {
        let t = truth();
        let small = Similarity::from_linear(
            &DVector::from_vec(vec![0.3, 0.1, -0.2, 0.01, 0.02, -0.01, 0.004]),
            &Vector3::new(1.0, 1.0, 0.0),
        );
        let both = t.after(&small);
        for x in points() {
            let direct =
                t.scale * t.rotation * (small.scale * small.rotation * x + small.translation)
                    + t.translation;
            let composed = both.scale * both.rotation * x + both.translation;
            assert!((direct - composed).norm() < 1e-12);
        }
    }
}
