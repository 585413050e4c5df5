//! The projection models and the unknowns they act on: [`camera`] (interior orientation and lens
//! distortion), `rotation`, [`orthogonal`] (Ono & Hattori, eqs 5, 9–14) and `central`
//! (collinearity), the [`frame`] the adjustment works in, and `bundle`: the unknowns of an epoch
//! and the observation equations of one image point, with exact Jacobians by `dual` numbers.

pub(crate) mod bundle;
pub mod camera;
pub(crate) mod central;
pub(crate) mod dual;
pub mod frame;
pub mod orthogonal;
pub(crate) mod rotation;

use serde::{Deserialize, Serialize};

/// Which projection model an adjustment uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, Default)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(rename_all = "lowercase")]
pub enum Model {
    /// Ono & Hattori's orthogonal projection model (eqs 5, 9–14) with self-calibrated c.
    #[default]
    Orthogonal,
    /// Collinearity (central perspective) with selectable self-calibration.
    Central,
}

crate::contract_names!(Model, "model" {
    Orthogonal => "orthogonal",
    Central => "central",
});
