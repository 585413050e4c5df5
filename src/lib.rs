//! # cliffwatch
//!
//! A daemon that watches rock cliffs for movement. For each epoch (a campaign of images) it takes the
//! targets' image coordinates, runs a bundle adjustment with the orthogonal projection model (Ono &
//! Hattori) and a self-calibrated principal distance, stores coordinates with their precision, computes
//! displacements against a reference epoch and raises alerts.
//!
//! ## Crates
//! The pure core (no I/O, no async, no database) is a crate of its own, [`cliffwatch_core`]:
//! `photogrammetry` (the upload form, start values, the orthogonal and central bundle
//! adjustments, precision, blunder detection), `detect` (images → circular targets → identified
//! observations), `analysis` (datum, congruence test, displacements, velocity, time to failure,
//! alert rules) and `contract` (the names of the domain's enums). The simulator of scenes with
//! truth, for tests, benchmarks and `cliffwatch simulate`, is [`cliffwatch_sim`].
//!
//! ## Module map
//! The daemon around it:
//! - [`config`]: layered configuration (file, environment, flags).
//! - [`store`]: all SQL (SQLite or PostgreSQL through sqlx, behind one `Store`); migrations under
//!   `migrations/sqlite/` and `migrations/postgres/`.
//! - [`service`]: the use cases, one file each (ingest an epoch, recompute a site, change its
//!   settings, acknowledge an alert); each owns its
//!   transaction and calls the core and the store.
//! - [`http`]: the HTTP layer below the API and the dashboard: the shared state, the router's
//!   composition, auth and sessions, errors and extractors.
//! - [`api`]: the HTTP API (axum) handlers and OpenAPI, on [`http`].
//! - [`dashboard`]: the HTML pages on the same port (maud templates, embedded uPlot and htmx), on
//!   [`http`] beside [`api`]; neither imports the other.
//! - [`cap`]: the public-warning feed, alerts as CAP 1.2 messages and an Atom feed of them.
//! - [`webhooks`]: signing, bodies, retry policy and one delivery attempt of the alert webhooks.
//! - [`url_path`]: the percent-encoding of URL path segments, shared by [`http`] and [`webhooks`].
//! - [`watch`]: the watched directory: its folders, each station's detection, the naming of the
//!   targets, and a folder's ingestion (as an upload, through [`service::ingest`]).
//! - [`workers`]: the background loops (webhook delivery, Alertmanager re-posts, the campaign
//!   check, retentions).
//! - [`daemon`] and [`shutdown`]: start and stop every part with one shutdown signal.
//!
//! A module is `pub` when the binary, the tests, the benchmarks or the examples use it; the
//! others (handlers, page templates, internal rows) are `pub(crate)`.

pub mod api;
pub mod cap;
pub mod config;
pub mod daemon;
pub mod dashboard;
pub mod http;
pub(crate) mod natural_order;
pub mod service;
pub mod shutdown;
pub mod store;
pub(crate) mod url_path;
pub mod watch;
pub mod webhooks;
pub mod workers;
