//! The adjustment report of the contract (field names are part of the contract) and the richer
//! in-memory result the service and the displacement analysis use.

use serde::{Deserialize, Serialize};

use crate::photogrammetry::model::Model;

/// The variance behind the data snooping's test statistics.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(rename_all = "snake_case")]
pub enum VarianceModel {
    /// Baarda's w with the a-priori σ and the normal critical value (the global test accepted σ).
    #[default]
    APriori,
    /// Pope's τ test: w with the a-posteriori σ̂0 and the critical value of the τ distribution (the
    /// global test rejected the a-priori σ, either way).
    APosteriori,
}

/// Adjusted interior orientation of one camera.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct CameraReport {
    /// Camera id.
    pub id: String,
    /// Principal distance in mm.
    pub c_mm: f64,
    /// σ of c in mm (None when c was held fixed).
    pub c_sigma_mm: Option<f64>,
    /// Every estimated interior parameter (name, value, σ), in the units of the upload form.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub calibrated: Vec<CalibratedParameter>,
}

/// One estimated interior parameter.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct CalibratedParameter {
    /// c, x0, y0, k1, k2, k3, p1 or p2.
    pub name: String,
    /// Estimate (units of the upload form).
    pub value: f64,
    /// Its σ.
    pub sigma: f64,
}

/// Adjusted coordinates of one point: metres in the site frame, σ in mm.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[allow(non_snake_case)]
pub struct PointReport {
    /// Point name.
    pub point: String,
    /// X in m.
    pub X: f64,
    /// Y in m.
    pub Y: f64,
    /// Z in m.
    pub Z: f64,
    /// σ of X in mm.
    pub sigma_X_mm: f64,
    /// σ of Y in mm.
    pub sigma_Y_mm: f64,
    /// σ of Z in mm.
    pub sigma_Z_mm: f64,
}

/// Per-image summary.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct ImageReport {
    /// Image id.
    pub id: String,
    /// Observations used (not dropped).
    pub observations: usize,
    /// RMS of the residuals (both coordinates) in mm.
    pub rms_mm: f64,
}

/// An observation dropped by data snooping.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct DroppedObservation {
    /// Image id.
    pub image: String,
    /// Point name.
    pub point: String,
    /// Normalized residual (Baarda's w) when dropped.
    pub w: f64,
}

/// Residual of one observation (mm) and its normalized residual.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ResidualReport {
    /// Image id.
    pub image: String,
    /// Point name.
    pub point: String,
    /// Residual in x (observed − computed), mm.
    pub vx_mm: f64,
    /// Residual in y, mm.
    pub vy_mm: f64,
    /// Largest |w| of the two coordinates.
    pub w: f64,
    /// True when data snooping dropped it (then v is the misclosure against the final solution).
    pub dropped: bool,
}

/// The adjustment report of the contract.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AdjustmentReport {
    /// `orthogonal` or `central`.
    pub model: Model,
    /// Whether the iteration converged.
    pub converged: bool,
    /// Gauss–Newton/LM iterations of the final adjustment.
    pub iterations: usize,
    /// A-posteriori σ0 = √(vᵀPv/dof) in image mm, expressed in the observations' quadratic-mean
    /// a-priori σ (`EpochProblem::reference_sigma_mm`).
    pub sigma0_mm: f64,
    /// Degrees of freedom (redundancy).
    pub dof: i64,
    /// (σ0 / a-priori σ)².
    pub variance_factor: f64,
    /// Adjusted cameras.
    pub cameras: Vec<CameraReport>,
    /// Adjusted points.
    pub points: Vec<PointReport>,
    /// Per-image residual summary.
    pub images: Vec<ImageReport>,
    /// Observations dropped as blunders.
    pub dropped: Vec<DroppedObservation>,
    /// Warnings (weak geometry, held parameters, …).
    pub warnings: Vec<String>,
    /// Residuals of every observation (the full report).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub residuals: Vec<ResidualReport>,
    /// The datum: `free network (inner constraints)`, `control points`.
    #[serde(default)]
    pub datum: String,
    /// Index 3 with `--truth`: RMSE [x, y, z, xyz] in mm after a similarity fit.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub index3_rmse_mm: Option<[f64; 4]>,
    /// Index 4 with `--truth`: RMSE [x, y, z, xyz] in mm after a 3-D affine fit.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub index4_rmse_mm: Option<[f64; 4]>,
    /// Which variance the data snooping's normalized residuals (`w` of residuals and dropped
    /// observations) rest on; the covariances always carry the a-posteriori variance factor.
    #[serde(default)]
    pub variance_model: VarianceModel,
    /// Each camera's share of vᵀPv and of the redundancy (when the options ask for them: the
    /// service does, for the site's adjustment health).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub variance_components:
        Vec<crate::photogrammetry::statistics::variance_components::VarianceComponent>,
}
