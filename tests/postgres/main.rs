//! The PostgreSQL backend and several nodes on one database (throwaway clusters the tests start).
//!
//! One test binary per area (each binary links the whole crate once); the files are its modules.

#[path = "../alerts_support/mod.rs"]
mod alerts_support;
#[path = "../pg_support/mod.rs"]
mod pg_support;
#[path = "../plot_support/mod.rs"]
mod plot_support;
#[path = "../watch_support/mod.rs"]
mod watch_support;

mod clocks;
mod nodes;
mod store;
mod watch;
