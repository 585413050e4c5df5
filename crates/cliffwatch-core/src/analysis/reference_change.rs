//! Whether a stable point the congruence test excluded has moved, or only looks moved because of
//! the reference epoch's error.
//!
//! Every epoch's displacement `d_k = e_k − e_ref` carries the reference epoch's error `e_ref` of
//! the point, the same in every epoch (with both epochs equally precise, half the variance of each
//! `d_k`: the displacements of one point in two epochs correlate by ½). A stable point whose
//! reference coordinates erred by 2–3 σ is therefore excluded by the congruence test in far more
//! than α of the epochs, and "excluded in 2 of 3 epochs" is no longer rare for it: on the detection
//! benchmark's still series T101 erred by ≈ 2.6 σ in depth at the reference epoch, was excluded in
//! epochs 4 and 6 and named by `reference_unstable` for 10 epochs although it never moved.
//!
//! The change test compares the epoch's displacement with the point's own earlier displacements,
//! in which `e_ref` cancels: `c = d_k − mean(d_j)` over the last [`CHANGE_BASELINE_EPOCHS`]
//! earlier epochs whose single-point test found nothing, with covariance
//! `Σ_c = (Σ_k − Σ_ref) + Σ_j (Σ_j − Σ_ref) / n²` (the epochs' own shares; `Σ_ref` the reference
//! epoch's share of the current covariance), tested as `cᵀ Σ_c⁻¹ c > 3 F(3, f; 1 − α)`. A point
//! with no such earlier epoch (it moved before the first epoch after the reference, or its
//! reference coordinates are so far off that every epoch finds it) is judged by its exclusion alone.

use chrono::{DateTime, Utc};
use nalgebra::{Matrix3, Vector3};

use super::displacement::DisplacementRecord;
use super::history::record_covariance;

/// How many of a point's latest earlier epochs (those whose single-point test found nothing) the
/// change test compares an exclusion with.
pub const CHANGE_BASELINE_EPOCHS: usize = 5;

/// Whether the excluded stable point's displacement `d` (mm; covariance `cov` in mm², of which
/// `shared` is the reference epoch's share) changed significantly from its baseline in `history`
/// (records before `now`), at the critical value `critical3` of the single-point test
/// (3·F(3, f; confidence)). True when there is no baseline to compare with.
pub(crate) fn changed_since_baseline(
    d: &Vector3<f64>,
    cov: &Matrix3<f64>,
    shared: &Matrix3<f64>,
    history: Option<&Vec<DisplacementRecord>>,
    now: DateTime<Utc>,
    critical3: f64,
) -> bool {
    let baseline: Vec<(Vector3<f64>, Matrix3<f64>)> = history
        .map(|h| {
            let end = h.partition_point(|r| r.observed_at < now);
            h[..end]
                .iter()
                .rev()
                .filter(|r| !r.significant)
                .filter_map(|r| {
                    let c = record_covariance(r)?;
                    let d = Vector3::new(r.dx_mm, r.dy_mm, r.dz_mm);
                    d.iter().all(|v| v.is_finite()).then_some((d, c))
                })
                .take(CHANGE_BASELINE_EPOCHS)
                .collect()
        })
        .unwrap_or_default();
    if baseline.is_empty() {
        return true;
    }
    let n = baseline.len() as f64;
    let mean = baseline.iter().map(|(d, _)| d).sum::<Vector3<f64>>() / n;
    let sum_cov = baseline.iter().map(|(_, c)| c).sum::<Matrix3<f64>>();
    let change = d - mean;
    // The epochs' own shares; when rounding or a changed datum leaves that not positive definite,
    // the whole covariances (which only makes the test more cautious).
    let own = (cov - shared) + (sum_cov - shared * n) / (n * n);
    let whole = cov + sum_cov / (n * n);
    let Some(ch) = own.cholesky().or_else(|| whole.cholesky()) else {
        return true;
    };
    let statistic = (change.transpose() * ch.inverse() * change)[(0, 0)];
    statistic > critical3
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A stored row of epoch `epoch` (observed `epoch` days after 1970): displacement `d` (mm),
    /// σ = √2 mm per axis, uncorrelated.
    fn record(epoch: i64, d: [f64; 3], significant: bool) -> DisplacementRecord {
        let t = DateTime::from_timestamp(epoch * 86_400, 0).unwrap_or_default();
        let s = 2f64.sqrt();
        serde_json::from_value(serde_json::json!({
            "point": "R1", "epoch": epoch, "observed_at": t,
            "dx_mm": d[0], "dy_mm": d[1], "dz_mm": d[2], "d_mm": Vector3::from(d).norm(),
            "sigma_dx_mm": s, "sigma_dy_mm": s, "sigma_dz_mm": s, "sigma_mm": s,
            "significant": significant,
        }))
        .expect("record")
    }

    /// Half of each displacement's variance (2 mm² per axis) from the reference epoch; the
    /// critical value of 99 % (χ²(3)).
    #[test]
    fn an_offset_present_since_the_reference_is_no_change_and_a_new_one_is() {
        let (cov, shared) = (Matrix3::identity() * 2.0, Matrix3::identity());
        let now = DateTime::from_timestamp(6 * 86_400, 0).unwrap_or_default();
        let changed = |d: [f64; 3], h: Option<&Vec<DisplacementRecord>>| {
            changed_since_baseline(&Vector3::from(d), &cov, &shared, h, now, 11.345)
        };
        // About the same 3.5 mm offset (2.5 σ) in every epoch: the reference epoch's error.
        let h: Vec<_> = (1..=5)
            .map(|e| record(e, [3.3 + 0.1 * e as f64, 0.0, 0.0], false))
            .collect();
        assert!(!changed([4.5, 0.0, 0.0], Some(&h)));
        // 4.5 mm more than the earlier epochs (own σ of the change ≈ 1.1 mm): a move.
        assert!(changed([8.1, 0.0, 0.0], Some(&h)));
        // No earlier epoch, or only significant ones (and later ones, ignored): the exclusion
        // alone.
        assert!(changed([4.5, 0.0, 0.0], None));
        let moved: Vec<_> = (1..=7).map(|e| record(e, [9.0, 0.0, 0.0], e < 6)).collect();
        assert!(changed([9.0, 0.0, 0.0], Some(&moved)));
    }
}
