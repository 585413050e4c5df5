//! The bundle adjustment against truth: the paper's epochs, simulated scenes, errors, and the Monte-Carlo calibration of its σ.
//!
//! One test binary per area (each binary links the whole crate once); the files are its modules,
//! and `tests/support/` holds the helpers every binary shares.

#[path = "../support/mod.rs"]
mod support;

mod calibration;
mod cancel;
mod errors;
mod paper;
mod plan;
mod plan_agreement;
mod plan_quality;
mod plausible;
mod scenes;
mod sigma0;
