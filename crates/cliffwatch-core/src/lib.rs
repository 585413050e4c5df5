//! # cliffwatch-core
//!
//! The pure core of cliffwatch, a monitor of rock cliffs: the bundle adjustment with the orthogonal
//! projection model (Ono & Hattori) and a self-calibrated principal distance, the detection and
//! identification of circular targets in images, and the analysis of displacement series (datum
//! on stable points, congruence test, velocity, time to failure, alert rules). No I/O, no async, no
//! database: every function takes values and returns values.
//!
//! ## Modules
//! - [`photogrammetry`]: the epoch form, start values, the orthogonal and central bundle
//!   adjustments, datum, precision, blunder detection, the adjustment report.
//! - [`detect`]: images → circular targets with sub-pixel centres → identified observations.
//! - [`analysis`]: stable-point datum, congruence test, displacements, velocity, time to failure,
//!   alert rules.
//! - [`contract`]: the names of the domain's enums (levels, states, roles, models) as the API, the
//!   webhooks and the database spell them; the integers of JSON bodies.
//!
//! The feature `openapi` derives the OpenAPI schemas (utoipa) of the types the daemon's API
//! carries; it is off by default.

#![warn(missing_docs)]

pub mod analysis;
pub mod contract;
pub mod detect;
pub mod photogrammetry;
