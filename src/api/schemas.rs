//! Schemas of the OpenAPI document for bodies that the handlers build without a Rust type of
//! their own (the epoch summary is the stored report merged with the list fields, errors are
//! built by [`super::error::ApiError`]). Documentation only: nothing is (de)serialized through
//! these types. The upload form's schema is derived from the types that read it
//! ([`crate::photogrammetry::EpochInput`]).

#![allow(dead_code)]

use serde::Serialize;
use utoipa::ToSchema;

use crate::store::alerts::Alert;
use crate::store::displacements::Displacement;
use crate::store::epochs::EpochListItem;

/// The error answer of every endpoint.
#[derive(Serialize, ToSchema)]
pub struct ErrorBody {
    /// What went wrong.
    pub error: ErrorDetail,
}

/// Code, message and details of an error.
#[derive(Serialize, ToSchema)]
pub struct ErrorDetail {
    /// Stable machine-readable code (`not_found`, `invalid_epoch`, `cannot_adjust`, `conflict`, …).
    pub code: String,
    /// Human-readable message naming the field, image or point at fault.
    pub message: String,
    /// Extra JSON (or null), e.g. `{"limit_bytes": N}` for 413.
    #[schema(value_type = Option<Object>)]
    pub details: Option<serde_json::Value>,
}

/// `{"status": "ok"}` / `{"status": "ready"}`.
#[derive(Serialize, ToSchema)]
pub struct Status {
    /// `ok`, `ready` or `not ready`.
    pub status: String,
}

/// The summary of a stored epoch (upload answer, `GET .../epochs/{epoch}`): the list fields, the
/// adjustment report (σ0, cameras with c ± σc, per-point coordinates with σ, images, dropped
/// observations), its displacements and the alerts it raised; the residuals per observation in
/// `GET .../epochs/{epoch}` only.
#[derive(Serialize, ToSchema)]
pub struct EpochSummary {
    /// Id, observed_at, status, σ0, c, iterations, created_at.
    #[serde(flatten)]
    pub epoch: EpochListItem,
    /// Site id.
    pub site: String,
    /// Adjustment converged.
    pub converged: bool,
    /// Degrees of freedom.
    pub dof: i64,
    /// σ0² against the a-priori σ.
    pub variance_factor: f64,
    /// Datum of the adjustment.
    pub datum: String,
    /// Cameras: id, c_mm, c_sigma_mm, calibrated parameters.
    #[schema(value_type = Vec<Object>)]
    pub cameras: Vec<serde_json::Value>,
    /// Points: name, X/Y/Z in m, σ in mm.
    #[schema(value_type = Vec<Object>)]
    pub points: Vec<serde_json::Value>,
    /// Images: id, observations, RMS in mm.
    #[schema(value_type = Vec<Object>)]
    pub images: Vec<serde_json::Value>,
    /// Observations dropped by data snooping: image, point, normalized residual.
    #[schema(value_type = Vec<Object>)]
    pub dropped: Vec<serde_json::Value>,
    /// Warnings of the adjustment.
    pub warnings: Vec<String>,
    /// Residuals per observation (image, point, vx_mm, vy_mm, w, dropped); detail view only.
    #[schema(value_type = Option<Vec<Object>>)]
    pub residuals: Option<Vec<serde_json::Value>>,
    /// Displacements of this epoch against the reference epoch.
    pub displacements: Vec<Displacement>,
    /// Alerts raised by this epoch.
    pub alerts: Vec<Alert>,
    /// Epochs from the watched directory only: per station, how its targets were identified
    /// (`station`, `method`, and the counts `detected`, `identified`, `ambiguous`, `unmatched`),
    /// where its image is kept (`folder` relative to the site's watched directory, `image`,
    /// `width_px`, `height_px`) and every detected target (`targets`: `col`, `row` and
    /// `diameter_px` in px, `point` when identified, `status` `identified` | `ambiguous` |
    /// `unmatched`).
    #[schema(value_type = Option<Vec<Object>>)]
    pub identification: Option<Vec<serde_json::Value>>,
}
