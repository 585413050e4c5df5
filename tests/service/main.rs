//! The HTTP API against a real server: uploads, series, concurrency, crashes.
//!
//! One test binary per area (each binary links the whole crate once); the files are its modules,
//! and `tests/support/` holds the helpers every binary shares.

#[path = "../support/mod.rs"]
mod support;

mod access;
mod admin;
mod bounded;
mod compute_bound;
mod concurrency;
mod crash;
mod implausible;
mod joint_covariance;
mod openapi;
mod plan;
mod point_settings;
mod rejections;
mod retention;
mod retire;
mod series;
mod unique_keys;
mod uploads;
mod wal;
