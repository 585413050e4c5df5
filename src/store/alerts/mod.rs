//! Alerts: raised by the alert rules on ingestion, acknowledged through the API.

use std::collections::HashMap;

use serde::Serialize;
use sqlx::{AnyConnection, AnyExecutor, FromRow};
use utoipa::ToSchema;

use chrono::{DateTime, Utc};

use super::{display_timestamp, timestamp, StoreError};
use cliffwatch_core::analysis::{AlertEventType, AlertLevel, AlertStatus};

/// A stored alert.
#[derive(Debug, Clone, Default, Serialize, FromRow, ToSchema)]
pub struct Alert {
    /// Identifier (UUID).
    pub id: String,
    /// Site id.
    #[sqlx(rename = "site_id")]
    pub site: String,
    /// Point (null for site-level and block-group alerts).
    pub point: Option<String>,
    /// Block group of a group alert (null otherwise).
    #[sqlx(rename = "group_name")]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub group: Option<String>,
    /// Points concerned (JSON array text in the database; a list here).
    #[sqlx(skip)]
    pub points: Vec<String>,
    #[serde(skip)]
    #[sqlx(rename = "points")]
    points_json: String,
    /// Its level now (at resolution, the level it had when it resolved).
    #[sqlx(try_from = "String")]
    pub level: AlertLevel,
    /// The highest level it ever reached (an alert that was a warning and resolved from watch
    /// still says it was a warning).
    #[sqlx(skip)]
    pub peak_level: AlertLevel,
    #[serde(skip)]
    #[sqlx(rename = "peak_level")]
    peak_level_text: Option<String>,
    /// Metric of the rule or a site-level kind.
    pub rule: String,
    /// Value that triggered it.
    pub value: Option<f64>,
    /// Threshold of the rule.
    pub threshold: Option<f64>,
    /// Unit of value and threshold.
    pub unit: Option<String>,
    /// Epoch id.
    #[sqlx(rename = "epoch_id")]
    pub epoch: Option<i64>,
    /// Observation time of the epoch.
    pub observed_at: Option<String>,
    /// The epoch that raised it (`epoch` is the latest that evaluated it); null for alerts
    /// of no epoch, and for old alerts whose raising was not recorded.
    #[sqlx(rename = "raised_epoch_id")]
    pub raised_epoch: Option<i64>,
    /// Observation time of the raising epoch (RFC 3339 UTC).
    pub raised_observed_at: Option<String>,
    /// Human-readable message.
    pub message: String,
    /// Where it is in its lifecycle.
    #[sqlx(try_from = "String")]
    pub state: AlertStatus,
    /// When it was raised.
    pub raised_at: String,
    /// Last change.
    pub updated_at: String,
    /// Who acknowledged it.
    pub acknowledged_by: Option<String>,
    /// Comment of the acknowledgement.
    pub ack_comment: Option<String>,
}

/// The columns of [`Alert`]; the peak level is the highest level of its events (the table is
/// read as `alerts`, unaliased).
pub(super) const COLUMNS: &str =
    "id, site_id, point, group_name, points AS points, level, rule, value, threshold, unit, epoch_id, \
    observed_at, raised_epoch_id, raised_observed_at, message, state, raised_at, updated_at, \
    acknowledged_by, ack_comment, (SELECT o.level FROM webhook_outbox o WHERE o.alert_id = alerts.id AND o.level IS NOT NULL \
     ORDER BY CASE o.level WHEN 'alarm' THEN 3 WHEN 'warning' THEN 2 ELSE 1 END DESC LIMIT 1) AS peak_level";

pub(super) fn finish(mut rows: Vec<Alert>) -> Vec<Alert> {
    for a in &mut rows {
        a.points = serde_json::from_str(&a.points_json).unwrap_or_default();
        let peak = a.peak_level_text.as_deref().and_then(|l| l.parse().ok());
        a.peak_level = peak.map_or(a.level, |p: AlertLevel| p.max(a.level));
        a.raised_at = display_timestamp(&a.raised_at);
        a.updated_at = display_timestamp(&a.updated_at);
        a.observed_at = a.observed_at.as_deref().map(display_timestamp);
        a.raised_observed_at = a.raised_observed_at.as_deref().map(display_timestamp);
    }
    rows
}

/// Alerts newest first, optionally of one site and state; `after` is `(raised_at, id)` of the last
/// item of the previous page (raised_at in store format).
pub async fn list(
    db: impl AnyExecutor<'_>,
    site: Option<&str>,
    state: Option<AlertStatus>,
    after: Option<(&str, &str)>,
    limit: i64,
) -> Result<Vec<(String, Alert)>, StoreError> {
    let (t, id) = after.unwrap_or((super::TEXT_MAX, super::TEXT_MAX));
    let state = state.map(AlertStatus::as_str);
    let sql = list_sql(site.is_some(), state.is_some());
    let mut query = sqlx::query_as::<_, Alert>(&sql);
    for value in [site, state].into_iter().flatten() {
        query = query.bind(value);
    }
    let rows: Vec<Alert> = query.bind(t).bind(id).bind(limit).fetch_all(db).await?;
    let raw: Vec<String> = rows.iter().map(|a| a.raised_at.clone()).collect();
    Ok(raw.into_iter().zip(finish(rows)).collect())
}

/// The statement of [`list`]: only the filters given, so that each combination reads its own
/// index (`alerts_by_time`, `alerts_by_site_time`, `alerts_by_state`, `alerts_by_site`) from the
/// cursor on, newest first, rather than scanning and sorting every alert. Binds: the site and
/// the state when filtered, then the cursor's `raised_at` and id, then the limit.
fn list_sql(site: bool, state: bool) -> String {
    let mut conditions = Vec::new();
    let mut n = 0;
    let mut next = || {
        n += 1;
        n
    };
    if site {
        conditions.push(format!("site_id = ${}", next()));
    }
    if state {
        conditions.push(format!("state = ${}", next()));
    }
    let (t, id, limit) = (next(), next(), next());
    conditions.push(format!("(raised_at, id) < (${t}, ${id})"));
    format!(
        "SELECT {COLUMNS} FROM alerts WHERE {} ORDER BY raised_at DESC, id DESC LIMIT ${limit}",
        conditions.join(" AND ")
    )
}

/// The newest `limit` alerts of `site` that are not resolved (open or acknowledged), newest
/// first, with their raw `raised_at`: however many resolved alerts are newer, an open alarm is
/// among them.
pub async fn list_active(
    db: impl AnyExecutor<'_>,
    site: &str,
    limit: i64,
) -> Result<Vec<(String, Alert)>, StoreError> {
    list_active_after(db, site, None, limit).await
}

/// [`list_active`] from the cursor `after` on (`(raised_at, id)` of the previous page's last
/// alert, raised_at in store format).
pub async fn list_active_after(
    db: impl AnyExecutor<'_>,
    site: &str,
    after: Option<(&str, &str)>,
    limit: i64,
) -> Result<Vec<(String, Alert)>, StoreError> {
    let (t, id) = after.unwrap_or((super::TEXT_MAX, super::TEXT_MAX));
    let rows: Vec<Alert> = sqlx::query_as(&format!(
        "SELECT {COLUMNS} FROM alerts WHERE site_id = $1 AND state <> 'resolved' \
         AND (raised_at, id) < ($2, $3) ORDER BY raised_at DESC, id DESC LIMIT $4"
    ))
    .bind(site)
    .bind(t)
    .bind(id)
    .bind(limit)
    .fetch_all(db)
    .await?;
    let raw: Vec<String> = rows.iter().map(|a| a.raised_at.clone()).collect();
    Ok(raw.into_iter().zip(finish(rows)).collect())
}

/// Whether an alert with id `id` was ever stored (open, acknowledged or resolved).
pub async fn exists(db: impl AnyExecutor<'_>, id: &str) -> Result<bool, StoreError> {
    let found: Option<i64> = sqlx::query_scalar("SELECT 1 FROM alerts WHERE id = $1")
        .bind(id)
        .fetch_optional(db)
        .await?;
    Ok(found.is_some())
}

/// One alert.
pub async fn get(db: impl AnyExecutor<'_>, id: &str) -> Result<Option<Alert>, StoreError> {
    let row: Option<Alert> = sqlx::query_as(&format!("SELECT {COLUMNS} FROM alerts WHERE id = $1"))
        .bind(id)
        .fetch_optional(db)
        .await?;
    Ok(row.map(|a| finish(vec![a]).remove(0)))
}

/// The alerts that one epoch raised or escalated, as they are now (an alert that a later epoch
/// left active is not repeated in that epoch's summary).
pub async fn of_epoch(
    db: impl AnyExecutor<'_>,
    site: &str,
    epoch: i64,
) -> Result<Vec<Alert>, StoreError> {
    let rows: Vec<Alert> = sqlx::query_as(&format!(
        "SELECT {COLUMNS} FROM alerts WHERE site_id = $1 AND id IN (SELECT o.alert_id FROM \
         webhook_outbox o WHERE o.epoch_id = $2 AND o.event_type IN ('alert.raised', 'alert.escalated')) \
         ORDER BY raised_at, id"
    ))
    .bind(site)
    .bind(epoch)
    .fetch_all(db)
    .await?;
    Ok(finish(rows))
}

/// The highest level of each point's open or acknowledged alerts (alerts that concern one point);
/// points without one are absent.
pub async fn active_levels(
    db: impl AnyExecutor<'_>,
    site: &str,
) -> Result<HashMap<String, AlertLevel>, StoreError> {
    let rows: Vec<(String, String)> = sqlx::query_as(
        "SELECT point, level FROM alerts WHERE site_id = $1 AND point IS NOT NULL AND state <> 'resolved'",
    )
    .bind(site)
    .fetch_all(db)
    .await?;
    let mut highest = HashMap::new();
    for (point, level) in rows {
        let level: AlertLevel = level.parse()?;
        let e = highest.entry(point).or_insert(level);
        *e = (*e).max(level);
    }
    Ok(highest)
}

/// Writes an alert as the alert engine left it after an event: the row is updated to the
/// alert's snapshot, or inserted when the alert is new (its raising epoch, else its epoch, kept
/// in `raised_epoch_id` and `raised_observed_at`). `state` is the row's state after the
/// event (`open`, `acknowledged` or `resolved`), `updated_at` the event's time.
pub async fn save(
    db: &mut AnyConnection,
    a: &cliffwatch_core::analysis::Alert,
    state: AlertStatus,
    updated_at: DateTime<Utc>,
) -> Result<(), StoreError> {
    let points = serde_json::to_string(&a.points)?;
    // One statement: a new alert is inserted; a known one takes the snapshot's changing columns
    // (its site, subject, rule and raising time stay as first written).
    sqlx::query(
        "INSERT INTO alerts (id, site_id, point, group_name, points, level, rule, value, \
         threshold, unit, epoch_id, observed_at, message, state, raised_at, updated_at, \
         acknowledged_by, ack_comment, raised_epoch_id, raised_observed_at) \
         VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9, $10, $11, $12, $13, $14, $15, $16, $17, $18, \
         $19, $20) \
         ON CONFLICT (id) DO UPDATE SET level = excluded.level, value = excluded.value, \
         threshold = excluded.threshold, unit = excluded.unit, epoch_id = excluded.epoch_id, \
         observed_at = excluded.observed_at, message = excluded.message, state = excluded.state, \
         points = excluded.points, updated_at = excluded.updated_at, \
         acknowledged_by = excluded.acknowledged_by, ack_comment = excluded.ack_comment",
    )
    .bind(&a.id)
    .bind(&a.site)
    .bind(&a.point)
    .bind(&a.group)
    .bind(&points)
    .bind(a.level.as_str())
    .bind(a.rule.as_str())
    .bind(a.value)
    .bind(a.threshold)
    .bind(&a.unit)
    .bind(a.epoch)
    .bind(a.observed_at.map(timestamp))
    .bind(&a.message)
    .bind(state.as_str())
    .bind(timestamp(a.raised_at))
    .bind(timestamp(updated_at))
    .bind(&a.acknowledged_by)
    .bind(&a.comment)
    .bind(a.raised_epoch.or(a.epoch))
    .bind(a.raised_observed_at.or(a.observed_at).map(timestamp))
    .execute(&mut *db)
    .await?;
    Ok(())
}

/// Brings an active alert's row up to the engine's latest evaluation: value, threshold, epoch,
/// observation time, message and the points concerned (a later epoch can add stable points to
/// `reference_unstable`, or points to a block's alert, without changing the level). Its state and
/// `updated_at` change only with events, [`save`].
pub async fn refresh(
    db: &mut AnyConnection,
    a: &cliffwatch_core::analysis::Alert,
) -> Result<(), StoreError> {
    sqlx::query(
        "UPDATE alerts SET value = $1, threshold = $2, epoch_id = $3, observed_at = $4, \
         message = $5, points = $6 WHERE id = $7",
    )
    .bind(a.value)
    .bind(a.threshold)
    .bind(a.epoch)
    .bind(a.observed_at.map(timestamp))
    .bind(&a.message)
    .bind(serde_json::to_string(&a.points)?)
    .bind(&a.id)
    .execute(&mut *db)
    .await?;
    Ok(())
}

/// Acknowledges an alert at `at` (the transaction's time on the store's clock); `Ok(false)` when
/// it does not exist.
pub async fn acknowledge(
    db: &mut AnyConnection,
    id: &str,
    by: &str,
    comment: Option<&str>,
    at: DateTime<Utc>,
) -> Result<bool, StoreError> {
    let at = timestamp(at);
    let done = sqlx::query(
        "UPDATE alerts SET state = CASE WHEN state = 'resolved' THEN state ELSE 'acknowledged' END, \
         acknowledged_by = $1, ack_comment = $2, updated_at = $3 WHERE id = $4",
    )
    .bind(by)
    .bind(comment)
    .bind(&at)
    .bind(id)
    .execute(db)
    .await?;
    Ok(done.rows_affected() == 1)
}

/// One change of an alert as recorded for the webhooks: `alert.raised`, `alert.escalated`,
/// `alert.deescalated`, `alert.acknowledged` or `alert.resolved`.
#[derive(Debug, Clone, PartialEq)]
pub struct AlertEvent {
    /// The event type.
    pub event_type: AlertEventType,
    /// The alert's id.
    pub alert_id: String,
    /// Level after the event.
    pub level: Option<AlertLevel>,
    /// When it happened on the epochs' time axis (store format): the epoch's observation time
    /// for changes made by an epoch, the wall-clock time of an acknowledgement.
    pub at: String,
}

/// `LIKE` pattern of `point` as a member of an alert's `points` (a JSON array; `%`, `_` and
/// the backslash escaped with a backslash). A prefilter only: SQLite's `LIKE` ignores the case of
/// ASCII letters, so [`concerns`] decides.
fn member_pattern(point: &str) -> String {
    format!(
        "%\"{}\"%",
        point
            .replace('\\', "\\\\")
            .replace('%', "\\%")
            .replace('_', "\\_")
    )
}

/// Whether the alert of `alert_point` and `points` (its JSON array of points) concerns `point`:
/// as its point or one of its points, exactly (point names are case-sensitive).
fn concerns(point: &str, alert_point: Option<&str>, points: &str) -> bool {
    alert_point == Some(point)
        || serde_json::from_str::<Vec<String>>(points).is_ok_and(|ps| ps.iter().any(|p| p == point))
}

/// The epochs at which the alerts concerning `point` (as the point of the alert or one of its
/// points) were last raised or changed, each once, in no order: epochs a plot of the point keeps.
pub async fn epochs_of_point(
    db: impl AnyExecutor<'_>,
    site: &str,
    point: &str,
) -> Result<Vec<i64>, StoreError> {
    let rows: Vec<(i64, Option<String>, String)> = sqlx::query_as(
        "SELECT epoch_id, point, points FROM alerts WHERE site_id = $1 AND epoch_id IS NOT NULL \
         AND (point = $2 OR points LIKE $3 ESCAPE '\\')",
    )
    .bind(site)
    .bind(point)
    .bind(member_pattern(point))
    .fetch_all(db)
    .await?;
    let mut epochs: Vec<i64> = rows
        .into_iter()
        .filter(|(_, p, ps)| concerns(point, p.as_deref(), ps))
        .map(|(e, _, _)| e)
        .collect();
    epochs.sort_unstable();
    epochs.dedup();
    Ok(epochs)
}

/// The recorded changes of the alerts that concern `point` (as the point of the alert or one of
/// its points), oldest first, each at the time of the epoch its body names (an acknowledgement,
/// or a body without one, at its recording time; a body that does not parse as well, with a
/// warning naming the alert).
pub async fn events_of_point(
    db: impl AnyExecutor<'_>,
    site: &str,
    point: &str,
) -> Result<Vec<AlertEvent>, StoreError> {
    /// A recorded change with the alert's point and points, to tell whether it concerns `point`.
    #[derive(sqlx::FromRow)]
    struct EventRow {
        event_type: String,
        alert_id: String,
        level: Option<String>,
        payload: String,
        created_at: String,
        point: Option<String>,
        points: String,
    }
    let rows: Vec<EventRow> = sqlx::query_as(
        "SELECT o.event_type, o.alert_id, o.level, o.payload, o.created_at, a.point, a.points \
         FROM webhook_outbox o JOIN alerts a ON a.id = o.alert_id \
         WHERE a.site_id = $1 AND (a.point = $2 OR a.points LIKE $3 ESCAPE '\\') ORDER BY o.created_at",
    )
    .bind(site)
    .bind(point)
    .bind(member_pattern(point))
    .fetch_all(db)
    .await?;
    rows.into_iter()
        .filter(|r| concerns(point, r.point.as_deref(), &r.points))
        .map(|r| {
            let EventRow {
                event_type,
                alert_id,
                level,
                payload,
                created_at: created,
                ..
            } = r;
            let event_type: AlertEventType = event_type.parse()?;
            let observed = match serde_json::from_str::<crate::webhooks::WebhookPayload>(&payload) {
                Ok(body) => body.data.observed_at,
                Err(e) => {
                    tracing::warn!(alert = %alert_id, error = %e,
                        "an alert event's body does not parse; shown at its recording time");
                    None
                }
            };
            let at = match (event_type, observed) {
                (AlertEventType::Acknowledged, _) | (_, None) => created,
                (_, Some(o)) => o,
            };
            Ok(AlertEvent {
                event_type,
                alert_id,
                level: level.as_deref().map(str::parse).transpose()?,
                at,
            })
        })
        .collect()
}

/// One alert's history: the body of each of its events as its webhooks carry it, oldest first
/// (events recorded in one transaction share the recording time; their own times order them).
/// A body that no longer parses is left out.
pub async fn history(
    db: impl AnyExecutor<'_>,
    alert_id: &str,
) -> Result<Vec<crate::webhooks::WebhookPayload>, StoreError> {
    let rows: Vec<(String, String)> =
        sqlx::query_as("SELECT created_at, payload FROM webhook_outbox WHERE alert_id = $1")
            .bind(alert_id)
            .fetch_all(db)
            .await?;
    let items = rows
        .into_iter()
        .filter_map(|(recorded, body)| {
            let payload: crate::webhooks::WebhookPayload = serde_json::from_str(&body).ok()?;
            Some((recorded, payload.timestamp.clone(), payload))
        })
        .collect();
    Ok(oldest_first(items))
}

/// Outbox items as (recording time, event time, item), oldest first: by recording time, then,
/// for events recorded in one transaction, by the time of their epoch.
fn oldest_first<T>(mut items: Vec<(String, String, T)>) -> Vec<T> {
    items.sort_by(|a, b| (&a.0, &a.1).cmp(&(&b.0, &b.1)));
    items.into_iter().map(|(_, _, item)| item).collect()
}

/// The recorded changes of one alert (its outbox events) as the CAP feed reads them, oldest
/// first: type, level after, when each was recorded (UTC) and the alert as the event's body
/// ([`crate::webhooks::WebhookPayload`], the typed body it was written from) states it. Events
/// recorded in one transaction share the recording time and are ordered by the time of their
/// epoch. A body that does not parse is [`StoreError::EventBody`], naming the alert.
pub async fn changes_of(
    db: impl AnyExecutor<'_>,
    alert_id: &str,
) -> Result<Vec<crate::cap::Change>, StoreError> {
    let rows: Vec<(String, Option<String>, String, String)> = sqlx::query_as(
        "SELECT event_type, level, payload, created_at FROM webhook_outbox WHERE alert_id = $1",
    )
    .bind(alert_id)
    .fetch_all(db)
    .await?;
    let mut changes: Vec<(String, String, crate::cap::Change)> = Vec::with_capacity(rows.len());
    for (event_type, level, payload, created) in rows {
        let Some(at) = super::parse_timestamp(&created) else {
            continue;
        };
        let body: crate::webhooks::WebhookPayload =
            serde_json::from_str(&payload).map_err(|source| StoreError::EventBody {
                alert: alert_id.to_string(),
                source,
            })?;
        changes.push((
            created,
            body.timestamp,
            crate::cap::Change {
                event_type: event_type.parse()?,
                level: level.as_deref().map(str::parse).transpose()?,
                at,
                snapshot: snapshot_of(body.data),
            },
        ));
    }
    Ok(oldest_first(changes))
}

/// The alert as an event's body states it, as a CAP message shows it.
fn snapshot_of(data: crate::webhooks::WebhookData) -> crate::cap::Snapshot {
    crate::cap::Snapshot {
        value: data.value,
        threshold: data.threshold,
        unit: Some(data.unit),
        observed_at: data.observed_at,
        message: data.message,
    }
}

/// The movement alerts ([`crate::cap::PUBLIC_RULES`]) that ever reached `warning` or `alarm`
/// (those the CAP feed carries), of one site or of all, most recently changed first.
pub async fn ever_public(
    db: impl AnyExecutor<'_>,
    site: Option<&str>,
    limit: i64,
) -> Result<Vec<Alert>, StoreError> {
    let sql = ever_public_sql(site.is_some());
    let mut query = sqlx::query_as::<_, Alert>(&sql);
    if let Some(site) = site {
        query = query.bind(site);
    }
    let rows: Vec<Alert> = query.bind(limit).fetch_all(db).await?;
    Ok(finish(rows))
}

/// The query of [`ever_public`] with only the filter given, so that one site's feed reads that
/// site's alerts alone (`alerts_by_site_update`), newest first without a sort.
fn ever_public_sql(site: bool) -> String {
    let (site_filter, limit_param) = match site {
        true => ("site_id = $1 AND", "$2"),
        false => ("", "$1"),
    };
    let rules: Vec<String> = crate::cap::PUBLIC_RULES
        .iter()
        .map(|k| format!("'{}'", k.as_str()))
        .collect();
    format!(
        "SELECT {COLUMNS} FROM alerts WHERE {site_filter} rule IN ({}) AND EXISTS \
         (SELECT 1 FROM webhook_outbox o2 WHERE o2.alert_id = alerts.id AND o2.level IN ('warning', 'alarm')) \
         ORDER BY updated_at DESC, id DESC LIMIT {limit_param}",
        rules.join(", ")
    )
}

#[cfg(test)]
mod tests;
