//! The helpers every test binary shares, one copy of each: a binary takes them all with
//! `#[path = "../support/mod.rs"] mod support;` and uses what it needs (the rest is dead code to
//! it, hence the `allow`).
//!
//! - `server`: paper data, synthetic epochs in the upload form, an in-process server and the
//!   daemon binary on ephemeral ports, table snapshots;
//! - `alerts`: a monitoring scene with known motion, configurations with fast retries, a loopback
//!   webhook receiver that verifies signatures;
//! - `dashboard`: a site with a moving block filled through the API, page fetching and links;
//! - `watch`: rendered epochs written into a watched folder;
//! - `dbat`, `identify`, `bad_images`: DBAT's real photographs, the long-range scene and broken
//!   image files, the core's test helpers (`crates/cliffwatch-core/tests/support`), taken by path;
//! - `pg`: a throwaway PostgreSQL cluster;
//! - `plot`: the long-history plot checked on either backend;
//! - `unique_keys`: JSON answers parsed with each key once per object (the server helpers' reads).
#![allow(dead_code)]

/// The folder that holds the shared reference data, `../shared` beside the repository, as a
/// string literal (for the core's helpers taken below).
macro_rules! shared_dir {
    () => {
        concat!(env!("CARGO_MANIFEST_DIR"), "/../shared")
    };
}

pub mod alerts;
#[path = "../../crates/cliffwatch-core/tests/support/bad_images.rs"]
pub mod bad_images;
pub mod dashboard;
#[path = "../../crates/cliffwatch-core/tests/support/dbat.rs"]
pub mod dbat;
#[path = "../../crates/cliffwatch-core/tests/support/identify.rs"]
pub mod identify;
pub mod pg;
pub mod plot;
pub mod server;
pub mod unique_keys;
pub mod watch;

use chrono::{DateTime, Duration, SecondsFormat, Utc};

/// The series' first epoch, 2026-11-01 09:00 UTC.
fn first_epoch() -> DateTime<Utc> {
    DateTime::parse_from_rfc3339("2026-11-01T09:00:00Z")
        .expect("a valid RFC 3339 time")
        .with_timezone(&Utc)
}

/// `k` days after the first epoch (2026-11-01 09:00 UTC), as RFC 3339 with `Z`.
pub fn day(k: usize) -> String {
    (first_epoch() + Duration::days(k as i64)).to_rfc3339_opts(SecondsFormat::Secs, true)
}

/// `hours` after the first epoch (2026-11-01 09:00 UTC), as RFC 3339 with `Z`.
pub fn hour(hours: usize) -> String {
    (first_epoch() + Duration::hours(hours as i64)).to_rfc3339_opts(SecondsFormat::Secs, true)
}

/// A free loopback TCP port (bound, read, released).
pub fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .map(|a| a.port())
        .expect("a free loopback port")
}
