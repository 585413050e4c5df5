//! The pure displacement analysis: datum, Kalman filter and forecast, rules, simulated series.
//!
//! One test binary per area (each binary links the whole crate once); the files are its modules,
//! and `tests/support/` holds the helpers every binary shares.

#[path = "../support/mod.rs"]
mod support;

mod alert_fixtures;
mod alert_rules;
mod alerts;
mod datum;
mod kalman;
mod reference_stability;
mod sensitivity;
mod simulation;
mod ttf;
mod undeclared;
