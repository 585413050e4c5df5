//! Displacement analysis and alert rules: pure functions over typed values (no I/O, no async, no database).
//!
//! The path of an epoch through this module:
//! 1. [`analyse_epoch`]: the current epoch's coordinates are brought into the reference datum by an
//!    S-transformation onto the stable points (`datum`), whose congruence is tested and whose moving
//!    members are excluded (`congruence`; an exclusion is a move for `reference_unstable` only
//!    when the point also changed from its own earlier epochs, [`reference_change`]); every point gets its displacement with covariance and
//!    significance test (`displacement`), velocity and acceleration (`velocity`) and, while it
//!    accelerates, an inverse-velocity time-to-failure forecast ([`failure`]); the Kalman filter
//!    ([`kalman`]) over the point's last epochs gives its filtered displacement, velocity and
//!    forecast ([`tracking`]); each declared block gets its rigid-body motion ([`rigid_body`]) with the
//!    joint covariance of its points and the same filtered kinematics (`block_analysis`). The
//!    reference may be the mean of several epochs ([`reference`](mod@self::reference)).
//! 2. [`evaluate_alerts`]: the site's rules turn the analysis into alert transitions and events
//!    ([`alerts`]): a rule fires when its value exceeds the threshold at the site's one-sided
//!    confidence, for points and blocks; [`check_overdue`] watches the campaign schedule; [`acknowledge`] and [`resolve`] are the
//!    user's actions.
//! 3. [`analyse_series`]: a whole series again against one reference, the rules replayed over it
//!    (`series`), when the reference or the history changes.
//!
//! The inputs and settings of these steps are in `epoch` (the Kalman filter's too);
//! one epoch's analysis is `epoch_analysis`, the blocks' `block_analysis`;
//! a point's past records and what is read from them are in `history`, the small
//! linear algebra they share in `linalg`.
//!
//! Units are in the names: m for coordinates, mm and mm² for displacements and their covariances, mm/day,
//! hours. Methods: Caspary 1987 and Niemeier 2008 (S-transformation, congruence test), Chen 1983 (IWST),
//! Fukuzono 1985 (inverse velocity).

// `!(x > 0.0)` is deliberate throughout: it also rejects NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod alerts;
pub(crate) mod alignment;
pub(crate) mod block_analysis;
pub(crate) mod congruence;
pub(crate) mod datum;
pub(crate) mod displacement;
pub(crate) mod epoch;
pub(crate) mod epoch_analysis;
pub(crate) mod error;
pub mod failure;
pub(crate) mod history;
pub mod kalman;
pub(crate) mod linalg;
pub(crate) mod onset;
pub(crate) mod onset_law;
pub mod pooling;
pub mod reference;
pub mod reference_change;
pub(crate) mod reversible;
pub mod rigid_body;
pub mod sensitivity;
pub(crate) mod series;
pub mod site_frame;
pub mod stats;
pub mod tracking;
pub(crate) mod velocity;

pub use alerts::{
    acknowledge, analysis_failed, campaign_arrived, check_overdue, evaluate_alerts,
    may_acknowledge, reconcile, resolve, Alert, AlertConfig, AlertEvent, AlertEventType, AlertKind,
    AlertLevel, AlertRule, AlertState, AlertStatus, ClearedHow, ClearingTest, Metric, Reading,
    Readings, Source, REFERENCE_INDEPENDENT, VELOCITY_CLEAR_FRACTION,
};
pub use block_analysis::{BlockAnalysis, MIN_BLOCK_POINTS};
pub use congruence::CongruenceTest;
pub use datum::DatumMethod;
pub use displacement::{
    is_usable_direction, unit_direction, DisplacementRecord, FilteredValues, PointAnalysis,
    UNUSABLE_DIRECTION,
};
pub use epoch::{
    AnalysisConfig, DatumTransformation, EpochCoordinates, FailureConfig, GroupConfig, GroupKind,
    JointCovarianceM2, PointConfig, PointCoordinates, PointRole, Window,
    DEFAULT_FORECAST_BIN_HOURS, MAX_FILTER_EPOCHS,
};
pub use epoch_analysis::{analyse_epoch, DatumReport, EpochAnalysis};
pub use error::AnalysisError;
pub use failure::FailureForecast;
pub use history::History;
pub use series::{analyse_series, SeriesAnalysis};
pub use velocity::Kinematics;
