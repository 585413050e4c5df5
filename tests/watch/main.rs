//! The watched directory: images in, epochs out.
//!
//! One test binary per area (each binary links the whole crate once); the files are its modules.

#[path = "../bad_images/mod.rs"]
mod bad_images;
#[path = "../identify_support/mod.rs"]
mod identify_support;
#[path = "../service_support/mod.rs"]
mod service_support;
#[path = "../watch_support/mod.rs"]
mod watch_support;

mod bad_input;
mod dir;
mod first_epoch;
mod live;
mod sigma0;
mod weights;
