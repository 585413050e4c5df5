//! # cliffwatch-sim
//!
//! Simulated scenes with truth, for the tests and benchmarks of cliffwatch and `cliffwatch
//! simulate`.
//!
//! - [`scenes`]: the paper's Table 1 scene, the long-range cliff, flat faces, calibration networks.
//! - [`images`]: rendered target images with ground-truth centres.
//! - [`monitoring`]: monitoring series of adjusted coordinates (stable points, a moving block).
//! - [`series`]: the same kind of series as image observations in the upload form (re-set-up
//!   cameras, drifting c), for end-to-end tests through the service.
//! - [`kinematics`]: block motions as real slopes make them (failures, bursts, steps, cycles,
//!   creep, scatter, shared errors), and [`ttf_benchmark`], the time-to-failure benchmark on them,
//!   with [`ttf_bound`], what any forecaster could do on them (the Cramér–Rao bound), and
//!   [`ttf_undeclared`], the same series with the block not declared.

#![warn(missing_docs)]

pub mod images;
pub mod kinematics;
pub mod monitoring;
pub mod plan_agreement;
pub mod scenes;
pub mod series;
pub mod ttf_benchmark;
pub mod ttf_bound;
pub mod ttf_undeclared;
