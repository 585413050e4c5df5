//! The pure displacement analysis: datum, Kalman filter and forecast, rules, simulated series.
//!
//! One test binary per area (each binary links the whole crate once); the files are its modules.

#[path = "../analysis_common/mod.rs"]
mod analysis_common;

mod alert_fixtures;
mod alert_rules;
mod alerts;
mod datum;
mod kalman;
mod reference_stability;
mod simulation;
mod ttf;
