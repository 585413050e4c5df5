//! Webhook delivery and payload formats.
//!
//! One test binary per area (each binary links the whole crate once); the files are its modules.

#[path = "../alerts_support/mod.rs"]
mod alerts_support;

mod alertmanager;
mod configured;
mod delivery;
mod format;
mod order;
mod receivers;
