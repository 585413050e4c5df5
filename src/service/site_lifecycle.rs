//! The end of a site's life: retired (no more uploads, its pages kept, every open alert closed
//! with the reason), its data exported as one JSON document, then deleted. Each step is one
//! transaction with its audit row. A site is deleted only once it is retired and its data was
//! exported after the retirement; the deletion keeps the site's audit trail (no foreign key
//! ties it to the site) and adds its own row to it, and logs it.

use serde::Serialize;
use serde_json::{json, Value};
use utoipa::ToSchema;

use crate::store::alerts::Alert;
use crate::store::audit::AuditEntry;
use crate::store::epochs::EpochListItem;
use crate::store::points::Point;
use crate::store::sites::{self, Site};
use crate::store::{
    self, alert_states, alerts, audit, epochs, groups, points, site_removal, Connection, Store,
    StoreError,
};
use cliffwatch_core::analysis::{self, GroupConfig};

use super::alert_outcome::save_and_record;
use super::site_admin::{as_new_site, record, Actor};
use super::sites::ensure_in_service;
use super::ServiceError;

/// Longest reason of a retirement (characters, after trimming).
pub const MAX_REASON_CHARS: usize = 2000;

/// Retires `site` for `reason` (trimmed, 1 to [`MAX_REASON_CHARS`] characters): from now on
/// its uploads are refused, its pages stay and say since when and why; every open or
/// acknowledged alert is resolved, its resolution event naming the retirement. One transaction
/// with its audit row (`site.retire`); the events' bodies link under `public_url` (the
/// configuration's). Returns the site after.
pub async fn retire_site(
    store: &Store,
    site: &str,
    reason: &str,
    actor: &Actor,
    public_url: Option<&str>,
) -> Result<Site, ServiceError> {
    let reason = reason.trim();
    if reason.is_empty() || reason.chars().count() > MAX_REASON_CHARS || reason.contains('\0') {
        return Err(ServiceError::InvalidSite(format!(
            "reason: why the site is retired, 1 to {MAX_REASON_CHARS} characters (no NUL)"
        )));
    }
    let mut tx = store.begin_write_site(site).await?;
    let before = sites::get(&mut *tx, site)
        .await?
        .ok_or_else(|| ServiceError::UnknownSite(site.to_string()))?;
    ensure_in_service(&before)?;
    let now = store::clock(&mut tx).await?;
    let at = store::timestamp(now);
    sites::retire(&mut *tx, site, &at, reason).await?;
    let closed = close_alerts(&mut tx, site, reason, actor, now, public_url).await?;
    record(
        &mut tx,
        site,
        actor,
        "site.retire",
        &format!("site {site}"),
        Some(&json!({"retired": false})),
        Some(&json!({"retired": true, "reason": reason, "alerts_closed": closed})),
    )
    .await?;
    let after = sites::get(&mut *tx, site)
        .await?
        .ok_or_else(|| ServiceError::UnknownSite(site.to_string()))?;
    tx.commit().await.map_err(StoreError::from)?;
    tracing::info!(site, reason, alerts_closed = closed, "site retired");
    Ok(after)
}

/// Resolves every active alert of `site` at `now`, each event's message ending with the
/// retirement's reason (the bodies link under `public_url`); returns how many.
async fn close_alerts(
    tx: &mut Connection,
    site: &str,
    reason: &str,
    actor: &Actor,
    now: chrono::DateTime<chrono::Utc>,
    public_url: Option<&str>,
) -> Result<usize, ServiceError> {
    let mut state = alert_states::load(&mut *tx, site).await?;
    let ids: Vec<String> = state.alerts.iter().map(|a| a.id.clone()).collect();
    let mut events = Vec::with_capacity(ids.len());
    for id in &ids {
        let (next, mut event) = analysis::resolve(&state, id, &actor.who, now)
            .map_err(|e| ServiceError::Task(e.to_string()))?;
        event.alert.message = format!(
            "{} — resolved: the site was retired by {}: {reason}",
            event.alert.message, actor.who
        );
        state = next;
        events.push(event);
    }
    if !events.is_empty() {
        save_and_record(tx, site, &state, &events, now, public_url).await?;
    }
    Ok(events.len())
}

/// A site's data as `GET /api/v1/sites/{site}/export` gives it: what it was set up as, what it
/// measured and raised, and every change made to it. A record to keep, not a backup to restore
/// (`cliffwatch backup` copies the whole database).
#[derive(Debug, Serialize, ToSchema)]
pub struct SiteExport {
    /// `cliffwatch site export 1`.
    pub format: String,
    /// When the export was made (RFC 3339, the store's clock).
    pub exported_at: String,
    /// The site as stored (with its retirement).
    pub site: Site,
    /// Its settings in the form of `POST /api/v1/sites` (every default written out).
    #[schema(value_type = Object)]
    pub settings: Value,
    /// Its epochs, oldest first.
    pub epochs: Vec<EpochListItem>,
    /// Its points with their roles.
    pub points: Vec<Point>,
    /// Its block groups.
    #[schema(value_type = Vec<Object>)]
    pub groups: Vec<GroupConfig>,
    /// Its alerts (every state), oldest first.
    pub alerts: Vec<Alert>,
    /// Its audit trail, oldest first (the export itself included).
    pub audit: Vec<AuditEntry>,
}

/// Reads every row of `site` into a [`SiteExport`] and records the export (audit row
/// `site.export`, and the site's `exported_at` that a deletion requires), in one transaction.
pub async fn export_site(
    store: &Store,
    site: &str,
    actor: &Actor,
) -> Result<SiteExport, ServiceError> {
    let mut tx = store.begin_write_site(site).await?;
    if sites::get(&mut *tx, site).await?.is_none() {
        return Err(ServiceError::UnknownSite(site.to_string()));
    }
    let now = store::clock(&mut tx).await?;
    let at = store::timestamp(now);
    sites::mark_exported(&mut *tx, site, &at).await?;
    let mut epoch_rows: Vec<EpochListItem> = epochs::list(&mut *tx, site, None, i64::MAX)
        .await?
        .into_iter()
        .map(|(_, e)| e)
        .collect();
    epoch_rows.reverse();
    let point_rows = points::list(&mut *tx, site, None, i64::MAX).await?;
    let group_rows = groups::list(&mut *tx, site).await?;
    let mut alert_rows: Vec<Alert> = alerts::list(&mut *tx, Some(site), None, None, i64::MAX)
        .await?
        .into_iter()
        .map(|(_, a)| a)
        .collect();
    alert_rows.reverse();
    let counts = json!({
        "epochs": epoch_rows.len(), "points": point_rows.len(),
        "groups": group_rows.len(), "alerts": alert_rows.len(),
    });
    record(
        &mut tx,
        site,
        actor,
        "site.export",
        &format!("site {site}"),
        None,
        Some(&counts),
    )
    .await?;
    let mut trail = audit::list(&mut *tx, site, None, i64::MAX).await?;
    trail.reverse();
    let stored = sites::get(&mut *tx, site)
        .await?
        .ok_or_else(|| ServiceError::UnknownSite(site.to_string()))?;
    tx.commit().await.map_err(StoreError::from)?;
    Ok(SiteExport {
        format: "cliffwatch site export 1".into(),
        exported_at: stored.exported_at.clone().unwrap_or_default(),
        settings: serde_json::to_value(as_new_site(&stored)).map_err(StoreError::from)?,
        site: stored,
        epochs: epoch_rows,
        points: point_rows,
        groups: group_rows,
        alerts: alert_rows,
        audit: trail,
    })
}

/// Deletes `site` and every row of it but its audit trail, in one transaction that also writes
/// the audit row `site.delete` (which outlives the site, with how many rows each table lost).
/// Refused ([`ServiceError::NotDeletable`]) unless the site is retired and its data was exported
/// after the retirement.
pub async fn delete_site(store: &Store, site: &str, actor: &Actor) -> Result<(), ServiceError> {
    let mut tx = store.begin_write_site(site).await?;
    let Some((retired_at, exported_at)) = sites::retirement_raw(&mut *tx, site).await? else {
        return Err(ServiceError::UnknownSite(site.to_string()));
    };
    let Some(retired_at) = retired_at else {
        return Err(ServiceError::NotDeletable(format!(
            "site '{site}' is in service: retire it first (POST /api/v1/sites/{site}/retire \
             with a reason), export its data (GET /api/v1/sites/{site}/export), then delete it"
        )));
    };
    if exported_at
        .as_deref()
        .is_none_or(|e| e < retired_at.as_str())
    {
        return Err(ServiceError::NotDeletable(format!(
            "site '{site}' was retired on {} but its data has not been exported since: \
             download GET /api/v1/sites/{site}/export first, then delete it",
            store::display_timestamp(&retired_at)
        )));
    }
    let deleted = site_removal::delete_site(&mut tx, site).await?;
    let rows: serde_json::Map<String, Value> = deleted
        .iter()
        .map(|(t, n)| (t.to_string(), json!(n)))
        .collect();
    record(
        &mut tx,
        site,
        actor,
        "site.delete",
        &format!("site {site}"),
        Some(&json!({"rows": rows})),
        None,
    )
    .await?;
    tx.commit().await.map_err(StoreError::from)?;
    tracing::warn!(site, actor = %actor.who, rows = ?deleted, "site deleted");
    Ok(())
}
