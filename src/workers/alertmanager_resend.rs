//! The Alertmanager re-post loop: every `alertmanager_resend_secs` (and at once after any alert
//! changes) each enabled `alertmanager_api_v2` endpoint is sent everything it is to hold now,
//! re-derived from the store ([`crate::webhooks::resend_body`]): every open alert firing with
//! `endsAt` [`HOLD_PERIODS`] periods ahead, and every alert resolved within that time posted
//! resolved. Alertmanager keeps alerts in memory only; after either side restarts it holds
//! every open alert again within one period, and an alert whose resolution never arrives
//! (endpoint deleted, database restored) ends by itself a few periods later.
//!
//! Nothing goes through the retrying outbox: a failed post is simply made again at the next
//! period with the state of then. With several nodes on one database, one node posts at a
//! time ([`Store::try_job_lock`]).

use std::collections::HashMap;
use std::time::{Duration, Instant};

use chrono::{DateTime, Utc};

use crate::shutdown::Shutdown;
use crate::store::{self, alert_repost, webhooks, Store, StoreError};
use crate::webhooks::{
    deliver, message_id_of, resend_body, CurrentAlert, DeliveryOutcome, IncidentLink,
    PayloadFormat, HOLD_PERIODS,
};
use cliffwatch_core::analysis::AlertLevel;

/// Settings of the loop.
#[derive(Debug, Clone)]
pub struct ResendConfig {
    /// The period of the re-posts.
    pub every: Duration,
    /// How often the store is asked whether an alert changed (a post follows at once).
    pub poll: Duration,
    /// Time limit of one POST.
    pub timeout: Duration,
    /// Where people reach the dashboard (the alerts' `generatorURL`).
    pub public_url: Option<String>,
}

impl ResendConfig {
    /// From the service configuration.
    pub fn from_config(c: &crate::config::Config) -> Self {
        let every = Duration::try_from_secs_f64(c.alertmanager_resend_secs)
            .unwrap_or(Duration::from_secs(60));
        ResendConfig {
            every,
            poll: Duration::from_millis(c.webhook_poll_ms.max(10)).min(every),
            timeout: Duration::from_secs(c.webhook_timeout_secs.max(1)),
            public_url: c.public_url.clone(),
        }
    }

    /// How long Alertmanager holds an alert posted firing: [`HOLD_PERIODS`] periods.
    pub fn hold(&self) -> chrono::Duration {
        chrono::Duration::from_std(self.every * HOLD_PERIODS as u32)
            .unwrap_or(chrono::Duration::minutes(4))
    }
}

/// An alert row as Alertmanager needs it, in its incident (`block_of`: the declared block of
/// each point of its site in one); `None` for a row whose times do not parse.
fn current(a: &store::alerts::Alert, block_of: &HashMap<String, String>) -> Option<CurrentAlert> {
    let subject = crate::service::incidents::subject_of(a, block_of);
    let changed_at = store::parse_timestamp(&a.updated_at)?;
    Some(CurrentAlert {
        id: a.id.clone(),
        site: a.site.clone(),
        point: a.point.clone(),
        group: a.group.clone(),
        points: a.points.clone(),
        rule: a.rule.clone(),
        level: a.level,
        peak_level: a.peak_level.max(a.level),
        value: a.value,
        threshold: a.threshold,
        unit: a.unit.clone().unwrap_or_default(),
        epoch: a.epoch,
        observed_at: a.observed_at.as_deref().and_then(store::parse_timestamp),
        message: a.message.clone(),
        raised_at: store::parse_timestamp(&a.raised_at).unwrap_or(changed_at),
        changed_at,
        resolved: a.state == cliffwatch_core::analysis::AlertStatus::Resolved,
        incident: Some(IncidentLink {
            key: subject.key(),
            page: subject.page(&a.site),
        }),
    })
}

/// What one pass did.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Pass {
    /// Whether this node posted (false: another node held the job).
    pub ran: bool,
    /// Endpoints posted to.
    pub endpoints: usize,
    /// Endpoints that answered 2xx.
    pub delivered: usize,
}

/// The message id of one post: `msg_` + 32 hex of the endpoint and the time.
fn post_id(endpoint: &str, now: DateTime<Utc>) -> String {
    message_id_of(&[endpoint.as_bytes(), &now.timestamp_micros().to_le_bytes()])
}

/// One pass: when this node holds the job, posts to every enabled `alertmanager_api_v2`
/// endpoint what it is to hold at the store's clock (only the alerts whose peak level reaches
/// the endpoint's `min_level`). `failing` remembers the endpoints whose last post failed, so a
/// failure and the recovery are logged once.
pub async fn resend_once(
    store: &Store,
    client: &reqwest::Client,
    config: &ResendConfig,
    failing: &mut HashMap<String, bool>,
) -> Result<Pass, StoreError> {
    let Some(_job) = store.try_job_lock("alertmanager resend").await? else {
        return Ok(Pass::default());
    };
    let endpoints: Vec<_> = {
        let mut conn = store.read().await?;
        webhooks::enabled_endpoints(&mut conn)
            .await?
            .into_iter()
            .filter(|e| e.format == PayloadFormat::AlertmanagerApiV2)
            .collect()
    };
    let mut pass = Pass {
        ran: true,
        ..Pass::default()
    };
    if endpoints.is_empty() {
        return Ok(pass);
    }
    let now = store.clock().await?;
    let hold = config.hold();
    let rows = alert_repost::held(store.reader(), &store::timestamp(now - hold)).await?;
    let mut blocks: HashMap<String, HashMap<String, String>> = HashMap::new();
    {
        let mut conn = store.read().await?;
        for r in &rows {
            if !blocks.contains_key(&r.site) {
                let of_site = crate::service::incidents::blocks_of_site(&mut conn, &r.site).await?;
                blocks.insert(r.site.clone(), of_site);
            }
        }
    }
    let alerts: Vec<CurrentAlert> = rows
        .iter()
        .filter_map(|r| current(r, &blocks[&r.site]))
        .collect();
    for e in &endpoints {
        let min = e.min_level.unwrap_or(AlertLevel::Watch);
        let mine: Vec<CurrentAlert> = alerts
            .iter()
            .filter(|a| a.peak_level >= min)
            .cloned()
            .collect();
        let body = resend_body(&mine, now, hold, config.public_url.as_deref());
        let bytes = serde_json::to_vec(&body)?;
        let outcome = deliver(
            client,
            &e.url,
            &e.secret,
            &post_id(&e.id, now),
            &bytes,
            Utc::now(),
        )
        .await;
        pass.endpoints += 1;
        let ok = matches!(outcome, DeliveryOutcome::Delivered { .. });
        let label = if ok { "ok" } else { "failed" };
        metrics::counter!("cliffwatch_alertmanager_posts_total", "outcome" => label).increment(1);
        let was_failing = failing.insert(e.id.clone(), !ok).unwrap_or(false);
        if ok {
            pass.delivered += 1;
            if was_failing {
                tracing::info!(webhook = %e.id, url = %crate::webhooks::loggable_origin(&e.url),
                    alerts = body.len(), "Alertmanager reachable again: every alert posted");
            }
        } else if !was_failing {
            tracing::warn!(webhook = %e.id, url = %crate::webhooks::loggable_origin(&e.url),
                outcome = ?outcome, "Alertmanager post failed; posted again every period");
        }
    }
    Ok(pass)
}

/// Runs until shutdown: a pass at start, then every `every`, and at once (within `poll`) when
/// an alert or an Alertmanager endpoint changed ([`alert_repost::last_change`]).
pub async fn run(store: Store, config: ResendConfig, shutdown: Shutdown) {
    let client = match crate::webhooks::client(config.timeout) {
        Ok(c) => c,
        Err(e) => {
            tracing::error!(error = %e, "Alertmanager client: re-post loop not started");
            return;
        }
    };
    let mut failing = HashMap::new();
    let mut seen = None;
    let mut next = Instant::now();
    while !shutdown.is_requested() {
        let change = alert_repost::last_change(store.reader()).await.ok();
        if Instant::now() >= next || (change.is_some() && change != seen) {
            if let Err(e) = resend_once(&store, &client, &config, &mut failing).await {
                tracing::warn!(error = %e, "Alertmanager re-post failed");
            }
            seen = change;
            next = Instant::now() + config.every;
        }
        if shutdown.sleep(config.poll).await {
            break;
        }
    }
    tracing::info!("Alertmanager re-post loop stopped");
}
