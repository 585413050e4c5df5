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
//! [`displacements`] (rows: [`displacement_row`]), [`block_motions`], [`alerts`],
//! [`alert_states`], [`webhooks`], [`outbox`], [`watch_state`]; [`series`] serves a point's
//! displacement time series fast from the packed blocks of [`series_blocks`] (layout:
//! [`series_record`]).
//!
//! # What differs between the backends (all of it)
//! - Connection set-up in [`Store::open`] (SQLite: WAL, `synchronous = FULL`, foreign keys,
//!   busy timeout, a read-only read pool, WAL checkpoints off the writer: [`wal_checkpoint`])
//!   and [`Store::connect`] (PostgreSQL).
//! - Placeholders of multi-row inserts ([`values_list`]): `$n` on PostgreSQL, `?` on SQLite.
//! - `BEGIN IMMEDIATE` in [`Store::begin_write`] and its siblings (PostgreSQL: `BEGIN` and
//!   advisory locks); [`outbox::claim_due`]'s `FOR UPDATE SKIP LOCKED`.
//! - Backups: `VACUUM INTO` in [`Store::backup`] and [`backup_file`]; PostgreSQL: `pg_dump`.
//! - The series read: SQLite's rows through the C API ([`sqlite_raw`]), PostgreSQL's through
//!   sqlx into packed records ([`series_postgres`]); the same writers format both.
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
pub(crate) mod block_motions;
pub mod copy;
pub(crate) mod displacement_row;
pub mod displacements;
pub(crate) mod epoch_report;
pub mod epochs;
pub(crate) mod groups;
pub mod joint_covariances;
pub(crate) mod outbox;
pub mod points;
pub mod series;
pub mod series_blocks;
pub mod series_columns;
pub(crate) mod series_postgres;
pub(crate) mod series_record;
pub(crate) mod sites;
pub(crate) mod sqlite_raw;
pub mod wal_checkpoint;
pub(crate) mod watch_state;
pub mod webhooks;

use std::path::Path;
use std::str::FromStr;
use std::time::Duration;

use chrono::{DateTime, SecondsFormat, Utc};
use sqlx::any::{AnyConnectOptions, AnyPoolOptions};
use sqlx::pool::PoolConnection;
use sqlx::postgres::{PgConnectOptions, PgPoolOptions};
use sqlx::sqlite::{SqliteConnectOptions, SqliteJournalMode, SqlitePoolOptions, SqliteSynchronous};
use sqlx::{
    Any, AnyConnection, AnyPool, ConnectOptions, Executor, PgPool, SqlitePool, Transaction,
};
use thiserror::Error;

/// The embedded migrations of SQLite (`migrations/sqlite`).
pub static SQLITE_MIGRATOR: sqlx::migrate::Migrator = sqlx::migrate!("./migrations/sqlite");

/// The embedded migrations of PostgreSQL (`migrations/postgres`).
pub static POSTGRES_MIGRATOR: sqlx::migrate::Migrator = sqlx::migrate!("./migrations/postgres");

/// A database connection, as the store's functions take it: a write transaction
/// ([`Store::begin_write`]) or a read connection ([`Store::read`]) derefs to one.
pub type Connection = AnyConnection;

/// A write transaction: commits with `commit()`, rolls back when dropped.
pub type WriteTransaction = Transaction<'static, Any>;

/// Held while this node runs a cluster-wide job ([`Store::try_job_lock`]); dropping it ends
/// the job's lock (PostgreSQL: its transaction rolls back).
pub struct JobLock {
    _tx: Option<Transaction<'static, Any>>,
}

/// A connection of the read pool, returned to it when dropped.
pub type ReadConnection = PoolConnection<Any>;

/// The read pool ([`Store::reader`]): each statement run on it takes a connection for itself.
pub type ReadPool = AnyPool;

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
    /// A stored name (level, state, role, model…) is not one this version knows.
    #[error("stored value: {0}")]
    Name(#[from] crate::contract_names::UnknownName),
    /// The database URL names no backend this version has.
    #[error("database URL '{0}': want sqlite://PATH or postgres://…")]
    Url(String),
}

impl StoreError {
    /// The database refused a value of the request, not the request's moment: PostgreSQL's
    /// SQLSTATE class 22, "data exception" (e.g. 22021, text holding the NUL character, which
    /// SQLite stores). Sending the same value again fails the same way.
    pub fn is_data_exception(&self) -> bool {
        match self {
            StoreError::Sql(sqlx::Error::Database(e)) => e
                .code()
                // A SQLSTATE has five characters; SQLite's result codes are at most four digits.
                .is_some_and(|c| c.len() == 5 && c.starts_with("22")),
            _ => false,
        }
    }
}

/// Pool sizes and timeouts.
#[derive(Debug, Clone)]
pub struct StoreOptions {
    /// Connections of the read pool.
    pub read_connections: u32,
    /// SQLite busy timeout.
    pub busy_timeout: Duration,
    /// PostgreSQL: connections of the write pool, i.e. write transactions of different sites this
    /// node runs at once (SQLite has one writer).
    pub write_connections: u32,
}

impl Default for StoreOptions {
    fn default() -> Self {
        StoreOptions {
            read_connections: 8,
            busy_timeout: Duration::from_secs(10),
            write_connections: 4,
        }
    }
}

/// The PostgreSQL advisory lock key of the writers ("cliffwat" in ASCII): taken exclusively by
/// a write transaction that may touch any site, shared by one that touches one site.
pub const WRITE_LOCK_KEY: i64 = 0x636c_6966_6677_6174;

/// The first key of PostgreSQL's two-key advisory locks of one site's writers (the second is
/// `hashtext(site)`; two sites with the same hash only wait for each other).
pub const SITE_LOCK_SPACE: i32 = 0x636c_6966;

/// The first key of the two-key advisory locks of cluster-wide jobs ([`Store::try_job_lock`]).
pub const JOB_LOCK_SPACE: i32 = 0x6a6f_6273;

/// The database behind a [`Store`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Backend {
    /// One SQLite file (the embedded default).
    Sqlite,
    /// A PostgreSQL database.
    Postgres,
}

/// Handle on the database: a read pool and a write pool, the same SQL on either backend
/// (sqlx's `Any` driver), plus the native pools of the hot reads. Cheap to clone.
#[derive(Debug, Clone)]
pub struct Store {
    backend: Backend,
    read: AnyPool,
    write: AnyPool,
    /// SQLite only: read-only native connections for [`series`] ([`sqlite_raw`]).
    sqlite_read: Option<SqlitePool>,
    /// PostgreSQL only: native connections for the upload's history read.
    postgres_read: Option<PgPool>,
    /// SQLite only: the connection that checkpoints the WAL ([`wal_checkpoint`]).
    checkpointer: Option<SqlitePool>,
}

/// The settings of every SQLite connection: foreign keys, `synchronous = FULL` (with WAL: each
/// commit syncs the WAL before it returns, so an epoch answered 201, or a watched folder moved to
/// `.done/`, survives a power loss; `NORMAL` would lose the last commits),
/// the busy timeout, and the WAL size at which a committing writer checkpoints itself
/// ([`wal_checkpoint::WRITER_AUTOCHECKPOINT_PAGES`]).
fn sqlite_pragmas(
    conn: &mut AnyConnection,
    busy_ms: u128,
) -> futures_core::future::BoxFuture<'_, Result<(), sqlx::Error>> {
    Box::pin(async move {
        let pages = wal_checkpoint::WRITER_AUTOCHECKPOINT_PAGES;
        let sql = format!(
            "PRAGMA foreign_keys = ON; PRAGMA synchronous = FULL; PRAGMA busy_timeout = {busy_ms}; \
             PRAGMA wal_autocheckpoint = {pages};"
        );
        conn.execute(sql.as_str()).await?;
        Ok(())
    })
}

/// `url` without its password, for logs.
pub fn redacted_url(url: &str) -> String {
    match url::Url::parse(url) {
        Ok(mut u) if u.password().is_some() => {
            let _ = u.set_password(Some("***"));
            u.to_string()
        }
        // Anything else with an `@` (a typo such as `cliff:pw@db/cw`, which parses as a URL of
        // scheme `cliff`): whatever stands before it may be a password.
        _ => match url.rsplit_once('@') {
            Some((before, host)) => match before.split_once("://") {
                Some((scheme, _)) => format!("{scheme}://***@{host}"),
                None => format!("***@{host}"),
            },
            None => url.to_string(),
        },
    }
}

/// The SQLite file of a `sqlite://PATH` or `sqlite:PATH` URL.
pub fn sqlite_path(url: &str) -> Option<&Path> {
    let rest = url.strip_prefix("sqlite:")?;
    let rest = rest.strip_prefix("//").unwrap_or(rest);
    Some(Path::new(rest.split('?').next().unwrap_or(rest)))
}

impl Store {
    /// Opens the database of `url`: `sqlite://PATH` (the file is created when missing) or
    /// `postgres://USER@HOST:PORT/DB`; applies that backend's migrations.
    pub async fn connect(url: &str, options: &StoreOptions) -> Result<Store, StoreError> {
        if let Some(path) = sqlite_path(url) {
            return Store::open(path, options).await;
        }
        if url.starts_with("postgres://") || url.starts_with("postgresql://") {
            return Store::open_postgres(url, options).await;
        }
        Err(StoreError::Url(redacted_url(url)))
    }

    /// Opens (creating when missing) the SQLite file, applies the migrations, packs the series
    /// of sites stored before migration 20261122000700 ([`series_blocks::backfill`]).
    pub async fn open(path: &Path, options: &StoreOptions) -> Result<Store, StoreError> {
        sqlx::any::install_default_drivers();
        if let Some(dir) = path.parent() {
            if !dir.as_os_str().is_empty() {
                std::fs::create_dir_all(dir)?;
            }
        }
        let native = SqliteConnectOptions::from_str("sqlite:")?
            .filename(path)
            .create_if_missing(true)
            .journal_mode(SqliteJournalMode::Wal)
            .synchronous(SqliteSynchronous::Full)
            .foreign_keys(true)
            .busy_timeout(options.busy_timeout);
        // Create the file and switch it to WAL once, natively.
        native.connect().await?;
        let busy_ms = options.busy_timeout.as_millis();
        let any = |o: &SqliteConnectOptions| AnyConnectOptions::from_url(&o.to_url_lossy());
        // A connection to a local file does not go away: no ping before each use (sqlx's
        // default costs a round trip to the connection's thread per acquisition).
        let write = AnyPoolOptions::new()
            .max_connections(1)
            .min_connections(1)
            .test_before_acquire(false)
            .acquire_timeout(Duration::from_secs(600))
            .after_connect(move |conn, _| sqlite_pragmas(conn, busy_ms))
            .connect_with(any(&native)?)
            .await?;
        SQLITE_MIGRATOR.run(&write).await?;
        let read = AnyPoolOptions::new()
            .max_connections(options.read_connections.max(1))
            .test_before_acquire(false)
            .acquire_timeout(Duration::from_secs(60))
            .after_connect(move |conn, _| sqlite_pragmas(conn, busy_ms))
            .connect_with(any(&native.clone().read_only(true))?)
            .await?;
        let checkpointer = SqlitePoolOptions::new()
            .max_connections(1)
            .acquire_timeout(Duration::from_secs(60))
            .connect_with(native.clone())
            .await?;
        let sqlite_read = SqlitePoolOptions::new()
            .max_connections(options.read_connections.max(1))
            .test_before_acquire(false)
            .acquire_timeout(Duration::from_secs(60))
            .connect_with(native.read_only(true))
            .await?;
        let store = Store {
            backend: Backend::Sqlite,
            read,
            write,
            sqlite_read: Some(sqlite_read),
            postgres_read: None,
            checkpointer: Some(checkpointer),
        };
        series_blocks::backfill(&store).await?;
        Ok(store)
    }

    /// Opens a PostgreSQL database, applies its migrations and packs the series of sites stored
    /// before migration 20261125000300 ([`series_blocks::backfill`]). Writes go through a pool of
    /// [`StoreOptions::write_connections`]; the advisory locks of [`Store::begin_write_site`]
    /// decide which of them may run side by side.
    async fn open_postgres(url: &str, options: &StoreOptions) -> Result<Store, StoreError> {
        sqlx::any::install_default_drivers();
        // Prepared statements are cached per connection; that needs the patched sqlx-core
        // (vendor/README.md: 0.8.6 sent a NULL f64 as float4, which a cached statement then
        // kept).
        let parsed = url::Url::parse(url).map_err(|_| StoreError::Url(redacted_url(url)))?;
        let connect = AnyConnectOptions::from_url(&parsed)?;
        let write = AnyPoolOptions::new()
            .max_connections(options.write_connections.max(1))
            .min_connections(1)
            .acquire_timeout(Duration::from_secs(600))
            .connect_with(connect.clone())
            .await?;
        POSTGRES_MIGRATOR.run(&write).await?;
        let read = AnyPoolOptions::new()
            .max_connections(options.read_connections.max(1))
            .acquire_timeout(Duration::from_secs(60))
            .connect_with(connect)
            .await?;
        // One history read per write transaction at most.
        let postgres_read = PgPoolOptions::new()
            .max_connections(options.write_connections.max(1))
            .acquire_timeout(Duration::from_secs(60))
            .connect_lazy_with(PgConnectOptions::from_url(&parsed)?);
        let store = Store {
            backend: Backend::Postgres,
            read,
            write,
            sqlite_read: None,
            postgres_read: Some(postgres_read),
            checkpointer: None,
        };
        series_blocks::backfill(&store).await?;
        Ok(store)
    }

    /// Which database this is.
    pub fn backend(&self) -> Backend {
        self.backend
    }

    /// The read pool.
    pub fn reader(&self) -> &ReadPool {
        &self.read
    }

    /// SQLite only: the native read-only pool of the series fast path.
    pub fn sqlite_reader(&self) -> Option<&SqlitePool> {
        self.sqlite_read.as_ref()
    }

    /// PostgreSQL only: the native read pool of the upload's history read (sqlx's `Any` driver
    /// copies every value of a row once more than the native driver; the history is 21 000).
    pub fn postgres_reader(&self) -> Option<&PgPool> {
        self.postgres_read.as_ref()
    }

    /// A connection of the read pool, for a use case that reads several times before it writes.
    pub async fn read(&self) -> Result<ReadConnection, StoreError> {
        Ok(self.read.acquire().await?)
    }

    /// Opens a write transaction that may touch any site; it runs alone. SQLite: `BEGIN
    /// IMMEDIATE` takes the write lock at once, so a write never has to upgrade a read lock
    /// ("database is locked"). PostgreSQL: the advisory lock [`WRITE_LOCK_KEY`], taken
    /// exclusively, does the same for every node on the database, so a read-then-write step
    /// sees no other writer, as on SQLite.
    pub async fn begin_write(&self) -> Result<WriteTransaction, StoreError> {
        self.begin_scoped(LockScope::All).await
    }

    /// Opens a write transaction that touches only `site`'s rows (and appends webhook
    /// messages). SQLite: as [`Store::begin_write`]. PostgreSQL: [`WRITE_LOCK_KEY`] shared and
    /// the site's own advisory lock ([`SITE_LOCK_SPACE`]) exclusive, so one site's writes are
    /// serialized across nodes (its epochs analysed in `observed_at` order, as on one node)
    /// while different sites' writes proceed in parallel.
    pub async fn begin_write_site(&self, site: &str) -> Result<WriteTransaction, StoreError> {
        self.begin_scoped(LockScope::Site(site)).await
    }

    /// Opens a write transaction for rows a statement claims itself (`FOR UPDATE SKIP LOCKED`:
    /// the webhook deliveries). SQLite: as [`Store::begin_write`]. PostgreSQL: only
    /// [`WRITE_LOCK_KEY`] shared, so claims of several nodes and sites' writes run side by side.
    pub async fn begin_write_rows(&self) -> Result<WriteTransaction, StoreError> {
        self.begin_scoped(LockScope::Rows).await
    }

    async fn begin_scoped(&self, scope: LockScope<'_>) -> Result<WriteTransaction, StoreError> {
        if self.backend == Backend::Sqlite {
            return Ok(self.write.begin_with("BEGIN IMMEDIATE").await?);
        }
        let mut tx = self.write.begin().await?;
        let global = match scope {
            LockScope::All => "SELECT pg_advisory_xact_lock($1)",
            LockScope::Site(_) | LockScope::Rows => "SELECT pg_advisory_xact_lock_shared($1)",
        };
        // Always the global key first, then the site's: one order, no deadlock.
        sqlx::query(global)
            .bind(WRITE_LOCK_KEY)
            .execute(&mut *tx)
            .await?;
        if let LockScope::Site(site) = scope {
            sqlx::query("SELECT pg_advisory_xact_lock($1, hashtext($2))")
                .bind(SITE_LOCK_SPACE)
                .bind(site)
                .execute(&mut *tx)
                .await?;
        }
        Ok(tx)
    }

    /// A cluster-wide job (`name`: the overdue check, a watched folder) runs on one node at a
    /// time: PostgreSQL: `Some` while this node holds the job's advisory lock, `None` when another
    /// node holds it (the caller skips this pass). The lock lives in a transaction of its own
    /// connection and ends when the guard is dropped or the node dies. SQLite (one node):
    /// always `Some`.
    pub async fn try_job_lock(&self, name: &str) -> Result<Option<JobLock>, StoreError> {
        if self.backend == Backend::Sqlite {
            return Ok(Some(JobLock { _tx: None }));
        }
        let mut tx = self.read.begin().await?;
        let held: bool = sqlx::query_scalar("SELECT pg_try_advisory_xact_lock($1, hashtext($2))")
            .bind(JOB_LOCK_SPACE)
            .bind(name)
            .fetch_one(&mut *tx)
            .await?;
        Ok(held.then_some(JobLock { _tx: Some(tx) }))
    }

    /// The store's clock ([`clock`]); on PostgreSQL read on a connection of the read pool.
    pub async fn clock(&self) -> Result<DateTime<Utc>, StoreError> {
        if self.backend == Backend::Sqlite {
            return Ok(Utc::now());
        }
        clock(&mut *self.read().await?).await
    }

    /// Readiness: the database answers and every embedded migration is applied.
    pub async fn ready(&self) -> Result<bool, StoreError> {
        let applied: i64 =
            sqlx::query_scalar("SELECT COUNT(*) FROM _sqlx_migrations WHERE success = TRUE")
                .fetch_one(&self.read)
                .await?;
        let expected = match self.backend {
            Backend::Sqlite => SQLITE_MIGRATOR.iter().count(),
            Backend::Postgres => POSTGRES_MIGRATOR.iter().count(),
        };
        Ok(applied as usize >= expected)
    }

    /// SQLite: writes a consistent copy of the live database to `target` (`VACUUM INTO`), while
    /// it serves. PostgreSQL: refused; use `pg_dump` (see the README).
    pub async fn backup(&self, target: &Path) -> Result<(), StoreError> {
        if self.backend == Backend::Postgres {
            return Err(StoreError::Url(
                "backup of PostgreSQL: use pg_dump (README, 'Backups')".into(),
            ));
        }
        let target = target.to_string_lossy().to_string();
        sqlx::query("VACUUM INTO $1")
            .bind(target)
            .execute(&self.read)
            .await?;
        Ok(())
    }

    /// Closes the pools (SQLite: checkpoints the WAL).
    pub async fn close(&self) {
        self.read.close().await;
        self.write.close().await;
        if let Some(p) = &self.sqlite_read {
            p.close().await;
        }
        if let Some(p) = &self.postgres_read {
            p.close().await;
        }
        if let Some(p) = &self.checkpointer {
            p.close().await;
        }
    }
}

/// A BOOLEAN column as the store selects it, `CAST(column AS INTEGER)`: sqlx's `Any` driver
/// reads no SQLite column declared BOOLEAN, and the cast is the same on both backends.
pub struct Flag(i64);

impl sqlx::Type<Any> for Flag {
    fn type_info() -> sqlx::any::AnyTypeInfo {
        <i64 as sqlx::Type<Any>>::type_info()
    }

    fn compatible(ty: &sqlx::any::AnyTypeInfo) -> bool {
        <i64 as sqlx::Type<Any>>::compatible(ty)
    }
}

impl<'r> sqlx::Decode<'r, Any> for Flag {
    fn decode(value: sqlx::any::AnyValueRef<'r>) -> Result<Self, sqlx::error::BoxDynError> {
        <i64 as sqlx::Decode<'r, Any>>::decode(value).map(Flag)
    }
}

impl From<Flag> for bool {
    fn from(f: Flag) -> bool {
        f.0 != 0
    }
}

/// Whether the connection `db` is to PostgreSQL (else SQLite): for the few statements whose
/// text differs between the backends.
pub(crate) fn is_postgres(db: &AnyConnection) -> bool {
    db.backend_name() == "PostgreSQL"
}

/// Placeholders of a multi-row `VALUES` list on the connection `db`: `rows` groups of `cols`,
/// bound in order. PostgreSQL numbers them from `$1`; SQLite gets anonymous `?`, because sqlx
/// looks up the name of every parameter it binds and SQLite finds a named one by walking a list,
/// which made binding a statement of n named parameters cost n² (6 M instructions per upload).
pub(crate) fn values_list(db: &AnyConnection, rows: usize, cols: usize) -> String {
    let numbered = is_postgres(db);
    let mut out = String::with_capacity(rows * cols * 5);
    for r in 0..rows {
        out.push_str(if r == 0 { "(" } else { ", (" });
        for c in 0..cols {
            if c > 0 {
                out.push_str(", ");
            }
            if numbered {
                out.push('$');
                out.push_str(&(r * cols + c + 1).to_string());
            } else {
                out.push('?');
            }
        }
        out.push(')');
    }
    out
}

/// Rows per multi-row `INSERT` of `cols` columns: at most 30 000 parameters per statement, below
/// SQLite's limit (32 766) and PostgreSQL's (65 535). One statement per batch instead of one per
/// row is what keeps an upload's ~200 rows cheap.
pub(crate) fn rows_per_insert(cols: usize) -> usize {
    (30_000 / cols.max(1)).max(1)
}

/// Above every stored text key under binary text order: the open upper bound of range queries.
pub const TEXT_MAX: &str = "\u{10FFFF}";

/// What a PostgreSQL write transaction locks (SQLite has one writer and ignores it).
#[derive(Debug, Clone, Copy)]
enum LockScope<'a> {
    /// [`WRITE_LOCK_KEY`] exclusive: the transaction may touch any site and runs alone.
    All,
    /// [`WRITE_LOCK_KEY`] shared and the site's key exclusive.
    Site(&'a str),
    /// [`WRITE_LOCK_KEY`] shared only: the statements lock their rows themselves.
    Rows,
}

/// Formats a time the way the store keeps it: RFC 3339, UTC, microseconds (sorts as text).
pub fn timestamp(t: DateTime<Utc>) -> String {
    t.to_rfc3339_opts(SecondsFormat::Micros, true)
}

/// The current time in the store's format, on the store's [`clock`], so that the times rows
/// record (`created_at`, `updated_at`, …) keep their order whichever node wrote them.
pub async fn now(db: &mut AnyConnection) -> Result<String, StoreError> {
    Ok(timestamp(clock(db).await?))
}

/// The clock that webhook deliveries' due times and leases are written and compared with, the
/// same for every node: on PostgreSQL the database server's (`clock_timestamp()`), so nodes
/// whose clocks disagree never read a live claim as expired nor a new delivery as not yet due;
/// on SQLite (one node) this node's.
pub async fn clock(db: &mut AnyConnection) -> Result<DateTime<Utc>, StoreError> {
    if !is_postgres(db) {
        return Ok(Utc::now());
    }
    let micros: i64 = sqlx::query_scalar(
        "SELECT CAST(EXTRACT(EPOCH FROM clock_timestamp()) * 1000000 AS BIGINT)",
    )
    .fetch_one(&mut *db)
    .await?;
    DateTime::from_timestamp_micros(micros)
        .ok_or_else(|| StoreError::Corrupt(format!("database clock out of range: {micros} µs")))
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
/// connection: a consistent snapshot while a server keeps writing; no migrations are run. The
/// copy and its directory entry are synced to disk before this returns (`VACUUM INTO` does not
/// sync), so a backup reported written survives a power cut.
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
    sqlx::query("VACUUM INTO $1")
        .bind(target.to_string_lossy().to_string())
        .execute(&mut conn)
        .await?;
    conn.close().await?;
    let target = target.to_path_buf();
    tokio::task::spawn_blocking(move || sync_file_and_directory(&target))
        .await
        .map_err(|e| StoreError::Corrupt(format!("syncing the backup: {e}")))??;
    Ok(())
}

/// fsync of `path` and of the directory that holds it (the new file's entry).
fn sync_file_and_directory(path: &Path) -> std::io::Result<()> {
    std::fs::File::open(path)?.sync_all()?;
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    std::fs::File::open(dir)?.sync_all()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A password never reaches a log line or an error, however the URL is mistyped.
    #[test]
    fn urls_are_shown_without_their_password() {
        for url in [
            "postgres://cliff:s3cret@db:5432/cw",
            "postgress://cliff:s3cret@db/cw",
            "cliff:s3cret@db:5432/cw",
            "postgres://cliff:s3cret@",
        ] {
            let shown = redacted_url(url);
            assert!(!shown.contains("s3cret"), "{url} → {shown}");
        }
        assert_eq!(redacted_url("sqlite://data/cw.db"), "sqlite://data/cw.db");
    }

    /// A committed epoch survives a power loss: the writer syncs each commit (`FULL` = 2).
    #[tokio::test]
    async fn sqlite_commits_are_synced() {
        let dir = tempfile::tempdir().unwrap();
        let store = Store::open(&dir.path().join("t.db"), &StoreOptions::default())
            .await
            .unwrap();
        let mut tx = store.begin_write().await.unwrap();
        let level: i64 = sqlx::query_scalar("PRAGMA synchronous")
            .fetch_one(&mut *tx)
            .await
            .unwrap();
        assert_eq!(level, 2);
    }
}
