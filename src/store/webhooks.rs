//! Webhook endpoints: registered through the API or the configuration file, with their level
//! filter and body format; disabled after a 410 Gone. The messages and deliveries are in
//! [`super::outbox`].

use serde::{Deserialize, Serialize};
use sqlx::{AnyConnection, AnyExecutor, FromRow};
use utoipa::openapi::schema::{Object, ObjectBuilder, Type};
use utoipa::ToSchema;

use super::{display_timestamp, now, StoreError};
use crate::webhooks::PayloadFormat;
use cliffwatch_core::analysis::AlertLevel;

/// OpenAPI schema of a `format` field: a string, one of [`PayloadFormat`]'s names.
fn format_schema() -> Object {
    ObjectBuilder::new()
        .schema_type(Type::String)
        .enum_values(Some(PayloadFormat::ALL.iter().map(|f| f.as_str())))
        .default(Some(PayloadFormat::Standard.as_str().into()))
        .description(Some(
            "Body format: `standard` (the contract body), `alertmanager_webhook` (Alertmanager's \
             webhook body, version 4) or `alertmanager_api_v2` (the body of Alertmanager's \
             `POST /api/v2/alerts`, a JSON array of alerts). Every format is signed the same way.",
        ))
        .build()
}

/// Where an endpoint was registered: `api` (`POST /api/v1/webhooks`) or `config` (`[[webhooks]]`
/// of the configuration file, replaced at each start).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum WebhookSource {
    /// Registered through the API.
    Api,
    /// From the configuration file.
    Config,
}

cliffwatch_core::contract_names!(WebhookSource, "webhook source" {
    Api => "api",
    Config => "config",
});

/// A webhook endpoint as created (`POST /api/v1/webhooks`).
/// No `Debug`: it holds the signing secret, which must never reach a log.
#[derive(Clone, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct NewWebhook {
    /// Target URL: absolute, http or https, with a host, at most 2048 characters
    /// (`service::webhooks::MAX_URL_CHARS`).
    #[schema(pattern = "^https?://", max_length = 2048)]
    pub url: String,
    /// Signing secret `whsec_<base64>` (standard alphabet, padded or not, canonical) of a key
    /// of at least 3 bytes: the key that signs every delivery; at most 256 characters
    /// (`service::webhooks::MAX_SECRET_CHARS`).
    #[schema(
        max_length = 256,
        pattern = "^whsec_(?:[A-Za-z0-9+/]{4})+(?:[A-Za-z0-9+/][AQgw](?:==)?|[A-Za-z0-9+/]{2}[AEIMQUYcgkosw048]=?)?$"
    )]
    pub secret: String,
    /// Lowest level delivered (default `warning`).
    #[serde(default)]
    pub min_level: Option<AlertLevel>,
    /// Body format (default `standard`).
    #[serde(default)]
    #[schema(schema_with = format_schema)]
    pub format: PayloadFormat,
}

/// A stored webhook endpoint (the secret is never returned), with the state of its deliveries.
#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct Webhook {
    /// Identifier (UUID).
    pub id: String,
    /// Target URL.
    pub url: String,
    /// Lowest level delivered.
    pub min_level: AlertLevel,
    /// Body format.
    #[schema(schema_with = format_schema)]
    pub format: PayloadFormat,
    /// Where it was registered.
    pub source: WebhookSource,
    /// Creation time.
    pub created_at: String,
    /// False once the endpoint answered 410 Gone: nothing more is sent to it (delete it and add
    /// it again to resume).
    pub enabled: bool,
    /// Messages waiting for delivery or being retried.
    pub pending_deliveries: i64,
    /// Messages given up: retried to the policy's last attempt, or pending when the endpoint
    /// answered 410 Gone. Each was logged as an error. Counted until the deliveries' retention
    /// (`webhook_delivery_retention_days`, 90 by default) deletes them.
    pub failed_deliveries: i64,
    /// The latest reason a message was not delivered, while any is pending or failed.
    pub last_error: Option<String>,
}

#[derive(FromRow)]
struct WebhookRow {
    id: String,
    url: String,
    #[sqlx(try_from = "String")]
    min_level: AlertLevel,
    #[sqlx(try_from = "String")]
    format: PayloadFormat,
    #[sqlx(try_from = "String")]
    source: WebhookSource,
    created_at: String,
    enabled: i64,
    pending_deliveries: i64,
    failed_deliveries: i64,
    last_error: Option<String>,
}

/// Every endpoint, newest first, with the counts of its pending and failed deliveries.
pub async fn list(db: impl AnyExecutor<'_>) -> Result<Vec<Webhook>, StoreError> {
    let rows: Vec<WebhookRow> = sqlx::query_as(
        "SELECT w.id, w.url, w.min_level, w.format, w.source, w.created_at, \
         CAST(CASE WHEN w.enabled = TRUE THEN 1 ELSE 0 END AS BIGINT) AS enabled, \
         (SELECT COUNT(*) FROM webhook_deliveries d WHERE d.webhook_id = w.id AND d.state = 'pending') \
           AS pending_deliveries, \
         (SELECT COUNT(*) FROM webhook_deliveries d WHERE d.webhook_id = w.id AND d.state = 'failed') \
           AS failed_deliveries, \
         (SELECT d.last_error FROM webhook_deliveries d WHERE d.webhook_id = w.id \
           AND d.state <> 'delivered' AND d.last_error IS NOT NULL \
           ORDER BY d.next_attempt_at DESC LIMIT 1) AS last_error \
         FROM webhooks w ORDER BY w.created_at DESC, w.id DESC",
    )
    .fetch_all(db)
    .await?;
    Ok(rows
        .into_iter()
        .map(|r| Webhook {
            id: r.id,
            url: r.url,
            min_level: r.min_level,
            format: r.format,
            source: r.source,
            created_at: display_timestamp(&r.created_at),
            enabled: r.enabled != 0,
            pending_deliveries: r.pending_deliveries,
            failed_deliveries: r.failed_deliveries,
            last_error: r.last_error,
        })
        .collect())
}

/// Adds an endpoint; returns its id.
pub async fn insert(
    db: &mut AnyConnection,
    hook: &NewWebhook,
    source: WebhookSource,
) -> Result<String, StoreError> {
    let id = uuid::Uuid::new_v4().to_string();
    let at = now(&mut *db).await?;
    sqlx::query(
        "INSERT INTO webhooks (id, url, secret, min_level, format, source, created_at) \
         VALUES ($1, $2, $3, $4, $5, $6, $7)",
    )
    .bind(&id)
    .bind(&hook.url)
    .bind(&hook.secret)
    .bind(hook.min_level.unwrap_or(AlertLevel::Warning).as_str())
    .bind(hook.format.as_str())
    .bind(source.as_str())
    .bind(&at)
    .execute(db)
    .await?;
    Ok(id)
}

/// Replaces the endpoints that came from the configuration file. A stored one whose URL is still
/// configured stays, with its id and its pending deliveries, and takes the configured secret,
/// level and format (a rotated secret signs the next attempts; the deliveries' bodies stay the
/// bytes they were made with); one whose URL is no longer configured is deleted with its pending
/// deliveries; a new URL is inserted. Several endpoints of one URL pair up in order.
pub async fn replace_configured(
    db: &mut AnyConnection,
    hooks: &[NewWebhook],
) -> Result<(), StoreError> {
    let existing: Vec<(String, String)> = sqlx::query_as(
        "SELECT id, url FROM webhooks WHERE source = 'config' ORDER BY created_at, id",
    )
    .fetch_all(&mut *db)
    .await?;
    let mut kept = vec![false; existing.len()];
    for h in hooks {
        let same_url = (0..existing.len()).find(|&i| !kept[i] && existing[i].1 == h.url);
        match same_url {
            Some(i) => {
                kept[i] = true;
                sqlx::query(
                    "UPDATE webhooks SET secret = $1, min_level = $2, format = $3 WHERE id = $4",
                )
                .bind(&h.secret)
                .bind(h.min_level.unwrap_or(AlertLevel::Warning).as_str())
                .bind(h.format.as_str())
                .bind(&existing[i].0)
                .execute(&mut *db)
                .await?;
            }
            None => {
                insert(&mut *db, h, WebhookSource::Config).await?;
            }
        }
    }
    for (i, (id, url)) in existing.iter().enumerate() {
        if !kept[i] {
            let pending = delete(&mut *db, id).await?.unwrap_or(0);
            if pending > 0 {
                tracing::warn!(webhook = %id, url = %crate::webhooks::loggable_origin(url), pending,
                    "webhook no longer configured: its undelivered messages were dropped");
            }
        }
    }
    Ok(())
}

/// Deletes an endpoint and drops its pending deliveries: how many were dropped, `None` when the
/// endpoint is unknown.
pub async fn delete(db: &mut AnyConnection, id: &str) -> Result<Option<u64>, StoreError> {
    let dropped =
        sqlx::query("DELETE FROM webhook_deliveries WHERE webhook_id = $1 AND state = 'pending'")
            .bind(id)
            .execute(&mut *db)
            .await?;
    let done = sqlx::query("DELETE FROM webhooks WHERE id = $1")
        .bind(id)
        .execute(&mut *db)
        .await?;
    Ok((done.rows_affected() == 1).then_some(dropped.rows_affected()))
}

/// Number of pending deliveries (the `/metrics` queue depth).
pub async fn pending(db: impl AnyExecutor<'_>) -> Result<i64, StoreError> {
    Ok(
        sqlx::query_scalar("SELECT COUNT(*) FROM webhook_deliveries WHERE state = 'pending'")
            .fetch_one(db)
            .await?,
    )
}

/// The enabled endpoints with their level filter and body format, as the alert events need
/// them (a format this version does not know, impossible under the schema's CHECK, falls back
/// to the contract body with a warning).
pub async fn enabled_endpoints(
    db: &mut AnyConnection,
) -> Result<Vec<crate::webhooks::WebhookEndpoint>, StoreError> {
    let rows: Vec<(String, String, String, String, String)> = sqlx::query_as(
        "SELECT id, url, secret, min_level, format FROM webhooks WHERE enabled = TRUE",
    )
    .fetch_all(&mut *db)
    .await?;
    Ok(rows
        .into_iter()
        .map(|(id, url, secret, min, format)| {
            let format = format.parse().unwrap_or_else(|_| {
                tracing::warn!(webhook = %id, format = %format, "unknown body format: contract body");
                PayloadFormat::Standard
            });
            crate::webhooks::WebhookEndpoint {
                id,
                url,
                secret,
                min_level: min.parse().ok(),
                format,
                enabled: true,
            }
        })
        .collect())
}

/// One endpoint with its secret, as a delivery needs it (disabled ones too); `None` when
/// unknown.
pub async fn endpoint(
    db: impl AnyExecutor<'_>,
    id: &str,
) -> Result<Option<crate::webhooks::WebhookEndpoint>, StoreError> {
    let row: Option<(String, String, String, String, String, i64)> = sqlx::query_as(
        "SELECT id, url, secret, min_level, format, \
         CAST(CASE WHEN enabled = TRUE THEN 1 ELSE 0 END AS BIGINT) FROM webhooks WHERE id = $1",
    )
    .bind(id)
    .fetch_optional(db)
    .await?;
    Ok(row.map(
        |(id, url, secret, min, format, enabled)| crate::webhooks::WebhookEndpoint {
            id,
            url,
            secret,
            min_level: min.parse().ok(),
            format: format.parse().unwrap_or_default(),
            enabled: enabled != 0,
        },
    ))
}
