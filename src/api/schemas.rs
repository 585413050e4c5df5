//! Response types of the contract that have no Rust type elsewhere: the error body (written
//! through [`ErrorBody`] by [`super::error::ApiError`]), the status of the health endpoints, and
//! the epoch summary. The summary is the stored report merged with the list fields, so its schema
//! [`EpochSummary`] is documentation only, but each of its parts is the type that writes it (the
//! report's [`CameraReport`], [`PointReport`], …, the store's rows). The upload form's schema is
//! derived from the types that read it ([`crate::photogrammetry::EpochInput`]).

use serde::Serialize;
use utoipa::ToSchema;

use crate::photogrammetry::adjust::report::{
    CameraReport, DroppedObservation, ImageReport, PointReport, VarianceModel,
};
use crate::store::alerts::Alert;
use crate::store::displacements::Displacement;
use crate::store::epochs::{EpochListItem, StoredResidual};

/// The error answer of every endpoint, as [`super::error::ApiError`] writes it.
#[derive(Serialize, ToSchema)]
pub struct ErrorBody {
    /// What went wrong.
    pub error: ErrorDetail,
}

/// Code, message and details of an error.
#[derive(Serialize, ToSchema)]
pub struct ErrorDetail {
    /// Stable machine-readable code (`not_found`, `invalid_epoch`, `cannot_adjust`, `conflict`, …).
    pub code: &'static str,
    /// Human-readable message naming the field, image or point at fault.
    pub message: String,
    /// Extra JSON (or null), e.g. `{"limit_bytes": N}` for 413.
    #[schema(value_type = Option<Object>)]
    pub details: serde_json::Value,
}

/// `{"status": "ok"}` / `{"status": "ready"}`.
#[derive(Serialize, ToSchema)]
pub struct Status {
    /// `ok` or `ready`.
    pub status: &'static str,
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
    pub cameras: Vec<CameraReport>,
    /// Points: name, X/Y/Z in m, σ in mm.
    pub points: Vec<PointReport>,
    /// Images: id, observations, RMS in mm.
    pub images: Vec<ImageReport>,
    /// Observations dropped by data snooping: image, point, normalized residual.
    pub dropped: Vec<DroppedObservation>,
    /// Warnings of the adjustment.
    pub warnings: Vec<String>,
    /// Which variance the normalized residuals rest on (absent from epochs stored before it was
    /// reported).
    pub variance_model: Option<VarianceModel>,
    /// Why the displacement analysis failed (status `analysis_failed` only).
    pub analysis_error: Option<String>,
    /// Residuals per observation; detail view only.
    pub residuals: Option<Vec<StoredResidual>>,
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
