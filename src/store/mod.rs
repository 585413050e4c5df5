//! The database: SQLite through sqlx (WAL, foreign keys, busy timeout), migrations under
//! `migrations/` embedded and applied at open.
//!
//! Reads go through a pool; writes through a pool of one connection and `BEGIN IMMEDIATE`, so a
//! write transaction never has to upgrade a read lock ("database is locked"). The SQL avoids
//! SQLite-only forms where a standard one exists, so a PostgreSQL backend can follow.
//!
//! One submodule per aggregate: [`sites`], [`epochs`], [`points`], [`groups`], [`displacements`], [`alerts`],
//! [`webhooks`], [`watch_state`]; [`series`] serves a point's displacement time series fast from
//! the packed blocks of [`series_blocks`] (layout: [`series_record`]).
//!
//! # SQLite-specific constructs (all of them; what a PostgreSQL backend would replace)
//! - Connection set-up in [`Store::open`] and [`backup_file`]: `SqliteConnectOptions` with WAL,
//!   `synchronous = NORMAL`, `foreign_keys`, busy timeout, read-only read pool (PostgreSQL: a
//!   `PgPool`; foreign keys and MVCC readers are built in).
//! - `BEGIN IMMEDIATE` in [`Store::begin_write`] (PostgreSQL: `BEGIN`; writers do not upgrade locks).
//! - `VACUUM INTO ?` in [`Store::backup`] and [`backup_file`] (PostgreSQL: `pg_dump`/base backups).
//! - [`sqlite_raw`]: the SQLite C API under sqlx's connection, used by [`series`] only; the portable
//!   read of the same rows is [`displacements::series`] (a PostgreSQL backend feeds the series
//!   writers from its own row loop, e.g. `COPY … TO STDOUT` or a cursor).
//! - `WITHOUT ROWID` on `displacements` in the first migration (SQLite's clustering clause;
//!   PostgreSQL: the same primary key, plus `CLUSTER` if wanted). Migrations are SQLite's dialect
//!   otherwise only in types that PostgreSQL reads the same way (`TEXT`, `BIGINT`,
//!   `DOUBLE PRECISION`, `BOOLEAN`, `BLOB` — PostgreSQL `BYTEA`); a PostgreSQL backend keeps its
//!   own migration directory.
//! - [`series`]' statement merges `series_blocks` and `displacements` with `UNION ALL … ORDER BY
//!   1` and untyped `NULL` columns (PostgreSQL wants them cast, e.g. `NULL::bytea`). The blocks'
//!   bytes are the crate's own layout ([`series_record`], little-endian), not SQLite's.
//! - `?` placeholders in every query (PostgreSQL: `$1`, `$2`, …).
//! - [`TEXT_MAX`], the open upper bound of text ranges, relies on binary (memcmp) text order,
//!   SQLite's default collation (PostgreSQL: `COLLATE "C"` on the key columns or no bound).
//! - Portable and used as is: `ON CONFLICT … DO UPDATE/NOTHING` with `excluded.`, `RETURNING`
//!   (SQLite ≥ 3.35), `ALTER TABLE … ADD COLUMN`, timestamps as fixed-width RFC 3339 text, JSON
//!   documents as text.
//! - Benchmarks and tests only: `strftime`, `printf`, `WITH RECURSIVE` fills and the `dbstat`
//!   table (`benches/service.rs`, `tests/service_series.rs`).

pub mod alerts;
pub mod block_motions;
pub mod displacements;
pub mod epochs;
pub mod groups;
pub mod points;
pub mod series;
pub mod series_blocks;
pub mod series_columns;
pub mod series_record;
pub mod sites;
pub mod sqlite_raw;
pub mod watch_state;
pub mod webhooks;

use std::path::Path;
use std::str::FromStr;
use std::time::Duration;

use chrono::{DateTime, SecondsFormat, Utc};
use sqlx::sqlite::{SqliteConnectOptions, SqliteJournalMode, SqlitePoolOptions, SqliteSynchronous};
use sqlx::{Sqlite, SqlitePool, Transaction};
use thiserror::Error;

/// The embedded migrations.
pub static MIGRATOR: sqlx::migrate::Migrator = sqlx::migrate!("./migrations");

/// A database error.
#[derive(Debug, Error)]
pub enum StoreError {
    /// The database failed.
    #[error("database: {0}")]
    Sql(#[from] sqlx::Error),
    /// A migration failed.
    #[error("migration: {0}")]
    Migrate(#[from] sqlx::migrate::MigrateError),
    /// A stored JSON column does not parse.
    #[error("stored JSON: {0}")]
    Json(#[from] serde_json::Error),
    /// A direct SQLite call failed (the series reader, [`sqlite_raw`]).
    #[error("sqlite ({code}): {message}")]
    Sqlite {
        /// SQLite result code (0: the reader thread itself failed).
        code: i32,
        /// What failed and SQLite's message.
        message: String,
    },
    /// A packed series block cannot be written or read ([`series_blocks`], [`series_record`]).
    #[error("series block: {0}")]
    Block(String),
    /// The data directory cannot be created.
    #[error("data directory: {0}")]
    Io(#[from] std::io::Error),
    /// A stored value is not one this version knows.
    #[error("stored value: {0}")]
    Corrupt(String),
}

/// Pool sizes and timeouts.
#[derive(Debug, Clone)]
pub struct StoreOptions {
    /// Connections of the read pool.
    pub read_connections: u32,
    /// SQLite busy timeout.
    pub busy_timeout: Duration,
}

impl Default for StoreOptions {
    fn default() -> Self {
        StoreOptions {
            read_connections: 8,
            busy_timeout: Duration::from_secs(10),
        }
    }
}

/// Handle on the database: a read pool and a single write connection. Cheap to clone.
#[derive(Debug, Clone)]
pub struct Store {
    read: SqlitePool,
    write: SqlitePool,
}

impl Store {
    /// Opens (creating when missing) the database file, applies the migrations, packs the series
    /// of sites stored before migration 20261122000700 ([`series_blocks::backfill`]).
    pub async fn open(path: &Path, options: &StoreOptions) -> Result<Store, StoreError> {
        if let Some(dir) = path.parent() {
            if !dir.as_os_str().is_empty() {
                std::fs::create_dir_all(dir)?;
            }
        }
        let connect = SqliteConnectOptions::from_str("sqlite:")?
            .filename(path)
            .create_if_missing(true)
            .journal_mode(SqliteJournalMode::Wal)
            .synchronous(SqliteSynchronous::Normal)
            .foreign_keys(true)
            .busy_timeout(options.busy_timeout);
        let write = SqlitePoolOptions::new()
            .max_connections(1)
            .min_connections(1)
            .acquire_timeout(Duration::from_secs(600))
            .connect_with(connect.clone())
            .await?;
        MIGRATOR.run(&write).await?;
        let read = SqlitePoolOptions::new()
            .max_connections(options.read_connections.max(1))
            .acquire_timeout(Duration::from_secs(60))
            .connect_with(connect.read_only(true))
            .await?;
        let store = Store { read, write };
        series_blocks::backfill(&store).await?;
        Ok(store)
    }

    /// The read pool.
    pub fn reader(&self) -> &SqlitePool {
        &self.read
    }

    /// Opens a write transaction (`BEGIN IMMEDIATE`: takes the write lock at once).
    pub async fn begin_write(&self) -> Result<Transaction<'static, Sqlite>, StoreError> {
        Ok(self.write.begin_with("BEGIN IMMEDIATE").await?)
    }

    /// Readiness: the database answers and every embedded migration is applied.
    pub async fn ready(&self) -> Result<bool, StoreError> {
        let applied: i64 =
            sqlx::query_scalar("SELECT COUNT(*) FROM _sqlx_migrations WHERE success = TRUE")
                .fetch_one(&self.read)
                .await?;
        Ok(applied as usize >= MIGRATOR.iter().count())
    }

    /// Writes a consistent copy of the live database to `target` (`VACUUM INTO`), while it serves.
    pub async fn backup(&self, target: &Path) -> Result<(), StoreError> {
        let target = target.to_string_lossy().to_string();
        sqlx::query("VACUUM INTO ?")
            .bind(target)
            .execute(&self.read)
            .await?;
        Ok(())
    }

    /// Closes both pools (checkpoints the WAL).
    pub async fn close(&self) {
        self.read.close().await;
        self.write.close().await;
    }
}

/// Above every stored text key under binary text order: the open upper bound of range queries.
pub const TEXT_MAX: &str = "\u{10FFFF}";

/// Formats a time the way the store keeps it: RFC 3339, UTC, microseconds (sorts as text).
pub fn timestamp(t: DateTime<Utc>) -> String {
    t.to_rfc3339_opts(SecondsFormat::Micros, true)
}

/// The current time in the store's format.
pub fn now() -> String {
    timestamp(Utc::now())
}

/// Parses a stored time.
pub fn parse_timestamp(s: &str) -> Option<DateTime<Utc>> {
    DateTime::parse_from_rfc3339(s)
        .ok()
        .map(|t| t.with_timezone(&Utc))
}

/// Formats a stored time for the API: RFC 3339 with `Z`, seconds unless sub-second.
pub fn display_timestamp(s: &str) -> String {
    if let Some(short) = series::shortened(s.as_bytes()) {
        let mut out = String::with_capacity(short.len() + 1);
        out.push_str(std::str::from_utf8(short).unwrap_or_default());
        out.push('Z');
        return out;
    }
    parse_timestamp(s)
        .map(|t| t.to_rfc3339_opts(SecondsFormat::AutoSi, true))
        .unwrap_or_else(|| s.to_string())
}

/// Copies the database file at `source` to `target` with `VACUUM INTO` through a read-only
/// connection: a consistent snapshot while a server keeps writing; no migrations are run.
pub async fn backup_file(
    source: &Path,
    target: &Path,
    busy_timeout: Duration,
) -> Result<(), StoreError> {
    use sqlx::{ConnectOptions, Connection};
    let mut conn = SqliteConnectOptions::from_str("sqlite:")?
        .filename(source)
        .read_only(true)
        .busy_timeout(busy_timeout)
        .connect()
        .await?;
    sqlx::query("VACUUM INTO ?")
        .bind(target.to_string_lossy().to_string())
        .execute(&mut conn)
        .await?;
    conn.close().await?;
    Ok(())
}
