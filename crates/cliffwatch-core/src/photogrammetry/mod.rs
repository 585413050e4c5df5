//! The photogrammetric core: pure functions, no I/O, no async.
//!
//! The path of an epoch through it, one sub-module per step:
//! - [`input`]: the upload form, checked, becomes the problem to solve;
//! - [`start`]: start values from four known points per image (affine resection, perspective
//!   refinement, ray intersection);
//! - [`model`]: the [`model::orthogonal`] and `model::central` projection models, the working
//!   [`model::frame`], and the observation equations of the `model::bundle`;
//! - `solve`: normal equations with the Schur complement and Levenberg–Marquardt;
//! - [`statistics`]: precision, data snooping, and the paper's quality indexes;
//! - [`adjust`](mod@adjust): the adjustment as a whole (`adjust::adjuster`), its options and result, and the
//!   contract's report.
//!
//! The solver, the bundle's internals, precision and snooping are crate-private: callers use
//! [`adjust()`] / [`adjust_problem`] and the types re-exported here.

pub mod adjust;
pub(crate) mod error;
pub mod input;
pub mod model;
pub(crate) mod solve;
pub mod start;
pub mod statistics;
#[cfg(test)]
mod test_support;

pub use adjust::adjuster::{adjust, adjust_problem};
pub use adjust::cancel::Cancel;
pub use adjust::options::AdjustOptions;
pub use adjust::report::AdjustmentReport;
pub use adjust::result::{AdjustedPoint, Adjustment, ImageOrientation, JointCovariance};
pub use adjust::C_PRIOR_RELATIVE;
pub use error::{AdjustError, EpochError};
pub use input::epoch::{EpochInput, EpochProblem, PriorCoordinates};
pub use model::camera::Camera;
pub use model::Model;
