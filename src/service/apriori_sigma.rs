//! The a-priori σ a site's adjustments use (issue 61, item 8): each camera's σ of an image
//! coordinate pooled from the variance components of the site's last [`WINDOW_EPOCHS`] epochs
//! (`σ̂² = Σ σ² vᵀPv / Σ r`, [`pooled`]). The site page shows it; with the site's
//! `apriori_sigma: estimated` an epoch's adjustment uses it in place of the uploaded σ, once
//! [`MIN_EPOCHS`] earlier epochs carry components.

use crate::store::{epoch_health, Connection, Store, StoreError};
use cliffwatch_core::photogrammetry::statistics::variance_components::{
    pooled, PooledSigma, VarianceComponent,
};
use cliffwatch_core::photogrammetry::EpochProblem;

/// The sliding window of epochs the estimate pools.
pub const WINDOW_EPOCHS: usize = 20;

/// The fewest epochs with components before an estimate is offered or applied.
pub const MIN_EPOCHS: usize = 5;

/// The cameras' σ pooled from the components of the [`WINDOW_EPOCHS`] newest epochs observed
/// before `before` (store format; `None`: the newest epochs), each camera seen in at least
/// [`MIN_EPOCHS`] of them; empty when none is.
pub async fn estimate(
    db: &mut Connection,
    site: &str,
    before: Option<&str>,
) -> Result<Vec<PooledSigma>, StoreError> {
    let window =
        epoch_health::recent_variance_components(&mut *db, site, before, WINDOW_EPOCHS).await?;
    Ok(pooled_enough(&window))
}

/// Gives each camera of `problem` that `estimate` names its estimated σ; returns the entries
/// applied (the cameras this epoch has), in the problem's camera order.
pub fn apply(problem: &mut EpochProblem, estimate: &[PooledSigma]) -> Vec<PooledSigma> {
    let mut applied = Vec::new();
    for cam in problem.cameras.iter_mut() {
        if let Some(e) = estimate.iter().find(|e| e.camera == cam.id) {
            cam.sigma_mm = e
                .sigma_mm
                .max(cliffwatch_core::photogrammetry::model::camera::MIN_SIGMA_MM);
            applied.push(e.clone());
        }
    }
    applied
}

/// What the site page shows of a site's a-priori σ.
#[derive(Debug, Clone, PartialEq)]
pub struct SiteSigma {
    /// The cameras' σ pooled from the newest epochs ([`estimate`]).
    pub estimate: Vec<PooledSigma>,
    /// The σ (mm) each camera of the newest epoch with components used: camera id and σ.
    pub used: Vec<(String, f64)>,
    /// The estimate is a first step: the σ used weighted the cameras in another ratio than the
    /// estimate's (beyond three of its σ), which biases each camera's share (Förstner's estimate
    /// is unbiased only at the right ratio); applied, it converges over the next epochs.
    pub first_step: bool,
}

/// The estimate over the site's newest epochs, and the σ its newest epoch used.
pub async fn of_site(store: &Store, site: &str) -> Result<SiteSigma, StoreError> {
    let mut db = store.read().await?;
    let window =
        epoch_health::recent_variance_components(&mut *db, site, None, WINDOW_EPOCHS).await?;
    let used: Vec<(String, f64)> = window
        .first()
        .map(|c| c.iter().map(|c| (c.camera.clone(), c.sigma_mm)).collect())
        .unwrap_or_default();
    let estimate = pooled_enough(&window);
    let first_step = first_step(&estimate, &used);
    Ok(SiteSigma {
        estimate,
        used,
        first_step,
    })
}

/// [`pooled`] over a window, keeping the cameras seen in at least [`MIN_EPOCHS`] epochs.
fn pooled_enough(window: &[Vec<VarianceComponent>]) -> Vec<PooledSigma> {
    let lists: Vec<&[VarianceComponent]> = window.iter().map(Vec::as_slice).collect();
    pooled(&lists)
        .into_iter()
        .filter(|p| p.epochs >= MIN_EPOCHS && p.sigma_mm.is_finite() && p.sigma_mm > 0.0)
        .collect()
}

/// Whether the ratios σ̂ / σ used differ between the cameras by more than three of their σ.
fn first_step(estimate: &[PooledSigma], used: &[(String, f64)]) -> bool {
    let ratios: Vec<(f64, f64)> = estimate
        .iter()
        .filter_map(|e| {
            let (_, u) = used.iter().find(|(c, _)| *c == e.camera)?;
            Some((e.sigma_mm / u, e.relative_sigma))
        })
        .collect();
    ratios.iter().any(|(q1, s1)| {
        ratios
            .iter()
            .any(|(q2, s2)| (q1 / q2).ln().abs() > 3.0 * (s1 * s1 + s2 * s2).sqrt())
    })
}
