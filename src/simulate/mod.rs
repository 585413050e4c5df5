//! Simulated scenes with truth, for tests and benchmarks.
//!
//! - [`scenes`]: the paper's Table 1 scene, the long-range cliff, flat faces, calibration networks.
//! - [`images`]: rendered target images with ground-truth centres.
//! - [`monitoring`]: monitoring series (stable points, a moving block, re-set-up cameras).

pub mod images;
pub mod monitoring;
pub mod scenes;
