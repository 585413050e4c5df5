//! The watched directory: images in, epochs out.
//!
//! One test binary per area (each binary links the whole crate once); the files are its modules.

#[path = "../identify_support/mod.rs"]
mod identify_support;
#[path = "../service_support/mod.rs"]
mod service_support;
#[path = "../watch_support/mod.rs"]
mod watch_support;

mod dir;
mod first_epoch;
mod live;
mod sigma0;
mod weights;
