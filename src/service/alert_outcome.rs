//! The alert side of a use case, inside its transaction: load the site's alert state, let the
//! pure rules of [`cliffwatch_core::analysis`] decide, save the state, and write each event's alert row,
//! outbox message and one pending delivery per endpoint that takes it (but Alertmanager API v2
//! endpoints, which the re-post loop keeps up to date from the store:
//! [`crate::workers::alertmanager_resend`]).

use chrono::{DateTime, Utc};

use crate::store::sites::Site;
use crate::store::{self, alert_states, alerts, epochs, outbox, webhooks, Connection, StoreError};
use crate::webhooks::{accepts, message_id, render, IncidentLink, PayloadFormat, WebhookPayload};
use cliffwatch_core::analysis::{
    self, AlertEvent, AlertEventType, AlertKind, AlertState, AlertStatus, EpochAnalysis,
};

use super::analysis_inputs::alert_config;

/// The alert row's state after an event.
fn state_after(event: &AlertEvent) -> AlertStatus {
    if event.event_type == AlertEventType::Resolved {
        return AlertStatus::Resolved;
    }
    event.alert.status
}

/// Writes the outcome of alert events: the alert row of each (inserted or updated to the event's
/// snapshot), one outbox message per event (id = [`message_id`], the `webhook-id` of every
/// retry; payload the contract body) and one pending delivery per endpoint that [`accepts`] it,
/// holding the body in the endpoint's format when that is not the contract's ([`render`]), so
/// that every retry sends the same bytes. An `alertmanager_api_v2` endpoint gets no delivery:
/// Alertmanager is told the state, re-derived from the store every period
/// ([`crate::workers::alertmanager_resend`]), not a queue of events whose retries could post a state
/// that is no longer true. `start` is the transaction's time on the store's clock
/// ([`store::clock`]): the delivery worker compares due times with that clock (the database's on
/// PostgreSQL), and the messages' times keep their order whichever node wrote them. Returns how
/// many alerts were raised. Each body names the incident its alert belongs to and links its
/// page ([`super::incident_subject::Subject::page`]), the declared blocks as they are in `tx`;
/// the links are under `public_url` (where people reach the dashboard, the configuration's
/// `public_url`; `None`: no links).
pub async fn record_events(
    tx: &mut Connection,
    events: &[AlertEvent],
    start: DateTime<Utc>,
    public_url: Option<&str>,
) -> Result<usize, StoreError> {
    if events.is_empty() {
        return Ok(0);
    }
    let hooks = webhooks::enabled_endpoints(&mut *tx).await?;
    let mut blocks: std::collections::HashMap<String, _> = std::collections::HashMap::new();
    let due = store::timestamp(start);
    let mut raised = 0;
    for (k, e) in events.iter().enumerate() {
        if e.event_type == AlertEventType::Raised {
            raised += 1;
        }
        alerts::save(&mut *tx, &e.alert, state_after(e), e.timestamp).await?;
        let id = message_id(e);
        if outbox::contains(&mut *tx, &id).await? {
            continue;
        }
        let created_at = message_time(tx, &e.alert.id, start, k).await?;
        if !blocks.contains_key(&e.alert.site) {
            let of_site = super::incident_subject::blocks_of_site(tx, &e.alert.site).await?;
            blocks.insert(e.alert.site.clone(), of_site);
        }
        let incident = incident_of(&e.alert, &blocks[&e.alert.site]);
        let incident = Some(&incident);
        let body = serde_json::to_string(&WebhookPayload::from_event(e, public_url, incident))?;
        let message = outbox::OutboxMessage {
            id: &id,
            event_type: e.event_type.as_str(),
            alert_id: &e.alert.id,
            level: e.alert.level.as_str(),
            payload: &body,
            created_at: &created_at,
            epoch: e.alert.epoch,
        };
        outbox::insert(&mut *tx, &message).await?;
        for h in hooks.iter().filter(|h| accepts(h, e)) {
            let own_body = match h.format {
                PayloadFormat::Standard => None,
                PayloadFormat::AlertmanagerApiV2 => continue,
                PayloadFormat::AlertmanagerWebhook => Some(render(e, h, public_url, incident)?),
            };
            // false: a 410 disabled the endpoint since `hooks` was read
            outbox::queue_delivery(&mut *tx, &id, &h.id, &due, own_body.as_deref()).await?;
        }
    }
    Ok(raised)
}

/// The incident alert `a` belongs to, given the declared block of each point in one.
fn incident_of(
    a: &analysis::Alert,
    block_of: &std::collections::HashMap<String, String>,
) -> IncidentLink {
    let subject =
        super::incident_subject::subject_for(a.group.as_deref(), a.point.as_deref(), block_of);
    IncidentLink {
        key: subject.key(),
        page: subject.page(&a.site),
    }
}

/// The `created_at` of the `k`-th message of a transaction that started at `start`: the
/// worker delivers each alert's messages in `created_at` order, so the messages of one
/// transaction are a microsecond apart in the order of the events, and each comes after every
/// earlier message of its alert even when that was written by a node whose clock runs ahead
/// (the site's write lock orders the transactions, not the nodes' clocks).
async fn message_time(
    tx: &mut Connection,
    alert_id: &str,
    start: DateTime<Utc>,
    k: usize,
) -> Result<String, StoreError> {
    let own = start + chrono::Duration::microseconds(k as i64);
    let after_latest = outbox::latest_of_alert(&mut *tx, alert_id)
        .await?
        .and_then(|t| store::parse_timestamp(&t))
        .map(|t| t + chrono::Duration::microseconds(1));
    Ok(store::timestamp(after_latest.map_or(own, |t| t.max(own))))
}

/// Counts `n` alerts raised in a committed transaction (`cliffwatch_alerts_raised_total`).
pub fn count_raised(n: usize) {
    metrics::counter!("cliffwatch_alerts_raised_total").increment(n as u64);
}

/// Saves the site's new alert state and records the events that led to it; the rows of the
/// other active alerts take their latest value and message. `now` is the transaction's time on
/// the store's clock ([`store::clock`]); the bodies link under `public_url` ([`record_events`]).
/// Returns how many alerts were raised.
pub async fn save_and_record(
    tx: &mut Connection,
    site: &str,
    state: &AlertState,
    events: &[AlertEvent],
    now: DateTime<Utc>,
    public_url: Option<&str>,
) -> Result<usize, StoreError> {
    let (state, events) = &fresh_ids(tx, state, events).await?;
    alert_states::save(&mut *tx, site, state, now).await?;
    let raised = record_events(tx, events, now, public_url).await?;
    // The active alerts without an event this time: their rows follow the latest value too.
    for a in &state.alerts {
        if !events.iter().any(|e| e.alert.id == a.id) {
            alerts::refresh(&mut *tx, a).await?;
        }
    }
    Ok(raised)
}

/// Gives each newly raised alert whose id is already taken a fresh one: `<id>:<raise time in µs>`.
/// An id names the subject, the rule and the epoch that raised it, and a recompute replays the
/// series over the same epochs, so the replay can raise an alert under the id of one that was
/// resolved before; saving it would reopen that row, keeping its old raising time and history,
/// and `alert.raised` would go out for an id staff had seen resolved.
async fn fresh_ids(
    tx: &mut Connection,
    state: &AlertState,
    events: &[AlertEvent],
) -> Result<(AlertState, Vec<AlertEvent>), StoreError> {
    let mut state = state.clone();
    let mut events = events.to_vec();
    for i in 0..events.len() {
        if events[i].event_type != AlertEventType::Raised
            || !alerts::exists(&mut *tx, &events[i].alert.id).await?
        {
            continue;
        }
        let old = events[i].alert.id.clone();
        let new = format!("{old}:{}", events[i].timestamp.timestamp_micros());
        for e in events[i..].iter_mut().filter(|e| e.alert.id == old) {
            e.alert.id = new.clone();
        }
        for a in state.alerts.iter_mut().filter(|a| a.id == old) {
            a.id = new.clone();
        }
    }
    Ok((state, events))
}

/// An epoch arrived on a path that recomputed the whole series instead of evaluating the rules
/// against it: resolves an open `campaign_overdue` ([`analysis::campaign_arrived`]).
pub async fn campaign_arrived(
    tx: &mut Connection,
    site: &Site,
    epoch: i64,
    observed_at: DateTime<Utc>,
    now: DateTime<Utc>,
    public_url: Option<&str>,
) -> Result<usize, StoreError> {
    let state = alert_states::load(&mut *tx, &site.id).await?;
    let (state, events) =
        analysis::campaign_arrived(&alert_config(site), &state, epoch, observed_at, now);
    save_and_record(tx, &site.id, &state, &events, now, public_url).await
}

/// Evaluates a site's rules against one epoch's analysis and records the outcome (state, alerts,
/// outbox). Returns how many alerts were raised.
pub async fn evaluate(
    tx: &mut Connection,
    site: &Site,
    analysis: &EpochAnalysis,
    now: DateTime<Utc>,
    public_url: Option<&str>,
) -> Result<usize, StoreError> {
    let state = alert_states::load(&mut *tx, &site.id).await?;
    let (state, events) = analysis::evaluate_alerts(&alert_config(site), &state, analysis, now);
    save_and_record(tx, &site.id, &state, &events, now, public_url).await
}

/// Makes a failed analysis visible: the epoch's status becomes `analysis_failed` with the reason
/// in its report, and the site-level `analysis_failed` alert is raised (or kept up to date).
/// Returns how many alerts were raised.
pub async fn analysis_failed(
    tx: &mut Connection,
    site: &Site,
    epoch: i64,
    observed_at: DateTime<Utc>,
    reason: &str,
    now: DateTime<Utc>,
    public_url: Option<&str>,
) -> Result<usize, StoreError> {
    epochs::set_analysis_outcome(&mut *tx, &site.id, epoch, Some(reason)).await?;
    let state = alert_states::load(&mut *tx, &site.id).await?;
    let (state, events) =
        analysis::analysis_failed(&alert_config(site), &state, epoch, observed_at, reason, now);
    save_and_record(tx, &site.id, &state, &events, now, public_url).await
}

/// Brings the stored alert state of a site to the state replayed over a recomputed series
/// ([`analysis::reconcile`]: only net changes are announced; open alerts of the `kept` kinds are
/// not lowered) and records the events. Returns how many alerts were raised.
pub async fn reconcile(
    tx: &mut Connection,
    site: &str,
    replayed: &AlertState,
    now: DateTime<Utc>,
    cause: &str,
    kept: &[AlertKind],
    public_url: Option<&str>,
) -> Result<usize, StoreError> {
    let current = alert_states::load(&mut *tx, site).await?;
    let (state, events) = analysis::reconcile(&current, replayed, now, cause, kept);
    save_and_record(tx, site, &state, &events, now, public_url).await
}
