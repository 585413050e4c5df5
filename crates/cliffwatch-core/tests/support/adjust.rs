//! Helpers shared by the `adjust_*` integration tests.
#![allow(dead_code)]

use cliffwatch_core::photogrammetry::statistics::quality::fit_similarity;
use cliffwatch_core::photogrammetry::{AdjustOptions, Adjustment, EpochInput, Model};
use cliffwatch_sim::scenes::Truth;

/// The shared epoch and truth of one paper case and seed, or None when `../shared` is absent.
pub fn shared(case: u32, seed: u64) -> Option<(EpochInput, Truth)> {
    let dir =
        std::env::var("CLIFFWATCH_SHARED_DATA").unwrap_or(concat!(shared_dir!(), "/data").into());
    let e =
        std::fs::read_to_string(format!("{dir}/paper-case{case}-seed{seed}.epoch.json")).ok()?;
    let t =
        std::fs::read_to_string(format!("{dir}/paper-case{case}-seed{seed}.truth.json")).ok()?;
    Some((
        serde_json::from_str(&e).expect("shared epoch parses"),
        serde_json::from_str(&t).expect("shared truth parses"),
    ))
}

/// Default options with another model.
pub fn options(model: Model) -> AdjustOptions {
    AdjustOptions {
        model,
        ..AdjustOptions::default()
    }
}

/// Index 3 xyz (mm) of an adjustment against truth.
pub fn index3(adj: &Adjustment, truth: &Truth) -> f64 {
    truth.index3_rmse_mm(&adj.points).expect("index 3")[3]
}

/// The adjusted c of the first camera (mm) and its σ (mm, 0 when held).
pub fn c_of(adj: &Adjustment) -> (f64, f64) {
    let c = &adj.report.cameras[0];
    (c.c_mm, c.c_sigma_mm.unwrap_or(0.0))
}

/// Errors against truth after a similarity fit of the adjusted points onto the truth, each
/// coordinate divided by its reported σ (covariance rotated and scaled with the fit).
pub fn normalized_errors(adj: &Adjustment, truth: &Truth) -> Vec<f64> {
    let pts: Vec<_> = adj
        .points
        .iter()
        .filter(|p| truth.points.contains_key(&p.name))
        .collect();
    let a: Vec<_> = pts.iter().map(|p| p.xyz).collect();
    let t: Vec<_> = pts.iter().map(|p| truth.points[&p.name]).collect();
    let fit = fit_similarity(&a, &t).expect("similarity fit");
    let mut out = Vec::new();
    for (p, e) in pts.iter().zip(&fit.residuals) {
        let c = fit.transform.apply_covariance(&p.covariance_m2);
        for k in 0..3 {
            out.push(e[k] / c[k][k].sqrt());
        }
    }
    out
}

/// Root mean square.
pub fn rms(v: &[f64]) -> f64 {
    (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt()
}
