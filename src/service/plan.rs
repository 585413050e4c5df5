//! Campaign design through the API (issue 78): the pre-analysis of a plan given in full
//! (`POST /api/v1/plan`), and of a site's current network with changes (`POST
//! /api/v1/sites/{site}/plan`, the what-if). The CPU work runs on a blocking thread under an
//! upload slot (the node's bound on concurrent adjustments) and its compute budget; dropping the
//! caller's future cancels it.

use serde::Serialize;

use super::admission::{CancelOnDrop, UploadSlot};
use super::apriori_sigma;
use super::ingest::EpochLimits;
use super::ServiceError;
use crate::store::sites::AprioriSigma;
use crate::store::{plan_network, sites, Store};
use cliffwatch_core::photogrammetry::input::epoch::ApproxInput;
use cliffwatch_core::photogrammetry::{AdjustError, Cancel, EpochInput};
use cliffwatch_core::plan::{
    apply_changes, pre_analysis_cancellable, site_plan, Plan, PlanChange, PlanError, PlanReport,
    SiteNetwork,
};

/// The pre-analysis of a site's network (with changes), and what it rests on.
#[derive(Debug, Clone, Serialize, utoipa::ToSchema)]
pub struct SitePlan {
    /// Site id.
    pub site: String,
    /// The epoch whose network was analysed (the site's latest).
    pub epoch: i64,
    /// The changes applied, in order (empty: the site's own network).
    pub changes: Vec<PlanChange>,
    /// The plan analysed (the site's network after the changes): cameras, stations, targets.
    pub plan: Plan,
    /// The pre-analysis.
    pub report: PlanReport,
    /// What the epoch's adjustment reported, per point: σX, σY, σZ in mm (a-posteriori, as
    /// stored) and the a-posteriori variance factor they carry.
    pub achieved: Achieved,
}

/// The σ a site's epoch achieved.
#[derive(Debug, Clone, Serialize, utoipa::ToSchema)]
pub struct Achieved {
    /// The epoch's a-posteriori variance factor (σ̂0/σ0)², None when not stored.
    pub variance_factor: Option<f64>,
    /// Per point: name and σX, σY, σZ in mm, site frame.
    pub points: Vec<AchievedPoint>,
}

/// The σ one point achieved in an epoch.
#[derive(Debug, Clone, Serialize, utoipa::ToSchema)]
pub struct AchievedPoint {
    /// Point name.
    pub point: String,
    /// σX, σY, σZ in mm.
    pub sigma_mm: [f64; 3],
}

/// A plan error as the use case's: a cancelled adjustment stays a cancellation (503), anything
/// else names the item (422).
fn plan_error(e: PlanError) -> ServiceError {
    match e {
        PlanError::Adjustment(err @ AdjustError::Cancelled { .. }) => ServiceError::Adjust(err),
        other => ServiceError::Plan(other),
    }
}

/// Runs `work` on a blocking thread holding `slot`, cancelled when the caller drops this future.
async fn blocking<T: Send + 'static>(
    slot: UploadSlot,
    work: impl FnOnce(Cancel) -> Result<T, PlanError> + Send + 'static,
) -> Result<T, ServiceError> {
    let cancel = slot.cancel().clone();
    let _cancel_when_dropped = CancelOnDrop(cancel.clone());
    let (out, _slot) = tokio::task::spawn_blocking(move || (work(cancel), slot)).await?;
    out.map_err(plan_error)
}

/// Refuses a plan larger than the node takes of an epoch: more targets than `max_epoch_points`,
/// or more possible observations (stations × targets) than `max_epoch_observations`.
fn check_size(plan: &Plan, limits: EpochLimits) -> Result<(), ServiceError> {
    if plan.targets.len() > limits.points {
        return Err(ServiceError::TooLarge {
            what: "targets",
            count: plan.targets.len(),
            limit: limits.points,
            setting: "max_epoch_points",
        });
    }
    let observations = plan.targets.len().saturating_mul(plan.stations.len());
    if observations > limits.observations {
        return Err(ServiceError::TooLarge {
            what: "possible image observations (stations × targets)",
            count: observations,
            limit: limits.observations,
            setting: "max_epoch_observations",
        });
    }
    Ok(())
}

/// The pre-analysis of `plan` (the answer of `cliffwatch plan`), within the node's epoch size
/// limits.
pub async fn analyse(
    plan: Plan,
    limits: EpochLimits,
    slot: UploadSlot,
) -> Result<PlanReport, ServiceError> {
    check_size(&plan, limits)?;
    blocking(slot, move |cancel| pre_analysis_cancellable(&plan, cancel)).await
}

/// The pre-analysis of site `site`'s current network (its latest epoch's cameras and stations,
/// its targets and stable points, the a-priori σ its adjustments use) after `changes`.
pub async fn what_if(
    store: &Store,
    site: &str,
    changes: Vec<PlanChange>,
    limits: EpochLimits,
    slot: UploadSlot,
) -> Result<SitePlan, ServiceError> {
    let mut db = store.read().await?;
    let site = sites::get(&mut *db, site)
        .await?
        .ok_or_else(|| ServiceError::UnknownSite(site.to_string()))?;
    let stored = plan_network::latest(&mut db, &site.id)
        .await?
        .ok_or_else(|| {
            ServiceError::NoNetwork(format!(
                "site '{}' has no epoch yet: its network is known from its first epoch",
                site.id
            ))
        })?;
    if stored.pruned || stored.images.is_empty() {
        return Err(ServiceError::NoNetwork(format!(
            "the observations of site '{}''s latest epoch {} were deleted by retention \
             (observation_retention_days): its network cannot be rebuilt",
            site.id, stored.epoch
        )));
    }
    let mut cameras = stored.cameras.clone();
    if site.apriori_sigma == AprioriSigma::Estimated {
        let estimate = apriori_sigma::estimate(&mut db, &site.id, None).await?;
        for c in &mut cameras {
            if let Some(e) = estimate.iter().find(|e| e.camera == c.id) {
                c.sigma_mm = Some(e.sigma_mm);
            }
        }
    }
    drop(db);
    let achieved = Achieved {
        variance_factor: stored.variance_factor,
        points: stored
            .coordinates
            .iter()
            .map(|c| AchievedPoint {
                point: c.point.clone(),
                sigma_mm: std::array::from_fn(|i| c.covariance_m2[i][i].max(0.0).sqrt() * 1e3),
            })
            .collect(),
    };
    let network = SiteNetwork {
        model: site.model,
        epoch: EpochInput {
            observed_at: crate::store::display_timestamp(&stored.observed_at),
            label: None,
            cameras,
            images: stored.images,
            control: Vec::new(),
            approx: stored
                .coordinates
                .iter()
                .map(|c| ApproxInput {
                    point: c.point.clone(),
                    X: c.xyz[0],
                    Y: c.xyz[1],
                    Z: c.xyz[2],
                })
                .collect(),
        },
        stable: stored.stable,
        control_datum: stored.datum.starts_with("control"),
        confidence: site.confidence,
        face_normal: site.frame.face_normal,
    };
    let (epoch, site_id) = (stored.epoch, site.id.clone());
    let (plan, report) = blocking(slot, move |cancel| {
        let own = site_plan(&network, cancel.clone())?;
        let plan = apply_changes(&own, &changes).map(|p| (p, changes))?;
        if check_size(&plan.0, limits).is_err() {
            return Err(PlanError::Invalid {
                item: "changes".into(),
                why: "the network grows beyond the node's epoch limits".into(),
            });
        }
        let report = pre_analysis_cancellable(&plan.0, cancel)?;
        Ok((plan, report))
    })
    .await?;
    Ok(SitePlan {
        site: site_id,
        epoch,
        changes: plan.1,
        plan: plan.0,
        report,
        achieved,
    })
}
