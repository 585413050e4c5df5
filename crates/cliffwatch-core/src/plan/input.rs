//! The plan as a user writes it (`cliffwatch plan PLAN.json`, `docs/api.md`, "Campaign design"):
//! cameras, stations, targets and the test's confidence and power, and the errors of a plan that
//! cannot be analysed.

use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::analysis::sensitivity::DEFAULT_POWER;
use crate::photogrammetry::input::epoch::DEFAULT_CONTROL_SIGMA_M;
use crate::photogrammetry::{AdjustError, Model};

/// A planned network (the JSON of `cliffwatch plan`; `docs/api.md`, "Campaign design").
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields)]
pub struct Plan {
    /// Projection model of the adjustment (default orthogonal).
    #[serde(default)]
    pub model: Model,
    /// A-priori σ of one image coordinate in pixels (e.g. 0.25).
    pub sigma_px: f64,
    /// Confidence of the displacement test, 0.5–0.999999 (default 0.95).
    #[serde(default = "default_confidence")]
    pub confidence: f64,
    /// Detection probability the MDD is stated at, 0–1 (default 0.8).
    #[serde(default = "default_power")]
    pub power: f64,
    /// σ of each coordinate of a known (stable) target in m (default 0.001 m, the upload form's).
    #[serde(default = "default_known_sigma")]
    pub known_sigma_m: f64,
    /// Datum of the planned adjustment: the known targets as control (default), or a free
    /// network (inner constraints over all targets, as a site's later epochs without control).
    #[serde(default, skip_serializing_if = "PlanDatum::is_control")]
    pub datum: PlanDatum,
    /// Outward face normal (any length, site frame); default: from the targets' centroid toward
    /// the stations' centroid.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub face_normal: Option<[f64; 3]>,
    /// Cameras (lens and sensor).
    pub cameras: Vec<PlanCamera>,
    /// Camera stations, one image each.
    pub stations: Vec<PlanStation>,
    /// Targets with approximate coordinates.
    pub targets: Vec<PlanTarget>,
}

/// Datum of a planned adjustment.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(rename_all = "snake_case")]
pub enum PlanDatum {
    /// The known targets are control points with their σ (at least four needed).
    #[default]
    Control,
    /// Free network: inner constraints over all targets' planned coordinates; `known` only marks
    /// the stable points.
    Free,
}

impl PlanDatum {
    /// Whether this is the control-point datum (the default, not written out).
    pub fn is_control(&self) -> bool {
        *self == PlanDatum::Control
    }
}

fn default_confidence() -> f64 {
    0.95
}
fn default_power() -> f64 {
    DEFAULT_POWER
}
fn default_known_sigma() -> f64 {
    DEFAULT_CONTROL_SIGMA_M
}

/// A planned camera: lens and sensor.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields)]
pub struct PlanCamera {
    /// Camera id, referenced by stations.
    pub id: String,
    /// Principal distance c in mm.
    pub c_mm: f64,
    /// Self-calibrate c (default true, as the orthogonal model's adjustment does).
    #[serde(default = "yes")]
    pub calibrate_c: bool,
    /// Pixel size in mm.
    pub pixel_size_mm: f64,
    /// Sensor width in pixels.
    pub width_px: u32,
    /// Sensor height in pixels.
    pub height_px: u32,
    /// This camera's σ of one image coordinate in pixels (default: the plan's `sigma_px`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sigma_px: Option<f64>,
}

fn yes() -> bool {
    true
}

/// A planned camera station.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields)]
pub struct PlanStation {
    /// Station name (also the image id).
    pub name: String,
    /// Camera id.
    pub camera: String,
    /// Projection centre in m (site frame).
    pub position: [f64; 3],
    /// The point the camera is aimed at, m (site frame).
    pub aim: [f64; 3],
    /// The image's upward direction in the site frame (default `[0, 0, 1]`, Z up).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub up: Option<[f64; 3]>,
    /// The targets this station observes (an existing station's image); default: every target in
    /// front of it and inside its sensor. Listed targets must still lie in front of it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sees: Option<Vec<String>>,
}

/// A planned target.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields)]
pub struct PlanTarget {
    /// Point name.
    pub point: String,
    /// Approximate coordinates in m (site frame).
    pub xyz: [f64; 3],
    /// A stable point of known coordinates (control of the adjustment).
    #[serde(default)]
    pub known: bool,
    /// σ of each known coordinate in m (default: the plan's `known_sigma_m`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sigma_m: Option<f64>,
}

/// A plan that cannot be analysed; each variant names the item at fault.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum PlanError {
    /// A station names a camera the plan does not have.
    #[error("station {station}: camera '{camera}' is not in the plan's cameras")]
    UnknownCamera {
        /// The station.
        station: String,
        /// The camera it names.
        camera: String,
    },
    /// A station's aim is its position, or its `up` lies along the view.
    #[error("station {station}: aim equals the position, or 'up' lies along the view direction")]
    BadAim {
        /// The station.
        station: String,
    },
    /// A station sees no target (all behind it or off its sensor).
    #[error("station {station} sees no target: all are behind it or off its sensor")]
    SeesNothing {
        /// The station.
        station: String,
    },
    /// A target a station is said to observe lies behind it.
    #[error("station {station}: target {point} lies behind the camera")]
    Behind {
        /// The station.
        station: String,
        /// The target.
        point: String,
    },
    /// A value out of range.
    #[error("{item}: {why}")]
    Invalid {
        /// The field or item.
        item: String,
        /// What is wrong.
        why: String,
    },
    /// The planned adjustment cannot be solved (too few known points seen, singular network…).
    #[error("the planned network cannot be adjusted: {0}")]
    Adjustment(#[from] AdjustError),
}
