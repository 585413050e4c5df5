//! Backups of a SQLite database: of the live store ([`Store::backup`]) and of a database file
//! ([`backup_file`]). PostgreSQL's are `pg_dump`'s.

use std::path::Path;
use std::str::FromStr;
use std::time::Duration;

use sqlx::sqlite::SqliteConnectOptions;

use super::error::StoreError;
use super::pool::{Backend, Store};

impl Store {
    /// SQLite: writes a consistent copy of the live database to `target` (`VACUUM INTO`), while
    /// it serves. PostgreSQL: refused; use `pg_dump` (see the README).
    pub async fn backup(&self, target: &Path) -> Result<(), StoreError> {
        if self.backend() == Backend::Postgres {
            return Err(StoreError::Url(
                "backup of PostgreSQL: use pg_dump (README, 'Backups')".into(),
            ));
        }
        let target = target.to_string_lossy().to_string();
        sqlx::query("VACUUM INTO $1")
            .bind(target)
            .execute(self.reader())
            .await?;
        Ok(())
    }
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
