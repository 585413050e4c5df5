//! Schemas of the OpenAPI document for bodies that the handlers build without a Rust type of
//! their own (the upload form is parsed by the photogrammetric core, the epoch summary is the
//! stored report merged with the list fields, errors are built by [`super::error::ApiError`]).
//! Documentation only: nothing is (de)serialized through these types; the test
//! `tests/service/api.rs` checks that the paper epochs use only fields named here.

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

/// The upload form of one epoch (`docs/api-contract.md`): object coordinates in metres (site
/// frame), image coordinates in mm from the principal point or in pixels.
#[derive(Serialize, ToSchema)]
pub struct UploadForm {
    /// Observation time (RFC 3339), unique within the site.
    #[schema(format = DateTime)]
    pub observed_at: String,
    /// Free label.
    pub label: Option<String>,
    /// Cameras (only `c_mm` required).
    #[schema(min_items = 1)]
    pub cameras: Vec<CameraForm>,
    /// Images with their target observations.
    #[schema(min_items = 1)]
    pub images: Vec<ImageForm>,
    /// Points of known coordinates (weighted by `sigma_m`).
    pub control: Option<Vec<ControlForm>>,
    /// Start values only.
    pub approx: Option<Vec<ApproxForm>>,
}

/// A camera of the upload form.
#[derive(Serialize, ToSchema)]
pub struct CameraForm {
    /// Camera id.
    #[schema(pattern = "^[A-Za-z0-9._-]{1,64}$")]
    pub id: String,
    /// Principal distance in mm.
    pub c_mm: f64,
    /// Estimate c.
    pub calibrate_c: Option<bool>,
    /// Parameters to estimate: any of c, x0, y0, k1, k2, k3, p1, p2.
    pub calibrate: Option<Vec<String>>,
    /// Pixel size in mm (needed for pixel observations).
    pub pixel_size_mm: Option<f64>,
    /// Image width in pixels.
    pub width_px: Option<u32>,
    /// Image height in pixels.
    pub height_px: Option<u32>,
    /// Principal point x in mm.
    pub x0_mm: Option<f64>,
    /// Principal point y in mm.
    pub y0_mm: Option<f64>,
    /// Radial distortion, mm⁻².
    pub k1: Option<f64>,
    /// Radial distortion, mm⁻⁴.
    pub k2: Option<f64>,
    /// Radial distortion, mm⁻⁶.
    pub k3: Option<f64>,
    /// Decentring distortion, mm⁻¹.
    pub p1: Option<f64>,
    /// Decentring distortion, mm⁻¹.
    pub p2: Option<f64>,
    /// A-priori σ of one image coordinate in mm.
    pub sigma_mm: Option<f64>,
}

/// An image of the upload form.
#[derive(Serialize, ToSchema)]
pub struct ImageForm {
    /// Image id.
    #[schema(pattern = "^[A-Za-z0-9._-]{1,64}$")]
    pub id: String,
    /// Camera id.
    #[schema(pattern = "^[A-Za-z0-9._-]{1,64}$")]
    pub camera: String,
    /// Station name.
    pub station: Option<String>,
    /// Target observations.
    pub observations: Vec<ObservationForm>,
}

/// One target observation: `x_mm`/`y_mm` or `col`/`row` (pixels).
#[derive(Serialize, ToSchema)]
pub struct ObservationForm {
    /// Point name.
    #[schema(pattern = "^[A-Za-z0-9._-]{1,64}$")]
    pub point: String,
    /// x in mm (right).
    pub x_mm: Option<f64>,
    /// y in mm (up).
    pub y_mm: Option<f64>,
    /// Column in pixels (centre of the top-left pixel is 0).
    pub col: Option<f64>,
    /// Row in pixels (downward).
    pub row: Option<f64>,
}

/// A control point (metres).
#[derive(Serialize, ToSchema)]
pub struct ControlForm {
    /// Point name.
    #[schema(pattern = "^[A-Za-z0-9._-]{1,64}$")]
    pub point: String,
    /// X in m.
    #[serde(rename = "X")]
    pub x: f64,
    /// Y in m.
    #[serde(rename = "Y")]
    pub y: f64,
    /// Z in m.
    #[serde(rename = "Z")]
    pub z: f64,
    /// σ of each coordinate in m.
    pub sigma_m: Option<f64>,
}

/// Start values of a point (metres).
#[derive(Serialize, ToSchema)]
pub struct ApproxForm {
    /// Point name.
    #[schema(pattern = "^[A-Za-z0-9._-]{1,64}$")]
    pub point: String,
    /// X in m.
    #[serde(rename = "X")]
    pub x: f64,
    /// Y in m.
    #[serde(rename = "Y")]
    pub y: f64,
    /// Z in m.
    #[serde(rename = "Z")]
    pub z: f64,
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
