//! Simulated epochs with known truth, deterministic by seed (`rand_chacha::ChaCha8Rng`).
//!
//! Every generator returns the epoch in the upload form (`EpochInput`) and its [`Truth`] (the form
//! of the `*.truth.json` files `cliffwatch simulate` writes). Conventions are those of
//! `docs/model.md`: object
//! coordinates in m, image coordinates in mm (x right, y up) or pixels, camera coordinates
//! `R (X − Xo)`, the camera looks along −r3, measured = `brown_distort(projected)`.
//!
//! Random draws come from separate ChaCha streams of one seed — geometry, image noise, start
//! errors — so changing the noise level leaves the geometry and the start errors as they were.
//!
//! Scenes:
//! - [`paper_table1`]: Ono & Hattori's Table 1 scene, cases 1–3 (the same geometry as the shared
//!   truth files; noise 0.001 mm; start errors σ 10 mm).
//! - [`long_range`]: a 5 m × 3 m cliff face 100–110 m from 5 stations along a 60 m base, 400 mm lens,
//!   in a frame with Z toward the cameras or in East-North-Up with UTM-sized coordinates; with
//!   [`LongRangeParams::flat`] the nearly flat face (5 cm relief).
//! - [`calibration`]: a wide-angle convergent network of a flat 7 × 7 target plate with strong
//!   distortion, four control points, for the central model with full self-calibration.
//! - [`large`]: big networks for benchmarks (20 × 500, 100 × 10 000).
//! - [`swap_labels`]: a blunder, two targets' labels swapped in one image.

mod builder;
mod calibration;
mod large;
mod long_range;
mod paper;
#[cfg(test)]
mod tests;

pub use builder::*;
pub use calibration::*;
pub use large::*;
pub use long_range::*;
pub use paper::*;
