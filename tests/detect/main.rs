//! Target detection, centring and identification against truth.
//!
//! One test binary per area (each binary links the whole crate once); the files are its modules.

#[path = "../bad_images/mod.rs"]
mod bad_images;
#[path = "../identify_support/mod.rs"]
mod identify_support;

mod bad_input;
mod first_epoch;
mod identify;
mod real;
mod real_adjust;
mod reference;
mod sigma;
mod synthetic;
