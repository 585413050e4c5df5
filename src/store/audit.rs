//! The audit trail: one row per change of a site's settings (who, when, from where, what
//! before and after), newest first.

use serde::Serialize;
use sqlx::{AnyExecutor, FromRow};
use utoipa::ToSchema;

use super::StoreError;

/// One change.
#[derive(Debug, Clone, PartialEq, Serialize, FromRow, ToSchema)]
pub struct AuditEntry {
    /// Its id (its time and a random suffix).
    pub id: String,
    /// The site changed.
    #[serde(skip)]
    pub site_id: String,
    /// When (RFC 3339, the store's clock).
    pub at: String,
    /// Who: `token <first 16 hex digits of its SHA-256> (<role>)`, or `anonymous` when the
    /// service runs without tokens, or `configuration file`.
    pub actor: String,
    /// From where: `api`, `page` or `configuration`.
    pub source: String,
    /// What: `site.update`, `group.put`, `group.delete`, `reference.set`.
    pub action: String,
    /// What it was done to: the site, `group B1`, …
    pub target: String,
    /// The setting before (JSON text; null when it did not exist).
    pub value_before: Option<String>,
    /// The setting after (JSON text; null when it was removed).
    pub value_after: Option<String>,
}

/// Stores `e` (its id and time given by the caller).
pub async fn insert(db: impl AnyExecutor<'_>, e: &AuditEntry) -> Result<(), StoreError> {
    sqlx::query(
        "INSERT INTO audit (id, site_id, at, actor, source, action, target, value_before, \
         value_after) VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9)",
    )
    .bind(&e.id)
    .bind(&e.site_id)
    .bind(&e.at)
    .bind(&e.actor)
    .bind(&e.source)
    .bind(&e.action)
    .bind(&e.target)
    .bind(e.value_before.as_deref())
    .bind(e.value_after.as_deref())
    .execute(db)
    .await?;
    Ok(())
}

/// The changes of `site`, newest first, after the cursor `after` (`(at, id)` of the previous
/// page's last row), at most `limit`.
pub async fn list(
    db: impl AnyExecutor<'_>,
    site: &str,
    after: Option<(&str, &str)>,
    limit: i64,
) -> Result<Vec<AuditEntry>, StoreError> {
    let (at, id) = after.unwrap_or(("~", "~"));
    Ok(sqlx::query_as(
        "SELECT id, site_id, at, actor, source, action, target, value_before, value_after \
         FROM audit WHERE site_id = $1 AND (at < $2 OR (at = $2 AND id < $3)) \
         ORDER BY at DESC, id DESC LIMIT $4",
    )
    .bind(site)
    .bind(at)
    .bind(id)
    .bind(limit)
    .fetch_all(db)
    .await?)
}

/// The changes of `site` made between the stored times `from` and `to` (inclusive; `None`: no
/// bound), oldest first, at most `limit`.
pub async fn between(
    db: impl AnyExecutor<'_>,
    site: &str,
    from: Option<&str>,
    to: Option<&str>,
    limit: i64,
) -> Result<Vec<AuditEntry>, StoreError> {
    Ok(sqlx::query_as(
        "SELECT id, site_id, at, actor, source, action, target, value_before, value_after \
         FROM audit WHERE site_id = $1 AND at >= $2 AND at <= $3 ORDER BY at, id LIMIT $4",
    )
    .bind(site)
    .bind(from.unwrap_or(""))
    .bind(to.map_or_else(|| super::TEXT_MAX.to_string(), |t| format!("{t}~")))
    .bind(limit)
    .fetch_all(db)
    .await?)
}
