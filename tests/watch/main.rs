//! The watched directory: images in, epochs out.
//!
//! One test binary per area (each binary links the whole crate once); the files are its modules,
//! and `tests/support/` holds the helpers every binary shares.

#[path = "../support/mod.rs"]
mod support;

mod bad_input;
mod detection_settings;
mod dir;
mod first_epoch;
mod inside;
mod live;
mod real_first_epoch;
mod retired;
mod sigma0;
mod weights;
