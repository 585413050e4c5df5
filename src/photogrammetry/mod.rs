//! The photogrammetric core: pure functions, no I/O, no async.
//!
//! The path of an epoch through it: [`epoch`] validates the upload form, [`affine`] finds start values
//! from four known points per image, [`adjust`] runs the bundle adjustment in the [`frame`] working
//! frame with the [`orthogonal`] or [`central`] model, [`snooping`] drops blunders, and [`report`]
//! holds the contract's report. [`quality`] computes the paper's quality indexes against truth.

pub mod adjust;
pub mod camera;
pub mod epoch;
pub mod error;
pub mod report;
pub mod quality;
pub mod result;

pub use adjust::{adjust, adjust_problem};
pub use camera::Camera;
pub use epoch::{EpochInput, EpochProblem, PriorCoordinates};
pub use error::{AdjustError, EpochError};
pub use report::{AdjustmentReport, Model};
pub use result::{AdjustOptions, AdjustedPoint, Adjustment, ImageOrientation, JointCovariance};
