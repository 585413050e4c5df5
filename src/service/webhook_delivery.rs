//! The webhook delivery worker: delivers the outbox's due messages until shutdown. All of its
//! state lives in the database (`webhook_deliveries`), so a restart resumes where the last run
//! stopped; a crash between a POST and its bookkeeping sends that message again with the same
//! `webhook-id` (at least once). Each delivery sends the body stored with it (the endpoint's
//! format, rendered when the event was written) or else the outbox's contract body, the same
//! bytes on every retry, signed with the endpoint's secret.

use std::time::Duration;

use chrono::{DateTime, Utc};

use crate::shutdown::Shutdown;
use crate::store::outbox::{self, Attempt, DueDelivery};
use crate::store::{self, Store, StoreError};
use crate::webhooks::{deliver, next_retry, DeliveryOutcome, RetryPolicy};

/// Deliveries claimed at a time: a node that dies holding them leaves them for at most
/// `CLAIM × timeout` (plus a margin) before another node, or this one restarted, retries them.
const CLAIM: i64 = 4;

/// Deliveries sent per pass at most.
const PASS_LIMIT: usize = 100;

/// Settings of the worker.
#[derive(Debug, Clone)]
pub struct WorkerConfig {
    /// How often due deliveries are looked for.
    pub poll: Duration,
    /// Time limit of one POST.
    pub timeout: Duration,
    /// Backoff of retries.
    pub retry: RetryPolicy,
}

impl WorkerConfig {
    /// From the service configuration.
    pub fn from_config(c: &crate::config::Config) -> Self {
        WorkerConfig {
            poll: Duration::from_millis(c.webhook_poll_ms.max(10)),
            timeout: Duration::from_secs(c.webhook_timeout_secs.max(1)),
            retry: c.webhook_retry.clone(),
        }
    }
}

/// Runs until shutdown: delivers due webhook messages every `poll`.
pub async fn run(store: Store, config: WorkerConfig, shutdown: Shutdown) {
    let client = match reqwest::Client::builder().timeout(config.timeout).build() {
        Ok(c) => c,
        Err(e) => {
            tracing::error!(error = %e, "webhook client: worker not started");
            return;
        }
    };
    while !shutdown.is_requested() {
        if let Err(e) = deliver_due(&store, &client, &config, &shutdown).await {
            tracing::warn!(error = %e, "webhook delivery pass failed");
        }
        if let Ok(n) = store::webhooks::pending(store.reader()).await {
            metrics::gauge!("cliffwatch_webhook_queue_depth").set(n as f64);
        }
        if shutdown.sleep(config.poll).await {
            break;
        }
    }
    tracing::info!("webhook worker stopped");
}

/// Claims up to [`CLAIM`] due deliveries for this node (see [`outbox::claim_due`]): several
/// nodes on one database never send the same message at the same time.
async fn claim(store: &Store, timeout: Duration) -> Result<Vec<DueDelivery>, StoreError> {
    let now = Utc::now();
    let lease = chrono::Duration::from_std(timeout * CLAIM as u32 + Duration::from_secs(5))
        .unwrap_or(chrono::Duration::minutes(5));
    let mut tx = store.begin_write_rows().await?;
    let due = outbox::claim_due(
        &mut tx,
        &store::timestamp(now),
        &store::timestamp(now + lease),
        CLAIM,
    )
    .await?;
    tx.commit().await?;
    Ok(due)
}

/// One pass: the deliveries due now, oldest first, claimed a few at a time. Returns how many
/// attempts were made.
pub async fn deliver_due(
    store: &Store,
    client: &reqwest::Client,
    config: &WorkerConfig,
    shutdown: &Shutdown,
) -> Result<usize, StoreError> {
    // Nothing due (the usual case): no write transaction.
    if outbox::due(store.reader(), &store::now(), 1)
        .await?
        .is_empty()
    {
        return Ok(0);
    }
    let mut n = 0;
    let mut gone: Vec<String> = Vec::new();
    while n < PASS_LIMIT && !shutdown.is_requested() {
        let batch = claim(store, config.timeout).await?;
        if batch.is_empty() {
            break;
        }
        for d in batch {
            deliver_one(store, client, &config.retry, &d, &mut gone).await?;
            n += 1;
        }
    }
    Ok(n)
}

/// Sends one claimed delivery and records the outcome; an endpoint disabled by a 410 earlier in
/// the pass (`gone`) gets nothing more.
async fn deliver_one(
    store: &Store,
    client: &reqwest::Client,
    policy: &RetryPolicy,
    d: &DueDelivery,
    gone: &mut Vec<String>,
) -> Result<(), StoreError> {
    if gone.contains(&d.webhook_id) {
        return Ok(());
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
    record(store, d, &outcome, policy, t).await?;
    if outcome == DeliveryOutcome::Gone {
        gone.push(d.webhook_id.clone());
    }
    Ok(())
}

/// The stored outcome of attempt number `attempts` made at `t`.
fn attempt(
    outcome: &DeliveryOutcome,
    policy: &RetryPolicy,
    attempts: i64,
    t: DateTime<Utc>,
) -> Attempt {
    let now = store::timestamp(t);
    let finished = |state, status: Option<u16>, error: Option<String>| Attempt {
        state,
        attempts,
        next_attempt_at: now.clone(),
        status: status.map(i64::from),
        error,
        delivered_at: None,
    };
    match outcome {
        DeliveryOutcome::Delivered { status } => Attempt {
            delivered_at: Some(now.clone()),
            ..finished("delivered", Some(*status), None)
        },
        DeliveryOutcome::Retry {
            status,
            retry_after,
            reason,
        } => {
            let made = u32::try_from(attempts).unwrap_or(u32::MAX);
            match next_retry(policy, made, *retry_after, &mut rand::thread_rng()) {
                Some(delay) => {
                    let at =
                        t + chrono::Duration::from_std(delay).unwrap_or(chrono::Duration::hours(1));
                    Attempt {
                        next_attempt_at: store::timestamp(at),
                        ..finished("pending", *status, Some(reason.clone()))
                    }
                }
                None => finished("failed", *status, Some(reason.clone())),
            }
        }
        DeliveryOutcome::Gone => finished("failed", Some(410), Some("endpoint gone (410)".into())),
        DeliveryOutcome::Failed { status, reason } => {
            finished("failed", *status, Some(reason.clone()))
        }
    }
}

async fn record(
    store: &Store,
    d: &DueDelivery,
    outcome: &DeliveryOutcome,
    policy: &RetryPolicy,
    t: DateTime<Utc>,
) -> Result<(), StoreError> {
    let a = attempt(outcome, policy, d.attempts + 1, t);
    let label = match outcome {
        DeliveryOutcome::Delivered { .. } => "ok",
        DeliveryOutcome::Retry { .. } => "retry",
        DeliveryOutcome::Gone | DeliveryOutcome::Failed { .. } => "failed",
    };
    metrics::counter!("cliffwatch_webhook_deliveries_total", "outcome" => label).increment(1);
    let mut tx = store.begin_write_rows().await?;
    if *outcome == DeliveryOutcome::Gone {
        tracing::warn!(webhook = %d.webhook_id, url = %d.url, "410 Gone: endpoint disabled");
        outbox::endpoint_gone(&mut tx, &d.webhook_id).await?;
    }
    outbox::record_attempt(&mut tx, &d.outbox_id, &d.webhook_id, &a).await?;
    tx.commit().await?;
    Ok(())
}
