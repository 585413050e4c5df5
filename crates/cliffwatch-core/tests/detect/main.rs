//! Target detection, centring and identification against truth.
//!
//! One test binary per area (each binary links the whole crate once); the files are its modules,
//! and `tests/support/` holds the helpers every binary shares.

#[path = "../support/mod.rs"]
mod support;

mod first_epoch;
mod identify;
mod real;
mod real_adjust;
mod reference;
mod sigma;
mod synthetic;
