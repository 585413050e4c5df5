//! Alerting through the service: series, blocks, recompute, failed analyses, the alert service.
//!
//! One test binary per area (each binary links the whole crate once); the files are its modules,
//! and `tests/support/` holds the helpers every binary shares.

#[path = "../support/mod.rs"]
mod support;

mod blocks;
mod datum;
mod failed;
mod incidents;
mod recompute;
mod series;
mod service;
