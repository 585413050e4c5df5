//! The adjustment of an epoch as a whole: [`adjuster`] runs it (start, working frame, solve,
//! datum, data snooping, precision), [`result`] is what it returns with the options that steer
//! it, and [`report`] the contract's adjustment report.

pub mod adjuster;
pub mod options;
pub mod report;
pub mod result;
pub(crate) mod robust;
