//! The photogrammetric core: pure functions, no I/O, no async.
//!
//! The path of an epoch through it: [`epoch`] validates the upload form, [`start`] finds start values
//! from four known points per image ([`affine`] resection, perspective refinement, ray intersection),
//! [`adjust`] runs the bundle adjustment in the [`frame`] working frame with the [`orthogonal`] or
//! [`central`] model ([`bundle`] observation equations, [`normals`] with the Schur complement, [`lm`]
//! iteration), [`precision`] inverts it, [`snooping`] drops blunders, and [`report`] holds the
//! contract's report. [`quality`] computes the paper's quality indexes against truth.

pub mod adjust;
pub mod affine;
pub mod bundle;
pub mod camera;
pub mod camera_blocks;
pub mod central;
pub mod dense;
pub mod dense_schur;
pub mod dual;
pub mod epoch;
pub mod epoch_csv;
pub mod error;
pub mod frame;
pub mod lm;
pub mod normal_equations;
pub mod normals;
pub mod orthogonal;
pub mod precision;
pub mod quality;
pub mod report;
pub mod result;
pub mod rotation;
pub mod snooping;
pub mod start;
#[cfg(test)]
mod test_support;

pub use adjust::{adjust, adjust_problem};
pub use camera::Camera;
pub use epoch::{EpochInput, EpochProblem, PriorCoordinates};
pub use error::{AdjustError, EpochError};
pub use report::{AdjustmentReport, Model};
pub use result::{AdjustOptions, AdjustedPoint, Adjustment, ImageOrientation, JointCovariance};
