//! Dashboard sessions ([`crate::http::session`]): one row per sign-in, keyed by the SHA-256 of the
//! cookie's random id (the id itself is never stored), with the name and role of the token signed
//! in with, when it was created and when it was last used. A session that ends is deleted.
//!
//! Not copied by `migrate-store` ([`super::copy`]): a session is a sign-in on one installation,
//! and staff sign in again after the move.

use chrono::{DateTime, Utc};
use sqlx::{AnyConnection, AnyExecutor};

use super::{parse_timestamp, timestamp, StoreError};

/// A stored session.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct StoredSession {
    /// The name of the token signed in with (not the token).
    pub token_name: String,
    /// That token's role at sign-in (`read`, `upload`, `admin`).
    pub role: String,
    /// When it was signed in.
    pub created_at: DateTime<Utc>,
    /// When it was last used (updated at most every so often, see [`touch`]).
    pub last_seen_at: DateTime<Utc>,
}

fn parsed(column: &str, s: &str) -> Result<DateTime<Utc>, StoreError> {
    parse_timestamp(s)
        .ok_or_else(|| StoreError::Corrupt(format!("sessions.{column} is not a time: {s:.40}")))
}

/// Stores a new session `id_hash` signed in at `at` with the token `token_name` of `role`.
pub async fn insert(
    db: &mut AnyConnection,
    id_hash: &str,
    token_name: &str,
    role: &str,
    at: DateTime<Utc>,
) -> Result<(), StoreError> {
    let at = timestamp(at);
    sqlx::query(
        "INSERT INTO sessions (id_hash, token_name, role, created_at, last_seen_at) \
         VALUES ($1, $2, $3, $4, $4)",
    )
    .bind(id_hash)
    .bind(token_name)
    .bind(role)
    .bind(&at)
    .execute(db)
    .await?;
    Ok(())
}

/// The session stored under `id_hash`, if any.
pub async fn find(
    db: impl AnyExecutor<'_>,
    id_hash: &str,
) -> Result<Option<StoredSession>, StoreError> {
    let row: Option<(String, String, String, String)> = sqlx::query_as(
        "SELECT token_name, role, created_at, last_seen_at FROM sessions WHERE id_hash = $1",
    )
    .bind(id_hash)
    .fetch_optional(db)
    .await?;
    row.map(|(token_name, role, created, seen)| {
        Ok(StoredSession {
            token_name,
            role,
            created_at: parsed("created_at", &created)?,
            last_seen_at: parsed("last_seen_at", &seen)?,
        })
    })
    .transpose()
}

/// Records that session `id_hash` was used at `at` (never moving its time back).
pub async fn touch(
    db: &mut AnyConnection,
    id_hash: &str,
    at: DateTime<Utc>,
) -> Result<(), StoreError> {
    sqlx::query("UPDATE sessions SET last_seen_at = $2 WHERE id_hash = $1 AND last_seen_at < $2")
        .bind(id_hash)
        .bind(timestamp(at))
        .execute(db)
        .await?;
    Ok(())
}

/// Ends session `id_hash` (signing out): deletes it; whether there was one.
pub async fn delete(db: &mut AnyConnection, id_hash: &str) -> Result<bool, StoreError> {
    let done = sqlx::query("DELETE FROM sessions WHERE id_hash = $1")
        .bind(id_hash)
        .execute(db)
        .await?;
    Ok(done.rows_affected() > 0)
}

/// Deletes the sessions ended by time: last used before `idle_before` or created before
/// `created_before`; how many.
pub async fn delete_expired(
    db: &mut AnyConnection,
    idle_before: DateTime<Utc>,
    created_before: DateTime<Utc>,
) -> Result<u64, StoreError> {
    let done = sqlx::query("DELETE FROM sessions WHERE last_seen_at < $1 OR created_at < $2")
        .bind(timestamp(idle_before))
        .bind(timestamp(created_before))
        .execute(db)
        .await?;
    Ok(done.rows_affected())
}

/// Every stored session's `id_hash` (tests and audits: what the table holds).
pub async fn id_hashes(db: impl AnyExecutor<'_>) -> Result<Vec<String>, StoreError> {
    Ok(
        sqlx::query_scalar("SELECT id_hash FROM sessions ORDER BY id_hash")
            .fetch_all(db)
            .await?,
    )
}
