//! The PostgreSQL backend and several nodes on one database (throwaway clusters the tests start).
//!
//! One test binary per area (each binary links the whole crate once); the files are its modules,
//! and `tests/support/` holds the helpers every binary shares.

#[path = "../support/mod.rs"]
mod support;

mod clocks;
mod nodes;
mod retire;
mod sessions;
mod store;
mod watch;
