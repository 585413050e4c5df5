//! The database: SQLite (the embedded default) or PostgreSQL, the same SQL on both through
//! sqlx's `Any` driver, each backend's migrations embedded and applied at open
//! (`migrations/sqlite`, `migrations/postgres`). All of the crate's SQL is here; nothing
//! outside this module names sqlx.
//!
//! Reads go through a pool, writes through a write pool. SQLite: one connection, one write
//! transaction at a time (`BEGIN IMMEDIATE`). PostgreSQL, where several nodes share the
//! database: advisory locks serialize each site's writers across nodes
//! ([`Store::begin_write_site`]), let different sites write in parallel, and give cluster-wide
//! jobs to one node at a time ([`Store::try_job_lock`]).
//!
//! One submodule per aggregate: [`sites`], [`epochs`] (their joint covariances:
//! [`joint_covariances`]), [`points`], [`groups`],
//! [`displacements`] (rows: [`displacement_row`]), [`block_motions`], [`pooled_forecasts`], [`alerts`],
//! [`alert_states`], [`webhooks`], [`outbox`], [`watch_state`], the dashboard's [`sessions`],
//! a retired site's deletion ([`site_removal`]);
//! [`series`] serves a point's displacement time series fast from the packed blocks of
//! [`series::blocks`] (layout: `series::record`), its wire writer (`series::wire`) formatting the API's bytes itself.
//! The rest: the pool and transactions (`pool`, opened by `open`), the store's time (`time`),
//! backups (`backup`), the backends' SQL differences (`dialect`), the error (`error`).
//!
//! # What differs between the backends (all of it)
//! - Connection set-up in [`Store::open`] (SQLite: WAL, `synchronous = FULL`, foreign keys,
//!   busy timeout, a read-only read pool, WAL checkpoints off the writer: [`wal_checkpoint`])
//!   and [`Store::connect`] (PostgreSQL).
//! - Placeholders of multi-row inserts ([`values_list`]): `$n` on PostgreSQL, `?` on SQLite.
//! - `BEGIN IMMEDIATE` in [`Store::begin_write`] and its siblings (PostgreSQL: `BEGIN` and
//!   advisory locks); [`outbox::claim_due`]'s `FOR UPDATE SKIP LOCKED`.
//! - Backups: `VACUUM INTO` in [`Store::backup`] and [`backup_file`]; PostgreSQL: `pg_dump`.
//! - The series read: SQLite's rows through the C API (`series::sqlite_raw`), PostgreSQL's through
//!   sqlx into packed records (`series::postgres`); the same writers format both.
//! - The migrations: the same schema; PostgreSQL's in one step, with `COLLATE "C"` text (the
//!   store relies on binary text order: RFC 3339 timestamps, cursors, [`TEXT_MAX`]) and `BYTEA`.
//! - BOOLEAN columns are selected as `CAST(… AS INTEGER)` ([`Flag`]): the `Any` driver reads no
//!   SQLite column declared BOOLEAN.
//!
//! Portable and used as is: `$1` placeholders, `ON CONFLICT … DO UPDATE/NOTHING` with
//! `excluded.`, `RETURNING`, timestamps as fixed-width RFC 3339 text, JSON documents as text.
//! Benchmarks and tests only, SQLite: `strftime`, `printf`, `WITH RECURSIVE` fills and the
//! `dbstat` table (`benches/service.rs`, `tests/service/series.rs`).

pub mod alert_repost;
pub(crate) mod alert_states;
pub mod alerts;
pub mod audit;
mod backup;
pub(crate) mod block_motions;
pub mod copy;
mod dialect;
pub(crate) mod displacement_row;
pub mod displacements;
pub(crate) mod epoch_health;
pub(crate) mod epoch_report;
pub mod epochs;
mod error;
pub(crate) mod groups;
pub mod joint_covariances;
mod open;
pub mod operations;
pub(crate) mod outbox;
pub mod plan_network;
pub mod points;
mod pool;
pub(crate) mod pooled_forecasts;
pub mod series;
pub mod sessions;
pub(crate) mod site_removal;
pub(crate) mod sites;
mod time;
pub mod wal_checkpoint;
pub(crate) mod watch_state;
pub mod webhooks;

pub use backup::backup_file;
pub(crate) use dialect::{is_postgres, rows_per_insert, values_list};
pub use dialect::{Flag, TEXT_MAX};
pub use error::StoreError;
pub use pool::{
    redacted_url, sqlite_path, Backend, Connection, JobLock, ReadConnection, ReadPool, Store,
    StoreOptions, WriteTransaction, JOB_LOCK_SPACE, POSTGRES_MIGRATOR, SITE_LOCK_SPACE,
    SQLITE_MIGRATOR, WRITE_LOCK_KEY,
};
pub use time::{clock, display_timestamp, now, parse_timestamp, shortened, timestamp};
