//! The alerts Alertmanager is to hold now (the re-post loop, `workers::alertmanager_resend`):
//! every open or acknowledged alert, and those resolved recently enough that Alertmanager may
//! still hold them firing.

use sqlx::AnyExecutor;

use super::alerts::{finish, Alert, COLUMNS};
use super::StoreError;

/// Every alert not resolved, and every alert resolved (its latest change) at or after
/// `resolved_since` (store format), oldest raised first.
pub async fn held(
    db: impl AnyExecutor<'_>,
    resolved_since: &str,
) -> Result<Vec<Alert>, StoreError> {
    let rows: Vec<Alert> = sqlx::query_as(&format!(
        "SELECT {COLUMNS} FROM alerts WHERE state <> 'resolved' OR updated_at >= $1 \
         ORDER BY raised_at, id"
    ))
    .bind(resolved_since)
    .fetch_all(db)
    .await?;
    Ok(finish(rows))
}

/// What changes whenever an alert or an Alertmanager endpoint does: the latest change of any
/// alert (`alerts_by_update`) and the number of enabled `alertmanager_api_v2` endpoints. The
/// re-post loop posts at once when it differs from the last pass's.
pub async fn last_change(db: impl AnyExecutor<'_>) -> Result<(Option<String>, i64), StoreError> {
    Ok(sqlx::query_as(
        "SELECT (SELECT MAX(updated_at) FROM alerts), \
         (SELECT COUNT(*) FROM webhooks WHERE enabled = TRUE AND format = 'alertmanager_api_v2')",
    )
    .fetch_one(db)
    .await?)
}
