//! The service side of the displacement analysis and the alert rules: loads what
//! [`crate::analysis`] needs from the store (reference coordinates with the stable points' joint
//! covariance, point configurations, per-point history, the site's [`AlertState`]), and writes what
//! it produces (displacement rows, alert rows, webhook outbox rows). Every function takes the
//! caller's write transaction, so an epoch and everything derived from it commit together.
//!
//! The pure computations run in `spawn_blocking`, never on the async runtime.

use std::collections::HashMap;

use chrono::{DateTime, Utc};
use sqlx::SqliteConnection;

use crate::analysis::{
    self, AlertConfig, AlertEvent, AlertEventType, AlertRule, AlertState, AlertStatus,
    AnalysisConfig, AnalysisError, DisplacementRecord, EpochAnalysis, EpochCoordinates, History,
    JointCovarianceM2, PointConfig, PointCoordinates, PointRole,
};
use crate::store::displacements::Displacement;
use crate::store::sites::Site;
use crate::store::{self, points, StoreError};
use crate::webhooks::{
    accepts, message_id, render, PayloadFormat, WebhookEndpoint, WebhookPayload,
};

/// The ids of the epochs that make the reference: the reference epoch and the next
/// `reference_epochs − 1` epochs in time.
pub async fn reference_window(
    tx: &mut SqliteConnection,
    site: &Site,
    reference: i64,
) -> Result<Vec<i64>, StoreError> {
    Ok(sqlx::query_scalar(
        "SELECT id FROM epochs WHERE site_id = ? AND observed_at >= \
         (SELECT observed_at FROM epochs WHERE site_id = ? AND id = ?) ORDER BY observed_at LIMIT ?",
    )
    .bind(&site.id)
    .bind(&site.id)
    .bind(reference)
    .bind(site.reference_epochs.max(1))
    .fetch_all(&mut *tx)
    .await?)
}

/// The reference coordinates of a site: those of `reference`, or with `reference_epochs` K > 1
/// the covariance-weighted mean of the K epochs from it on
/// ([`analysis::reference::combine_reference`]). `Ok(None)` when the reference epoch has no
/// coordinates; `Err` inside `Ok` when the epochs cannot be combined.
pub async fn reference_coordinates(
    tx: &mut SqliteConnection,
    site: &Site,
    reference: i64,
    points: &[PointConfig],
    config: &AnalysisConfig,
) -> Result<Option<Result<EpochCoordinates, AnalysisError>>, StoreError> {
    let Some(first) = epoch_coordinates(tx, &site.id, reference).await? else {
        return Ok(None);
    };
    if site.reference_epochs <= 1 {
        return Ok(Some(Ok(first)));
    }
    let mut epochs = vec![first];
    for id in reference_window(tx, site, reference).await? {
        if id == reference {
            continue;
        }
        if let Some(e) = epoch_coordinates(tx, &site.id, id).await? {
            epochs.push(e);
        }
    }
    let (points, config) = (points.to_vec(), config.clone());
    let combined = tokio::task::spawn_blocking(move || {
        analysis::reference::combine_reference(&epochs, &points, &config)
    })
    .await
    .map_err(|e| StoreError::Corrupt(format!("reference task: {e}")))?;
    Ok(Some(combined))
}

/// The analysis settings of a site (its `confidence` for the significance tests, its
/// `process_noise` for the Kalman filter; library defaults otherwise), without its groups (see
/// [`site_analysis_config`]).
pub fn analysis_config(site: &Site) -> AnalysisConfig {
    let mut config = AnalysisConfig {
        confidence: site.confidence,
        ..AnalysisConfig::default()
    };
    if let Some(q) = site.process_noise {
        config.kalman.process_noise = q;
    }
    config
}

/// [`analysis_config`] with the site's declared block groups.
pub async fn site_analysis_config(
    tx: &mut SqliteConnection,
    site: &Site,
) -> Result<AnalysisConfig, StoreError> {
    let mut config = analysis_config(site);
    config.groups = store::groups::list(&mut *tx, &site.id).await?;
    Ok(config)
}

/// The alert configuration of a site: its `alert_rules` (from the API or the configuration file;
/// rules that do not parse are skipped with a warning) and `schedule_hours`.
pub fn alert_config(site: &Site) -> AlertConfig {
    let rules: Vec<AlertRule> = site
        .alert_rules
        .iter()
        .filter_map(|v| match serde_json::from_value::<AlertRule>(v.clone()) {
            Ok(r) => Some(r),
            Err(e) => {
                tracing::warn!(site = %site.id, rule = %v, error = %e, "alert rule ignored");
                None
            }
        })
        .collect();
    let mut c = AlertConfig::new(site.id.clone(), rules);
    c.schedule_hours = site.schedule_hours;
    c.confidence = site.confidence;
    c
}

/// The stored coordinates of one epoch (with the joint covariance of its stable points when the
/// adjustment stored one) as analysis input; `None` when the epoch has no coordinates.
pub async fn epoch_coordinates(
    tx: &mut SqliteConnection,
    site: &str,
    epoch: i64,
) -> Result<Option<EpochCoordinates>, StoreError> {
    let coords = points::epoch_coordinates(&mut *tx, site, epoch).await?;
    let Some(first) = coords.first() else {
        return Ok(None);
    };
    let Some(observed_at) = store::parse_timestamp(&first.observed_at) else {
        return Ok(None);
    };
    let joint: Option<(String, String)> = sqlx::query_as(
        "SELECT points, matrix_m2 FROM joint_covariances WHERE site_id = ? AND epoch_id = ?",
    )
    .bind(site)
    .bind(epoch)
    .fetch_optional(&mut *tx)
    .await?;
    let joint = match joint {
        Some((p, m)) => Some(JointCovarianceM2 {
            points: serde_json::from_str(&p)?,
            matrix_m2: serde_json::from_str(&m)?,
        }),
        None => None,
    };
    Ok(Some(EpochCoordinates {
        epoch,
        observed_at,
        points: coords
            .into_iter()
            .map(|c| PointCoordinates {
                name: c.point,
                xyz_m: c.xyz,
                covariance_m2: c.covariance_m2,
            })
            .collect(),
        joint,
    }))
}

/// Role, group and direction of interest of every configured point of a site.
pub async fn point_configs(
    tx: &mut SqliteConnection,
    site: &str,
) -> Result<Vec<PointConfig>, StoreError> {
    Ok(points::list(&mut *tx, site, None, i64::MAX)
        .await?
        .into_iter()
        .map(|p| PointConfig {
            name: p.name,
            role: if p.role == "stable" {
                PointRole::Stable
            } else {
                PointRole::Monitored
            },
            group: p.group,
            direction: p.direction,
        })
        .collect())
}

/// The last `per_point` displacement records of every point observed before `before` (stored
/// timestamp form), oldest first per point. One range scan of the primary key (site, point,
/// observed_at) per point, so the cost does not grow with the length of the site's history (a
/// window function over the site's rows read all of them on every upload).
pub async fn history(
    tx: &mut SqliteConnection,
    site: &str,
    before: &str,
    per_point: usize,
) -> Result<History, StoreError> {
    let names: Vec<(String,)> = sqlx::query_as("SELECT name FROM points WHERE site_id = ?")
        .bind(site)
        .fetch_all(&mut *tx)
        .await?;
    let mut out: History = HashMap::new();
    for (point,) in names {
        let mut rows =
            crate::store::displacements::recent(&mut *tx, site, &point, before, per_point).await?;
        rows.reverse();
        let records: Vec<DisplacementRecord> =
            rows.iter().filter_map(Displacement::to_record).collect();
        if !records.is_empty() {
            out.insert(point, records);
        }
    }
    Ok(out)
}

/// The store's time-series rows of analysis records against `reference_epoch` (timestamps in the
/// stored form).
pub fn to_rows(records: &[DisplacementRecord], reference_epoch: i64) -> Vec<Displacement> {
    records
        .iter()
        .map(|r| Displacement::from_record(r, reference_epoch))
        .collect()
}

/// Runs [`analysis::analyse_epoch`] on a blocking thread.
pub async fn analyse_blocking(
    reference: EpochCoordinates,
    current: EpochCoordinates,
    points: Vec<PointConfig>,
    history: History,
    config: AnalysisConfig,
) -> Result<Result<EpochAnalysis, AnalysisError>, tokio::task::JoinError> {
    tokio::task::spawn_blocking(move || {
        analysis::analyse_epoch(&reference, &current, &points, &history, &config)
    })
    .await
}

/// A series analysed again against one reference, with the alert rules replayed over it.
#[derive(Debug, Default)]
pub struct SeriesAnalysis {
    /// Every displacement record, epoch by epoch in time order.
    pub records: Vec<DisplacementRecord>,
    /// Every block motion record (`point` names the group), epoch by epoch.
    pub block_records: Vec<DisplacementRecord>,
    /// The alert state the rules reach over the series, replayed from an empty state.
    pub replayed: AlertState,
    /// Epochs whose analysis failed, with the reason.
    pub failures: Vec<(i64, String)>,
    /// Epochs analysed.
    pub analysed: Vec<i64>,
    /// Every alert event of the replay, in order, with the epoch that caused it.
    pub events: Vec<(i64, AlertEvent)>,
}

/// Analyses a whole series against one reference (pure; the analysis part of
/// `ingest::recompute_site`): `epochs` oldest first; each epoch's history is the records computed
/// before it, and the site's rules are replayed epoch by epoch from an empty state (each epoch
/// stamped with its observation time). Epochs whose analysis fails are listed with the reason and
/// replayed as [`analysis::analysis_failed`].
pub fn analyse_series(
    reference: &EpochCoordinates,
    epochs: &[EpochCoordinates],
    points: &[PointConfig],
    config: &AnalysisConfig,
    alerts: &AlertConfig,
) -> SeriesAnalysis {
    let keep = config.history_epochs().max(1);
    let mut history: History = HashMap::new();
    let mut out = SeriesAnalysis::default();
    for e in epochs {
        match analysis::analyse_epoch(reference, e, points, &history, config) {
            Ok(a) => {
                for r in a.records() {
                    let h = history.entry(r.point.clone()).or_default();
                    h.push(r.clone());
                    if h.len() > keep {
                        h.remove(0);
                    }
                    out.records.push(r);
                }
                out.block_records.extend(a.block_records());
                let (state, events) =
                    analysis::evaluate_alerts(alerts, &out.replayed, &a, e.observed_at);
                out.replayed = state;
                out.events
                    .extend(events.into_iter().map(|ev| (e.epoch, ev)));
                out.analysed.push(e.epoch);
            }
            Err(err) => {
                let reason = format!(
                    "analysis against reference epoch {}: {err}",
                    reference.epoch
                );
                let (state, events) = analysis::analysis_failed(
                    alerts,
                    &out.replayed,
                    e.epoch,
                    e.observed_at,
                    &reason,
                    e.observed_at,
                );
                out.replayed = state;
                out.events
                    .extend(events.into_iter().map(|ev| (e.epoch, ev)));
                out.failures.push((e.epoch, reason));
            }
        }
    }
    out
}

/// [`analyse_series`] on a blocking thread.
pub async fn analyse_series_blocking(
    reference: EpochCoordinates,
    epochs: Vec<EpochCoordinates>,
    points: Vec<PointConfig>,
    config: AnalysisConfig,
    alerts: AlertConfig,
) -> Result<SeriesAnalysis, tokio::task::JoinError> {
    tokio::task::spawn_blocking(move || {
        analyse_series(&reference, &epochs, &points, &config, &alerts)
    })
    .await
}

/// Sets the analysis outcome of a stored epoch: status `adjusted` without `analysis_error` in its
/// report, or `analysis_failed` with the reason in `analysis_error`.
pub async fn set_analysis_status(
    tx: &mut SqliteConnection,
    site: &str,
    epoch: i64,
    error: Option<&str>,
) -> Result<(), StoreError> {
    let report: Option<String> =
        sqlx::query_scalar("SELECT report FROM epochs WHERE site_id = ? AND id = ?")
            .bind(site)
            .bind(epoch)
            .fetch_optional(&mut *tx)
            .await?;
    let mut report: serde_json::Map<String, serde_json::Value> = match report {
        Some(r) => serde_json::from_str(&r)?,
        None => return Ok(()),
    };
    let status = match error {
        Some(e) => {
            report.insert("analysis_error".into(), e.into());
            "analysis_failed"
        }
        None => {
            if report.remove("analysis_error").is_none() {
                return Ok(());
            }
            "adjusted"
        }
    };
    sqlx::query("UPDATE epochs SET status = ?, report = ? WHERE site_id = ? AND id = ?")
        .bind(status)
        .bind(serde_json::Value::Object(report).to_string())
        .bind(site)
        .bind(epoch)
        .execute(&mut *tx)
        .await?;
    Ok(())
}

/// Brings the stored alert state of a site to the state replayed over a recomputed series
/// ([`analysis::reconcile`]: only net changes are announced) and records the events. Returns
/// how many alerts were raised.
pub async fn reconcile_and_record(
    tx: &mut SqliteConnection,
    site: &str,
    replayed: &AlertState,
    now: DateTime<Utc>,
) -> Result<usize, StoreError> {
    let current = load_state(&mut *tx, site).await?;
    let (state, events) = analysis::reconcile(&current, replayed, now);
    save_state(&mut *tx, site, &state).await?;
    record_events(&mut *tx, &events).await
}

/// The alert engine's state of a site (empty when none stored yet).
pub async fn load_state(tx: &mut SqliteConnection, site: &str) -> Result<AlertState, StoreError> {
    let s: Option<String> = sqlx::query_scalar("SELECT state FROM alert_states WHERE site_id = ?")
        .bind(site)
        .fetch_optional(&mut *tx)
        .await?;
    Ok(match s {
        Some(s) => serde_json::from_str(&s)?,
        None => AlertState::default(),
    })
}

/// Stores the alert engine's state of a site.
pub async fn save_state(
    tx: &mut SqliteConnection,
    site: &str,
    state: &AlertState,
) -> Result<(), StoreError> {
    let json = serde_json::to_string(state)?;
    let t = store::now();
    let updated =
        sqlx::query("UPDATE alert_states SET state = ?, updated_at = ? WHERE site_id = ?")
            .bind(&json)
            .bind(&t)
            .bind(site)
            .execute(&mut *tx)
            .await?;
    if updated.rows_affected() == 0 {
        sqlx::query("INSERT INTO alert_states (site_id, state, updated_at) VALUES (?, ?, ?)")
            .bind(site)
            .bind(&json)
            .bind(&t)
            .execute(&mut *tx)
            .await?;
    }
    Ok(())
}

fn state_name(event: &AlertEvent) -> &'static str {
    if event.event_type == AlertEventType::Resolved {
        return "resolved";
    }
    match event.alert.status {
        AlertStatus::Open => "open",
        AlertStatus::Acknowledged => "acknowledged",
        AlertStatus::Resolved => "resolved",
    }
}

/// The enabled webhook endpoints with their level filter and body format (a format the code
/// does not know, impossible under the schema's CHECK, falls back to the contract body with a
/// warning).
pub async fn endpoints(tx: &mut SqliteConnection) -> Result<Vec<WebhookEndpoint>, StoreError> {
    let rows: Vec<(String, String, String, String, String)> = sqlx::query_as(
        "SELECT id, url, secret, min_level, format FROM webhooks WHERE enabled = TRUE",
    )
    .fetch_all(&mut *tx)
    .await?;
    Ok(rows
        .into_iter()
        .map(|(id, url, secret, min, format)| {
            let format = PayloadFormat::from_name(&format).unwrap_or_else(|| {
                tracing::warn!(webhook = %id, format = %format, "unknown body format: contract body");
                PayloadFormat::Standard
            });
            WebhookEndpoint {
                id,
                url,
                secret,
                min_level: serde_json::from_value(serde_json::Value::String(min)).ok(),
                format,
                enabled: true,
            }
        })
        .collect())
}

/// Writes the outcome of alert events: the alert row of each (inserted or updated to the event's
/// snapshot), one outbox row per event (id = [`message_id`], the `webhook-id` of every retry;
/// payload the contract body) and one pending delivery per endpoint that [`accepts`] it, holding
/// the body in the endpoint's format when that is not the contract's ([`render`]), so that every
/// retry sends the same bytes. Returns how many alerts were raised.
pub async fn record_events(
    tx: &mut SqliteConnection,
    events: &[AlertEvent],
) -> Result<usize, StoreError> {
    if events.is_empty() {
        return Ok(0);
    }
    let hooks = endpoints(&mut *tx).await?;
    let now = store::now();
    let mut raised = 0;
    for e in events {
        let a = &e.alert;
        if e.event_type == AlertEventType::Raised {
            raised += 1;
        }
        let updated = sqlx::query(
            "UPDATE alerts SET level = ?, value = ?, threshold = ?, unit = ?, epoch_id = ?, \
             observed_at = ?, message = ?, state = ?, points = ?, updated_at = ?, \
             acknowledged_by = ?, ack_comment = ? WHERE id = ?",
        )
        .bind(a.level.as_str())
        .bind(a.value)
        .bind(a.threshold)
        .bind(&a.unit)
        .bind(a.epoch)
        .bind(a.observed_at.map(store::timestamp))
        .bind(&a.message)
        .bind(state_name(e))
        .bind(serde_json::to_string(&a.points)?)
        .bind(store::timestamp(e.timestamp))
        .bind(&a.acknowledged_by)
        .bind(&a.comment)
        .bind(&a.id)
        .execute(&mut *tx)
        .await?;
        if updated.rows_affected() == 0 {
            sqlx::query(
                "INSERT INTO alerts (id, site_id, point, group_name, points, level, rule, value, \
                 threshold, unit, epoch_id, observed_at, message, state, raised_at, updated_at, \
                 acknowledged_by, ack_comment) \
                 VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
            )
            .bind(&a.id)
            .bind(&a.site)
            .bind(&a.point)
            .bind(&a.group)
            .bind(serde_json::to_string(&a.points)?)
            .bind(a.level.as_str())
            .bind(a.rule.as_str())
            .bind(a.value)
            .bind(a.threshold)
            .bind(&a.unit)
            .bind(a.epoch)
            .bind(a.observed_at.map(store::timestamp))
            .bind(&a.message)
            .bind(state_name(e))
            .bind(store::timestamp(a.raised_at))
            .bind(store::timestamp(e.timestamp))
            .bind(&a.acknowledged_by)
            .bind(&a.comment)
            .execute(&mut *tx)
            .await?;
        }
        let id = message_id(e);
        let exists: Option<String> =
            sqlx::query_scalar("SELECT id FROM webhook_outbox WHERE id = ?")
                .bind(&id)
                .fetch_optional(&mut *tx)
                .await?;
        if exists.is_some() {
            continue;
        }
        let body = serde_json::to_string(&WebhookPayload::from_event(e))?;
        sqlx::query(
            "INSERT INTO webhook_outbox (id, event_type, alert_id, level, payload, created_at) \
             VALUES (?, ?, ?, ?, ?, ?)",
        )
        .bind(&id)
        .bind(e.event_type.as_str())
        .bind(&a.id)
        .bind(a.level.as_str())
        .bind(&body)
        .bind(&now)
        .execute(&mut *tx)
        .await?;
        for h in hooks.iter().filter(|h| accepts(h, e)) {
            let own_body = match h.format {
                PayloadFormat::Standard => None,
                _ => Some(render(e, h, "")?),
            };
            sqlx::query(
                "INSERT INTO webhook_deliveries (outbox_id, webhook_id, state, next_attempt_at, \
                 payload) VALUES (?, ?, 'pending', ?, ?)",
            )
            .bind(&id)
            .bind(&h.id)
            .bind(&now)
            .bind(own_body)
            .execute(&mut *tx)
            .await?;
        }
    }
    Ok(raised)
}

/// Evaluates a site's rules against one epoch's analysis and records the outcome (state, alerts,
/// outbox) in the transaction. Returns how many alerts were raised.
pub async fn evaluate_and_record(
    tx: &mut SqliteConnection,
    site: &Site,
    analysis: &EpochAnalysis,
    now: DateTime<Utc>,
) -> Result<usize, StoreError> {
    let config = alert_config(site);
    let state = load_state(&mut *tx, &site.id).await?;
    let (state, events) = analysis::evaluate_alerts(&config, &state, analysis, now);
    save_state(&mut *tx, &site.id, &state).await?;
    record_events(&mut *tx, &events).await
}

/// Makes a failed analysis visible: the epoch's `status` becomes `analysis_failed` and its report
/// gets `analysis_error` (why), and the site-level `analysis_failed` alert is raised (or kept up
/// to date) with its outbox rows, all in the epoch's transaction. Returns how many alerts were
/// raised.
pub async fn record_analysis_failure(
    tx: &mut SqliteConnection,
    site: &Site,
    epoch: i64,
    observed_at: DateTime<Utc>,
    reason: &str,
    now: DateTime<Utc>,
) -> Result<usize, StoreError> {
    set_analysis_status(&mut *tx, &site.id, epoch, Some(reason)).await?;
    let config = alert_config(site);
    let state = load_state(&mut *tx, &site.id).await?;
    let (state, events) =
        analysis::analysis_failed(&config, &state, epoch, observed_at, reason, now);
    save_state(&mut *tx, &site.id, &state).await?;
    record_events(&mut *tx, &events).await
}

/// `campaign_overdue` of every site with a schedule, in one write transaction per site that changes.
/// Returns how many alerts were raised.
pub async fn check_overdue_all(
    store: &store::Store,
    now: DateTime<Utc>,
) -> Result<usize, StoreError> {
    let ids: Vec<String> =
        sqlx::query_scalar("SELECT id FROM sites WHERE schedule_hours IS NOT NULL")
            .fetch_all(store.reader())
            .await?;
    let mut raised = 0;
    for id in ids {
        let mut tx = store.begin_write().await?;
        let Some(site) = store::sites::get(&mut *tx, &id).await? else {
            continue;
        };
        let last: Option<String> =
            sqlx::query_scalar("SELECT MAX(observed_at) FROM epochs WHERE site_id = ?")
                .bind(&id)
                .fetch_one(&mut *tx)
                .await?;
        let last = last.as_deref().and_then(store::parse_timestamp);
        let state = load_state(&mut tx, &id).await?;
        let (state, events) = analysis::check_overdue(&alert_config(&site), &state, last, now);
        if events.is_empty() {
            continue;
        }
        save_state(&mut tx, &id, &state).await?;
        raised += record_events(&mut tx, &events).await?;
        tx.commit().await?;
    }
    Ok(raised)
}
