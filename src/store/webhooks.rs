//! Webhook endpoints and the outbox: one row per event (its id is the `webhook-id` of every
//! retry) and one delivery row per (event, endpoint), written in the transaction that made the
//! event. The delivery worker (`crate::webhooks`) reads the due deliveries.

use serde::{Deserialize, Serialize};
use sqlx::{FromRow, SqliteConnection, SqliteExecutor};
use utoipa::ToSchema;

use super::{display_timestamp, now, StoreError};

/// Rank of an alert level (`watch` < `warning` < `alarm`); unknown levels rank 0.
pub fn level_rank(level: &str) -> u8 {
    match level {
        "watch" => 1,
        "warning" => 2,
        "alarm" => 3,
        _ => 0,
    }
}

/// A webhook endpoint as created (`POST /api/v1/webhooks`).
#[derive(Debug, Clone, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct NewWebhook {
    /// Target URL.
    pub url: String,
    /// Signing secret `whsec_<base64>`.
    pub secret: String,
    /// Lowest level delivered (default `warning`).
    #[serde(default)]
    pub min_level: Option<String>,
}

/// A stored webhook endpoint (the secret is never returned).
#[derive(Debug, Clone, Serialize, FromRow, ToSchema)]
pub struct Webhook {
    /// Identifier (UUID).
    pub id: String,
    /// Target URL.
    pub url: String,
    /// Lowest level delivered.
    pub min_level: String,
    /// `api` or `config`.
    pub source: String,
    /// Creation time.
    pub created_at: String,
}

/// Every endpoint, newest first.
pub async fn list(db: impl SqliteExecutor<'_>) -> Result<Vec<Webhook>, StoreError> {
    let mut rows: Vec<Webhook> = sqlx::query_as(
        "SELECT id, url, min_level, source, created_at FROM webhooks ORDER BY created_at DESC, id DESC",
    )
    .fetch_all(db)
    .await?;
    for r in &mut rows {
        r.created_at = display_timestamp(&r.created_at);
    }
    Ok(rows)
}

/// Adds an endpoint; returns its id.
pub async fn insert(
    db: impl SqliteExecutor<'_>,
    hook: &NewWebhook,
    source: &str,
) -> Result<String, StoreError> {
    let id = uuid::Uuid::new_v4().to_string();
    sqlx::query(
        "INSERT INTO webhooks (id, url, secret, min_level, source, created_at) VALUES (?, ?, ?, ?, ?, ?)",
    )
    .bind(&id)
    .bind(&hook.url)
    .bind(&hook.secret)
    .bind(hook.min_level.as_deref().unwrap_or("warning"))
    .bind(source)
    .bind(now())
    .execute(db)
    .await?;
    Ok(id)
}

/// Replaces the endpoints that came from the configuration file.
pub async fn replace_configured(
    db: &mut SqliteConnection,
    hooks: &[NewWebhook],
) -> Result<(), StoreError> {
    let existing: Vec<(String, String, String, String)> =
        sqlx::query_as("SELECT id, url, secret, min_level FROM webhooks WHERE source = 'config'")
            .fetch_all(&mut *db)
            .await?;
    for (id, url, secret, min) in &existing {
        let keep = hooks.iter().any(|h| {
            &h.url == url
                && &h.secret == secret
                && h.min_level.as_deref().unwrap_or("warning") == min
        });
        if !keep {
            delete(&mut *db, id).await?;
        }
    }
    for h in hooks {
        let present = existing.iter().any(|(_, url, secret, min)| {
            &h.url == url
                && &h.secret == secret
                && h.min_level.as_deref().unwrap_or("warning") == min
        });
        if !present {
            insert(&mut *db, h, "config").await?;
        }
    }
    Ok(())
}

/// Deletes an endpoint (its pending deliveries are dropped); `Ok(false)` when unknown.
pub async fn delete(db: &mut SqliteConnection, id: &str) -> Result<bool, StoreError> {
    sqlx::query("DELETE FROM webhook_deliveries WHERE webhook_id = ? AND state = 'pending'")
        .bind(id)
        .execute(&mut *db)
        .await?;
    let done = sqlx::query("DELETE FROM webhooks WHERE id = ?")
        .bind(id)
        .execute(&mut *db)
        .await?;
    Ok(done.rows_affected() == 1)
}

/// An event to deliver.
#[derive(Debug, Clone)]
pub struct NewEvent {
    /// Event id (the `webhook-id`).
    pub id: String,
    /// `alert.raised`, `alert.acknowledged`, …
    pub event_type: String,
    /// The alert it concerns.
    pub alert_id: Option<String>,
    /// Alert level (endpoints with a higher `min_level` do not get it).
    pub level: Option<String>,
    /// The JSON body to send.
    pub payload: serde_json::Value,
}

/// Writes events to the outbox with one pending delivery per endpoint whose `min_level` they
/// reach. Call inside the transaction that made the events.
pub async fn enqueue(db: &mut SqliteConnection, events: &[NewEvent]) -> Result<(), StoreError> {
    if events.is_empty() {
        return Ok(());
    }
    let hooks: Vec<(String, String)> = sqlx::query_as("SELECT id, min_level FROM webhooks")
        .fetch_all(&mut *db)
        .await?;
    let t = now();
    for e in events {
        sqlx::query(
            "INSERT INTO webhook_outbox (id, event_type, alert_id, level, payload, created_at) VALUES (?, ?, ?, ?, ?, ?)",
        )
        .bind(&e.id)
        .bind(&e.event_type)
        .bind(&e.alert_id)
        .bind(&e.level)
        .bind(e.payload.to_string())
        .bind(&t)
        .execute(&mut *db)
        .await?;
        let rank = e.level.as_deref().map(level_rank).unwrap_or(u8::MAX);
        for (hook, min) in &hooks {
            if rank >= level_rank(min) {
                sqlx::query(
                    "INSERT INTO webhook_deliveries (outbox_id, webhook_id, state, next_attempt_at) VALUES (?, ?, 'pending', ?)",
                )
                .bind(&e.id)
                .bind(hook)
                .bind(&t)
                .execute(&mut *db)
                .await?;
            }
        }
    }
    Ok(())
}

/// Number of pending deliveries (the `/metrics` queue depth).
pub async fn pending(db: impl SqliteExecutor<'_>) -> Result<i64, StoreError> {
    Ok(
        sqlx::query_scalar("SELECT COUNT(*) FROM webhook_deliveries WHERE state = 'pending'")
            .fetch_one(db)
            .await?,
    )
}
