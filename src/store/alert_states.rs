//! The alert engine's state of each site ([`AlertState`]: open alerts, rule memory), one JSON
//! document per site, read and written inside the transaction that changes it.

use chrono::{DateTime, Utc};
use sqlx::AnyConnection;

use super::{timestamp, StoreError};
use cliffwatch_core::analysis::AlertState;

/// The stored state of `site` (empty when none is stored yet).
pub async fn load(db: &mut AnyConnection, site: &str) -> Result<AlertState, StoreError> {
    let s: Option<String> = sqlx::query_scalar("SELECT state FROM alert_states WHERE site_id = $1")
        .bind(site)
        .fetch_optional(&mut *db)
        .await?;
    Ok(match s {
        Some(s) => serde_json::from_str(&s)?,
        None => AlertState::default(),
    })
}

/// Stores the state of `site` as of `at` (the transaction's time on the store's clock).
pub async fn save(
    db: &mut AnyConnection,
    site: &str,
    state: &AlertState,
    at: DateTime<Utc>,
) -> Result<(), StoreError> {
    let json = serde_json::to_string(state)?;
    let t = timestamp(at);
    sqlx::query(
        "INSERT INTO alert_states (site_id, state, updated_at) VALUES ($1, $2, $3) \
         ON CONFLICT (site_id) DO UPDATE SET state = excluded.state, updated_at = excluded.updated_at",
    )
    .bind(site)
    .bind(&json)
    .bind(&t)
    .execute(&mut *db)
    .await?;
    Ok(())
}
