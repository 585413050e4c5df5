//! The webhook delivery worker and the periodic campaign check: a tokio task started by the server
//! and stopped on shutdown. All of its state lives in the database (`webhook_deliveries`), so a
//! restart resumes where the last run stopped; a crash between a POST and its bookkeeping sends that
//! message again with the same `webhook-id` (at least once). Each delivery sends the body stored
//! with it (the endpoint's format, rendered when the event was written) or else the outbox's
//! contract body, the same bytes on every retry, signed with the endpoint's secret.

use std::time::Duration;

use chrono::{DateTime, Utc};
use sqlx::FromRow;

use crate::alerting;
use crate::store::{self, Store, StoreError};
use crate::webhooks::{deliver, next_retry, DeliveryOutcome, RetryPolicy};

/// Settings of the worker.
#[derive(Debug, Clone)]
pub struct WorkerConfig {
    /// How often due deliveries are looked for.
    pub poll: Duration,
    /// Time limit of one POST.
    pub timeout: Duration,
    /// Backoff of retries.
    pub retry: RetryPolicy,
    /// How often the campaign schedules are checked.
    pub overdue_every: Duration,
}

impl WorkerConfig {
    /// From the service configuration.
    pub fn from_config(c: &crate::config::Config) -> Self {
        WorkerConfig {
            poll: Duration::from_millis(c.webhook_poll_ms.max(10)),
            timeout: Duration::from_secs(c.webhook_timeout_secs.max(1)),
            retry: c.webhook_retry.clone(),
            overdue_every: Duration::from_secs(c.overdue_check_secs.max(1)),
        }
    }
}

#[derive(FromRow)]
struct Due {
    outbox_id: String,
    webhook_id: String,
    attempts: i64,
    payload: String,
    url: String,
    secret: String,
}

/// Runs until `stop` turns true: delivers due webhook messages and checks campaign schedules.
pub async fn run(store: Store, config: WorkerConfig, mut stop: tokio::sync::watch::Receiver<bool>) {
    let client = match reqwest::Client::builder().timeout(config.timeout).build() {
        Ok(c) => c,
        Err(e) => {
            tracing::error!(error = %e, "webhook client: worker not started");
            return;
        }
    };
    let mut last_overdue: Option<std::time::Instant> = None;
    loop {
        if *stop.borrow() {
            break;
        }
        if last_overdue.is_none_or(|t| t.elapsed() >= config.overdue_every) {
            last_overdue = Some(std::time::Instant::now());
            match alerting::check_overdue_all(&store, Utc::now()).await {
                Ok(n) if n > 0 => {
                    metrics::counter!("cliffwatch_alerts_raised_total").increment(n as u64)
                }
                Ok(_) => {}
                Err(e) => tracing::warn!(error = %e, "campaign schedule check failed"),
            }
        }
        match deliver_due(&store, &client, &config.retry, &mut stop).await {
            Ok(_) => {}
            Err(e) => tracing::warn!(error = %e, "webhook delivery pass failed"),
        }
        if let Ok(n) = store::webhooks::pending(store.reader()).await {
            metrics::gauge!("cliffwatch_webhook_queue_depth").set(n as f64);
        }
        tokio::select! {
            _ = tokio::time::sleep(config.poll) => {}
            _ = stop.wait_for(|v| *v) => break,
        }
    }
    tracing::info!("webhook worker stopped");
}

/// One pass: every delivery due now, oldest first. Returns how many attempts were made.
pub async fn deliver_due(
    store: &Store,
    client: &reqwest::Client,
    policy: &RetryPolicy,
    stop: &mut tokio::sync::watch::Receiver<bool>,
) -> Result<usize, StoreError> {
    let now = store::now();
    let due: Vec<Due> = sqlx::query_as(
        "SELECT d.outbox_id, d.webhook_id, d.attempts, COALESCE(d.payload, o.payload) AS payload, \
         w.url, w.secret \
         FROM webhook_deliveries d JOIN webhook_outbox o ON o.id = d.outbox_id \
         JOIN webhooks w ON w.id = d.webhook_id \
         WHERE d.state = 'pending' AND d.next_attempt_at <= ? AND w.enabled = TRUE \
         ORDER BY d.next_attempt_at, o.created_at, d.outbox_id LIMIT 100",
    )
    .bind(&now)
    .fetch_all(store.reader())
    .await?;
    let mut n = 0;
    let mut gone: Vec<String> = Vec::new();
    for d in due {
        if *stop.borrow() {
            break;
        }
        // An endpoint disabled by a 410 earlier in this pass gets nothing more.
        if gone.contains(&d.webhook_id) {
            continue;
        }
        let t = Utc::now();
        let outcome = deliver(
            client,
            &d.url,
            &d.secret,
            &d.outbox_id,
            d.payload.as_bytes(),
            t,
        )
        .await;
        record(store, &d, &outcome, policy, t).await?;
        if outcome == DeliveryOutcome::Gone {
            gone.push(d.webhook_id.clone());
        }
        n += 1;
    }
    Ok(n)
}

async fn record(
    store: &Store,
    d: &Due,
    outcome: &DeliveryOutcome,
    policy: &RetryPolicy,
    t: DateTime<Utc>,
) -> Result<(), StoreError> {
    let attempts = d.attempts + 1;
    let mut tx = store.begin_write().await?;
    let update = "UPDATE webhook_deliveries SET state = ?, attempts = ?, next_attempt_at = ?, \
                  last_status = ?, last_error = ?, delivered_at = ? WHERE outbox_id = ? AND webhook_id = ?";
    let now = store::timestamp(t);
    let (state, next, status, error, delivered): (
        &str,
        String,
        Option<i64>,
        Option<String>,
        Option<String>,
    ) = match outcome {
        DeliveryOutcome::Delivered { status } => {
            metrics::counter!("cliffwatch_webhook_deliveries_total", "outcome" => "ok")
                .increment(1);
            (
                "delivered",
                now.clone(),
                Some(*status as i64),
                None,
                Some(now.clone()),
            )
        }
        DeliveryOutcome::Retry {
            status,
            retry_after,
            reason,
        } => {
            metrics::counter!("cliffwatch_webhook_deliveries_total", "outcome" => "retry")
                .increment(1);
            let made = u32::try_from(attempts).unwrap_or(u32::MAX);
            match next_retry(policy, made, *retry_after, &mut rand::thread_rng()) {
                Some(delay) => {
                    let at =
                        t + chrono::Duration::from_std(delay).unwrap_or(chrono::Duration::hours(1));
                    (
                        "pending",
                        store::timestamp(at),
                        status.map(i64::from),
                        Some(reason.clone()),
                        None,
                    )
                }
                None => (
                    "failed",
                    now.clone(),
                    status.map(i64::from),
                    Some(reason.clone()),
                    None,
                ),
            }
        }
        DeliveryOutcome::Gone => {
            metrics::counter!("cliffwatch_webhook_deliveries_total", "outcome" => "failed")
                .increment(1);
            tracing::warn!(webhook = %d.webhook_id, url = %d.url, "410 Gone: endpoint disabled");
            sqlx::query("UPDATE webhooks SET enabled = FALSE WHERE id = ?")
                .bind(&d.webhook_id)
                .execute(&mut *tx)
                .await?;
            sqlx::query(
                    "UPDATE webhook_deliveries SET state = 'failed', last_error = 'endpoint gone (410)' \
                     WHERE webhook_id = ? AND state = 'pending'",
                )
                .bind(&d.webhook_id)
                .execute(&mut *tx)
                .await?;
            (
                "failed",
                now.clone(),
                Some(410),
                Some("endpoint gone (410)".into()),
                None,
            )
        }
        DeliveryOutcome::Failed { status, reason } => {
            metrics::counter!("cliffwatch_webhook_deliveries_total", "outcome" => "failed")
                .increment(1);
            (
                "failed",
                now.clone(),
                status.map(i64::from),
                Some(reason.clone()),
                None,
            )
        }
    };
    sqlx::query(update)
        .bind(state)
        .bind(attempts)
        .bind(next)
        .bind(status)
        .bind(error)
        .bind(delivered)
        .bind(&d.outbox_id)
        .bind(&d.webhook_id)
        .execute(&mut *tx)
        .await?;
    tx.commit().await?;
    Ok(())
}
