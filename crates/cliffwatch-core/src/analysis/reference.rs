//! A reference that is not one noisy epoch: the covariance-weighted mean of the first K epochs,
//! each brought into the first epoch's datum by the stable-point S-transformation of
//! [`super::analyse_epoch`] (congruence test included, so a stable point that moved between them
//! does not drag the others).
//!
//! Per point `x̄ = (Σ C_k⁻¹)⁻¹ Σ C_k⁻¹ x_k` with covariance `(Σ C_k⁻¹)⁻¹` (the epochs' own point
//! covariances; the small error of each transformation into the first epoch's datum is not
//! added). The joint covariance of the chosen points is combined likewise when every epoch carries
//! it for the same points. A point missing from an epoch is averaged over the epochs that have it.

use std::collections::HashMap;

use nalgebra::{DMatrix, Matrix3, Vector3};

use super::epoch::{
    AnalysisConfig, EpochCoordinates, JointCovarianceM2, PointConfig, PointCoordinates,
};
use super::epoch_analysis::analyse_epoch;
use super::error::AnalysisError;
use super::history::History;

/// The mean of `epochs` (oldest first) in the first one's datum; keeps the first epoch's id and
/// time. One epoch is returned unchanged.
///
/// Errors: no epoch, or an epoch that cannot be brought into the first one's datum (too few
/// common points, a singular datum); the message names the epoch.
pub fn combine_reference(
    epochs: &[EpochCoordinates],
    points: &[PointConfig],
    config: &AnalysisConfig,
) -> Result<EpochCoordinates, AnalysisError> {
    let Some(first) = epochs.first() else {
        return Err(AnalysisError::InvalidInput(
            "a reference needs at least one epoch".into(),
        ));
    };
    if epochs.len() == 1 {
        return Ok(first.clone());
    }
    let plain = AnalysisConfig {
        groups: vec![],
        ..config.clone()
    };
    // Per point: Σ C⁻¹ (m⁻²) and Σ C⁻¹ x.
    let mut sums: HashMap<String, (Matrix3<f64>, Vector3<f64>)> = HashMap::new();
    let mut add = |name: &str, x: Vector3<f64>, c: &[[f64; 3]; 3]| -> Result<(), AnalysisError> {
        let w = Matrix3::from(*c)
            .try_inverse()
            .filter(|w| w.iter().all(|v| v.is_finite()))
            .ok_or_else(|| AnalysisError::Singular {
                what: format!("covariance of point {name}"),
            })?;
        let s = sums
            .entry(name.to_string())
            .or_insert((Matrix3::zeros(), Vector3::zeros()));
        s.0 += w;
        s.1 += w * x;
        Ok(())
    };
    for p in &first.points {
        add(&p.name, Vector3::from(p.xyz_m), &p.covariance_m2)?;
    }
    for e in &epochs[1..] {
        let a = analyse_epoch(first, e, points, &History::new(), &plain).map_err(|err| {
            AnalysisError::InvalidInput(format!(
                "reference epoch {} into the datum of epoch {}: {err}",
                e.epoch, first.epoch
            ))
        })?;
        for pa in &a.points {
            let r = &pa.record;
            let (Some(p1), Some(pk)) = (
                first.points.iter().find(|p| p.name == r.point),
                e.points.iter().find(|p| p.name == r.point),
            ) else {
                continue;
            };
            let x = Vector3::from(p1.xyz_m) + Vector3::new(r.dx_mm, r.dy_mm, r.dz_mm) * 1e-3;
            add(&r.point, x, &pk.covariance_m2)?;
        }
    }
    let mut out = first.clone();
    out.points = first
        .points
        .iter()
        .map(|p| {
            let (w, wx) = sums[&p.name];
            let c = w
                .try_inverse()
                .unwrap_or_else(|| Matrix3::from(p.covariance_m2));
            PointCoordinates {
                name: p.name.clone(),
                xyz_m: (c * wx).into(),
                covariance_m2: c.into(),
            }
        })
        .collect();
    out.joint = combine_joint(epochs);
    Ok(out)
}

/// `(Σ J_k⁻¹)⁻¹` of the epochs' joint covariances when all carry one for the same points.
fn combine_joint(epochs: &[EpochCoordinates]) -> Option<JointCovarianceM2> {
    let first = epochs[0].joint.as_ref()?;
    let n = 3 * first.points.len();
    let mut sum = DMatrix::<f64>::zeros(n, n);
    for e in epochs {
        let j = e.joint.as_ref()?;
        if j.points != first.points || j.matrix_m2.len() != n * n {
            return None;
        }
        let m = DMatrix::from_row_slice(n, n, &j.matrix_m2);
        sum += m.cholesky()?.inverse();
    }
    let c = sum.cholesky()?.inverse();
    Some(JointCovarianceM2 {
        points: first.points.clone(),
        matrix_m2: (0..n * n).map(|k| c[(k / n, k % n)]).collect(),
    })
}
