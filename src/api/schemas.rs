//! Response types of the contract that have no Rust type elsewhere: the error body (written
//! through [`ErrorBody`] by [`crate::http::error::ApiError`]), the status of the health endpoints, and
//! the epoch summary ([`EpochSummary`]: the list fields, the stored report and the epoch's rows).
//! Each is the type that writes the answer, and the OpenAPI schema is derived from it, as the
//! upload form's is from the types that read it ([`cliffwatch_core::photogrammetry::EpochInput`]).

use serde::Serialize;
use utoipa::ToSchema;

use crate::store::alerts::Alert;
use crate::store::displacements::Displacement;
use crate::store::epoch_report::EpochReport;
use crate::store::epochs::{EpochListItem, StoredResidual};
use cliffwatch_core::photogrammetry::statistics::GlobalTest;

/// The error body lives with the errors it writes ([`crate::http::error`]); named here for the
/// OpenAPI document's paths.
pub use crate::http::error::{ErrorBody, ErrorDetail};

/// `{"status": "ok"}` / `{"status": "ready"}`.
#[derive(Serialize, ToSchema)]
pub struct Status {
    /// `ok` or `ready`.
    pub status: &'static str,
}

/// The summary of a stored epoch (upload answer, `GET .../epochs/{epoch}`): the list fields
/// ([`EpochHead`]: those of the list but `dof` and `variance_factor`, which the report carries, so
/// that no key appears twice), the adjustment report (σ0, the global test, cameras with c ± σc, per-point coordinates with σ,
/// images, dropped observations), its displacements and the alerts it raised; the residuals per
/// observation in `GET .../epochs/{epoch}` only.
#[derive(Serialize, ToSchema)]
pub struct EpochSummary {
    /// Id, observed_at, status, σ0, c, iterations, dropped observations, created_at.
    #[serde(flatten)]
    pub epoch: EpochHead,
    /// Site id.
    pub site: String,
    /// The stored adjustment report.
    #[serde(flatten)]
    pub report: EpochReport,
    /// The global test of the variance factor.
    pub global_test: GlobalTest,
    /// Residuals per observation; detail view only, empty once the observation retention deleted
    /// the observations (`observations_pruned_at`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub residuals: Option<Vec<StoredResidual>>,
    /// Displacements of this epoch against the reference epoch.
    pub displacements: Vec<Displacement>,
    /// Alerts this epoch raised or escalated, in their current state (alerts it only kept active
    /// are not listed: `GET /api/v1/alerts` has those).
    pub alerts: Vec<Alert>,
}

/// The fields of an epoch's list line ([`EpochListItem`]) without `dof` and `variance_factor`:
/// the summary takes those from its report ([`EpochReport`]), where they are always present.
#[derive(Serialize, ToSchema)]
pub struct EpochHead {
    /// Integer id, unique within the site.
    pub id: i64,
    /// Observation time (RFC 3339).
    pub observed_at: String,
    /// Label of the upload.
    pub label: Option<String>,
    /// What became of it.
    pub status: crate::store::epochs::EpochStatus,
    /// Projection model.
    pub model: cliffwatch_core::photogrammetry::Model,
    /// A-posteriori σ0 in image mm.
    pub sigma0_mm: f64,
    /// Principal distance of the first camera in mm.
    pub c_mm: Option<f64>,
    /// Its σ in mm (None when fixed).
    pub c_sigma_mm: Option<f64>,
    /// Iterations of the adjustment.
    pub iterations: i64,
    /// Observations dropped by data snooping (listed with their w in the report's `dropped`).
    pub dropped_observations: i64,
    /// Time of ingestion (RFC 3339).
    pub created_at: String,
    /// When the observation retention deleted the epoch's observations (RFC 3339), null while
    /// they are kept.
    pub observations_pruned_at: Option<String>,
}

impl From<EpochListItem> for EpochHead {
    fn from(e: EpochListItem) -> Self {
        // Destructured in full: a field added to the list line must be placed here too.
        let EpochListItem {
            id,
            observed_at,
            label,
            status,
            model,
            sigma0_mm,
            c_mm,
            c_sigma_mm,
            iterations,
            dropped_observations,
            created_at,
            observations_pruned_at,
            variance_factor: _,
            dof: _,
        } = e;
        EpochHead {
            id,
            observed_at,
            label,
            status,
            model,
            sigma0_mm,
            c_mm,
            c_sigma_mm,
            iterations,
            dropped_observations,
            created_at,
            observations_pruned_at,
        }
    }
}
