//! Webhook delivery and payload formats.
//!
//! One test binary per area (each binary links the whole crate once); the files are its modules,
//! and `tests/support/` holds the helpers every binary shares.

#[path = "../support/mod.rs"]
mod support;

mod alertmanager;
mod configured;
mod delivery;
mod format;
mod order;
mod receivers;
