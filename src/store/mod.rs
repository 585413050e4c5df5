//! The database: SQLite through sqlx (WAL, foreign keys, busy timeout), migrations under
//! `migrations/` embedded and applied at open.
//!
//! Reads go through a pool; writes through a pool of one connection and `BEGIN IMMEDIATE`, so a
//! write transaction never has to upgrade a read lock ("database is locked"). The SQL avoids
//! SQLite-only forms where a standard one exists, so a PostgreSQL backend can follow.
//!
//! One submodule per aggregate: [`sites`], [`epochs`], [`points`], [`displacements`], [`alerts`],
//! [`webhooks`], [`watch_state`].

pub mod alerts;
pub mod displacements;
pub mod epochs;
pub mod points;
pub mod sites;
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
    /// The data directory cannot be created.
    #[error("data directory: {0}")]
    Io(#[from] std::io::Error),
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
    /// Opens (creating when missing) the database file, applies the migrations.
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
        Ok(Store { read, write })
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
