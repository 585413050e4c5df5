//! The handle on the database: opening either backend (connection set-up, migrations), the read
//! and write pools, write transactions and their locks, cluster-wide job locks, the store's
//! clock, closing.

use std::path::Path;
use std::str::FromStr;
use std::time::Duration;

use chrono::{DateTime, Utc};
use sqlx::any::{AnyConnectOptions, AnyPoolOptions};
use sqlx::pool::PoolConnection;
use sqlx::postgres::{PgConnectOptions, PgPoolOptions};
use sqlx::sqlite::{SqliteConnectOptions, SqliteJournalMode, SqlitePoolOptions, SqliteSynchronous};
use sqlx::{
    Any, AnyConnection, AnyPool, ConnectOptions, Executor, PgPool, SqlitePool, Transaction,
};

use super::error::StoreError;
use super::time::clock;

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
    pub(super) backend: Backend,
    pub(super) read: AnyPool,
    pub(super) write: AnyPool,
    /// SQLite only: read-only native connections for [`series`] ([`sqlite_raw`]).
    pub(super) sqlite_read: Option<SqlitePool>,
    /// PostgreSQL only: native connections for the upload's history read.
    pub(super) postgres_read: Option<PgPool>,
    /// SQLite only: the connection that checkpoints the WAL ([`wal_checkpoint`]).
    pub(super) checkpointer: Option<SqlitePool>,
}

/// WAL pages (4 KiB each) past which a committing writer checkpoints itself: far above what the
/// daemon's checkpoints ([`super::wal_checkpoint`]) let the WAL reach, so it only acts when they do not run (commands
/// outside the daemon, a stalled checkpointer).
pub const WRITER_AUTOCHECKPOINT_PAGES: u32 = 10_000;

/// The settings of every SQLite connection: foreign keys, `synchronous = FULL` (with WAL: each
/// commit syncs the WAL before it returns, so an epoch answered 201, or a watched folder moved to
/// `.done/`, survives a power loss; `NORMAL` would lose the last commits),
/// the busy timeout, and the WAL size at which a committing writer checkpoints itself
/// ([`WRITER_AUTOCHECKPOINT_PAGES`]).
fn sqlite_pragmas(
    conn: &mut AnyConnection,
    busy_ms: u128,
) -> futures_core::future::BoxFuture<'_, Result<(), sqlx::Error>> {
    Box::pin(async move {
        let pages = WRITER_AUTOCHECKPOINT_PAGES;
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
    /// The SQLite file's pools (the file created when missing), its migrations applied.
    pub(super) async fn open_sqlite_pools(
        path: &Path,
        options: &StoreOptions,
    ) -> Result<Store, StoreError> {
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
        Ok(Store {
            backend: Backend::Sqlite,
            read,
            write,
            sqlite_read: Some(sqlite_read),
            postgres_read: None,
            checkpointer: Some(checkpointer),
        })
    }

    /// The PostgreSQL database's pools, its migrations applied. Writes go through a pool of
    /// [`StoreOptions::write_connections`]; the advisory locks of [`Store::begin_write_site`]
    /// decide which of them may run side by side.
    pub(super) async fn open_postgres_pools(
        url: &str,
        options: &StoreOptions,
    ) -> Result<Store, StoreError> {
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
        Ok(Store {
            backend: Backend::Postgres,
            read,
            write,
            sqlite_read: None,
            postgres_read: Some(postgres_read),
            checkpointer: None,
        })
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
