//! The adjustment of an epoch as a whole: `prepare` makes the epoch ready for the solver (start
//! values, working frame, datum, unknowns), `adjuster` runs it (Levenberg–Marquardt, data
//! snooping), `site_result` brings the solution into the site frame (datum, precision,
//! orientations, residuals), [`result`] is what it returns with the options that steer it,
//! [`cancel`] how a caller stops it early, and [`report`] the contract's adjustment report.

pub(crate) mod adjuster;
pub mod cancel;
pub(crate) mod options;
mod prepare;
pub mod report;
pub mod result;
pub(crate) mod robust;
mod site_result;

pub use prepare::C_PRIOR_RELATIVE;
