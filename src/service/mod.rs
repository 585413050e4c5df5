//! The use cases, one file each. Each owns its transaction, calls the pure core
//! ([`cliffwatch_core::photogrammetry`], [`cliffwatch_core::analysis`]) on blocking threads and the store
//! ([`crate::store`]) for every read and write; the API handlers, the watched directory and the
//! daemon call them; the daemon's background loops are in [`crate::workers`].
//!
//! - [`ingest`]: an epoch in (upload or watched directory): adjust, analyse, alert, one
//!   transaction.
//! - [`upload`]: an upload as the client sent it (JSON, or CSV with its camera and time) read
//!   into the upload form, ingested, and read back as stored ([`stored_epoch`]).
//! - [`recompute`]: a site's derived series again after its history changed.
//! - [`sites`]: a site created, its definition checked.
//! - [`site_settings`]: reference epoch and block groups, with the recompute they cause.
//! - [`site_admin`]: a site's settings edited, a group deleted, each change in the audit trail.
//! - [`site_lifecycle`]: a site retired (alerts closed), its data exported, then deleted.
//! - [`webhooks`]: webhook endpoints added and removed.
//! - [`configured`]: the sites and webhooks of the configuration file, applied at start.
//! - [`acknowledge`]: staff acknowledge an alert.
//! - [`incidents`]: the open alerts gathered per block or point, what staff act on, and their
//!   acknowledgement in one action; [`forecast`] states a subject's failure time.
//!
//! Adjustment health: [`apriori_sigma`] estimates the cameras' a-priori σ from the recent
//! epochs' variance components and applies it when the site asks.
//!
//! Campaign design: [`plan`] the pre-analysis of a plan, and the what-if on a site's network.
//!
//! Admission: [`admission`] bounds the uploads a node processes at once.
//!
//! Shared steps: [`analysis_inputs`] loads what the analysis needs, [`alert_outcome`] writes
//! what the alert rules decide (state, alerts, outbox).

pub(crate) mod acknowledge;
pub mod admission;
pub(crate) mod alert_outcome;
pub(crate) mod analysis_inputs;
pub mod apriori_sigma;
pub mod configured;
pub(crate) mod error;
pub mod forecast;
pub mod incident_subject;
pub mod incidents;
pub mod ingest;
pub mod plan;
pub mod recompute;
pub mod site_admin;
pub mod site_lifecycle;
pub(crate) mod site_settings;
pub mod sites;
pub mod stored_epoch;
pub mod upload;
pub mod webhooks;

pub use error::ServiceError;
