//! SQLite's WAL checkpoints, outside the request path.
//!
//! By default the connection whose commit takes the WAL past 1000 pages copies the WAL back into
//! the database file and syncs it, inside that commit: every ~15th upload took 30–100 ms instead
//! of 20. Here the writer does so only past [`WRITER_AUTOCHECKPOINT_PAGES`] (a safety net), and
//! the daemon calls [`Store::checkpoint_wal`] every [`CHECKPOINT_INTERVAL`] from a connection of
//! its own. A `PASSIVE` checkpoint takes no lock that writers or readers wait for; what it cannot
//! copy yet (pages a reader still needs) it copies next time. Durability is unchanged: with
//! `synchronous = FULL` every commit syncs the WAL before it returns, and the WAL is synced
//! before its pages are copied either way.

use std::time::Duration;

pub use super::pool::WRITER_AUTOCHECKPOINT_PAGES;
use super::{Store, StoreError};

/// How often the daemon checkpoints the WAL.
pub const CHECKPOINT_INTERVAL: Duration = Duration::from_secs(1);

/// What one checkpoint did (SQLite's `PRAGMA wal_checkpoint` answer).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Checkpoint {
    /// Pages in the WAL (frames).
    pub wal_pages: i64,
    /// Of them, copied into the database file.
    pub copied_pages: i64,
}

impl Store {
    /// SQLite: copies what it can of the WAL into the database file without waiting for any
    /// lock (`PRAGMA wal_checkpoint(PASSIVE)`). PostgreSQL: nothing, `None`.
    pub async fn checkpoint_wal(&self) -> Result<Option<Checkpoint>, StoreError> {
        let Some(pool) = &self.checkpointer else {
            return Ok(None);
        };
        let (_busy, wal_pages, copied_pages): (i64, i64, i64) =
            sqlx::query_as("PRAGMA wal_checkpoint(PASSIVE)")
                .fetch_one(pool)
                .await?;
        Ok(Some(Checkpoint {
            wal_pages,
            copied_pages,
        }))
    }
}
