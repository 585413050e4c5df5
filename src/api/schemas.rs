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

/// The summary of a stored epoch (upload answer, `GET .../epochs/{epoch}`): the list fields, the
/// adjustment report (σ0, the global test, cameras with c ± σc, per-point coordinates with σ,
/// images, dropped observations), its displacements and the alerts it raised; the residuals per
/// observation in `GET .../epochs/{epoch}` only.
#[derive(Serialize, ToSchema)]
pub struct EpochSummary {
    /// Id, observed_at, status, σ0, c, iterations, dropped observations, created_at.
    #[serde(flatten)]
    pub epoch: EpochListItem,
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
