//! What the adjustment says about itself: `precision` (cofactors of points and images from the
//! reduced system), `snooping` (normalised residuals and blunder detection), and [`quality`]
//! (the paper's quality indexes against truth).

pub(crate) mod variance_factor;
pub use variance_factor::{GlobalTest, GLOBAL_TEST_CONFIDENCE};
pub mod design;
pub(crate) mod precision;
pub mod quality;
pub(crate) mod snooping;
pub mod variance_components;
