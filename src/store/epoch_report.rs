//! The adjustment report as an epoch keeps it (the `report` column): the contract's report
//! without the residuals (those are rows of their own) and the list fields (columns of their
//! own), with what the service adds: the reason a displacement analysis failed and, for watched
//! epochs, how each station's targets were identified.

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use cliffwatch_core::photogrammetry::adjust::report::{
    CameraReport, DroppedObservation, ImageReport, PointReport, VarianceModel,
};
use cliffwatch_core::photogrammetry::statistics::variance_components::{
    PooledSigma, VarianceComponent,
};
use cliffwatch_core::photogrammetry::statistics::GlobalTest;

/// The stored report of one epoch, as the epoch summary and the dashboard show it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct EpochReport {
    /// Adjustment converged.
    pub converged: bool,
    /// Degrees of freedom (redundancy).
    pub dof: i64,
    /// (σ̂0 / a-priori σ)², dimensionless.
    pub variance_factor: f64,
    /// Datum of the adjustment: `free network (inner constraints)` or `control points`.
    #[serde(default)]
    pub datum: String,
    /// Cameras: id, c and σc in mm, calibrated parameters.
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
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub variance_model: Option<VarianceModel>,
    /// Why the displacement analysis failed (status `analysis_failed` only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub analysis_error: Option<String>,
    /// Epochs from the watched directory only: per station, how its targets were identified
    /// (`station`, `method`, and the counts `detected`, `identified`, `ambiguous`, `unmatched`),
    /// where its image is kept (`folder` relative to the site's watched directory, `image`,
    /// `width_px`, `height_px`) and every detected target (`targets`: `col`, `row` and
    /// `diameter_px` in px, `point` when identified, `status` `identified` | `ambiguous` |
    /// `unmatched`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<Vec<Object>>)]
    pub identification: Option<Vec<serde_json::Value>>,
    /// Each camera's variance component: its a-priori σ (mm), coordinates, share of the
    /// redundancy and of vᵀPv (epochs stored before it was reported have none).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub variance_components: Vec<VarianceComponent>,
    /// When the site's `apriori_sigma` is `estimated` and enough earlier epochs had components:
    /// the cameras' σ this adjustment used in place of the uploaded ones.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub apriori_sigma_estimated: Option<Vec<PooledSigma>>,
}

impl EpochReport {
    /// The global test of the adjustment's variance factor.
    pub fn global_test(&self) -> GlobalTest {
        GlobalTest::of(self.dof, self.variance_factor)
    }
}
