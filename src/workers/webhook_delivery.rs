//! The webhook delivery worker: delivers the outbox's due messages until shutdown. All of its
//! state lives in the database (`webhook_deliveries`), so a restart resumes where the last run
//! stopped; a crash between a POST and its bookkeeping sends that message again with the same
//! `webhook-id` (at least once). Each delivery sends the body stored with it (the endpoint's
//! format, rendered when the event was written) or else the outbox's contract body, the same
//! bytes on every retry, signed with the endpoint's secret.
//!
//! Each endpoint is served by its own task, and sees each alert's messages in the order they
//! were written: a message waits while an earlier one of its alert to that endpoint is still
//! being retried ([`outbox::claim_due`]). A message is given up only after the retry policy's
//! last attempt (about two days by default) or when its endpoint answers 410 Gone; either is
//! logged as an error, counted as `outcome="failed"`, and shown by `GET /api/v1/webhooks`.

use std::collections::HashMap;
use std::time::{Duration, Instant};

use chrono::{DateTime, Utc};

use crate::shutdown::Shutdown;
use crate::store::outbox::{self, Attempt, DueDelivery};
use crate::store::{self, Store, StoreError};
use crate::webhooks::{deliver, next_retry, DeliveryOutcome, RetryPolicy};

/// Deliveries to one endpoint claimed at a time: a node that dies holding them leaves them for at most
/// `CLAIM × timeout` (plus a margin) before another node, or this one restarted, retries them.
const CLAIM: i64 = 4;

/// Deliveries sent to one endpoint per pass at most.
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

/// Runs until shutdown: every `poll`, each endpoint with due messages gets a task of its own that
/// delivers them ([`deliver_to`]). An endpoint that hangs or refuses holds up only its own
/// messages, never another endpoint's alarms. At shutdown the tasks finish the POST in hand.
pub async fn run(store: Store, config: WorkerConfig, shutdown: Shutdown) {
    let client = match crate::webhooks::client(config.timeout) {
        Ok(c) => c,
        Err(e) => {
            tracing::error!(error = %e, "webhook client: worker not started");
            return;
        }
    };
    let mut busy: HashMap<String, tokio::task::JoinHandle<()>> = HashMap::new();
    while !shutdown.is_requested() {
        busy.retain(|_, task| !task.is_finished());
        let due = match store.clock().await {
            Ok(now) => outbox::due_endpoints(store.reader(), &store::timestamp(now)).await,
            Err(e) => Err(e),
        };
        match due {
            Ok(endpoints) => {
                for id in endpoints {
                    if busy.contains_key(&id) {
                        continue;
                    }
                    let task = tokio::spawn(deliver_to(
                        store.clone(),
                        client.clone(),
                        config.clone(),
                        shutdown.clone(),
                        id.clone(),
                    ));
                    busy.insert(id, task);
                }
            }
            Err(e) => tracing::warn!(error = %e, "webhook delivery: due endpoints not read"),
        }
        if let Ok(n) = store::webhooks::pending(store.reader()).await {
            metrics::gauge!("cliffwatch_webhook_queue_depth").set(n as f64);
        }
        if shutdown.sleep(config.poll).await {
            break;
        }
    }
    for (_, task) in busy {
        let _ = task.await;
    }
    tracing::info!("webhook worker stopped");
}

/// Delivers endpoint `webhook_id`'s due messages, claimed [`CLAIM`] at a time, until none is due,
/// [`PASS_LIMIT`] were sent, shutdown, or the endpoint is gone.
async fn deliver_to(
    store: Store,
    client: reqwest::Client,
    config: WorkerConfig,
    shutdown: Shutdown,
    webhook_id: String,
) {
    if let Err(e) = deliver_due_to(&store, &client, &config, &shutdown, &webhook_id).await {
        tracing::warn!(webhook = %webhook_id, error = %e, "webhook delivery pass failed");
    }
}

/// Deliveries claimed by this node. The lease is stored on the store's clock ([`Store::clock`])
/// and timed here on this node's monotonic clock, so no node's wall clock decides when a claim
/// ends: a node whose clock runs ahead cannot take over a live claim.
struct Claim {
    due: Vec<DueDelivery>,
    /// The store's clock when the claim was made, and this node's instant then.
    clock: DateTime<Utc>,
    clock_read: Instant,
    /// The lease's end on this node's monotonic clock, counted from before the store's clock
    /// was read, so it comes no later than the stored lease's end.
    lease_end: Instant,
}

impl Claim {
    /// The store's clock now, as far as this node can tell (its clock at the claim plus the
    /// monotonic time since): the time stored with an attempt.
    fn now(&self) -> DateTime<Utc> {
        self.clock + chrono::Duration::from_std(self.clock_read.elapsed()).unwrap_or_default()
    }

    /// Whether an attempt of at most `timeout` still ends before the lease does.
    fn has_time_for(&self, timeout: Duration) -> bool {
        Instant::now() + timeout <= self.lease_end
    }
}

/// Claims up to [`CLAIM`] deliveries due to one endpoint for this node (see
/// [`outbox::claim_due`]): several nodes on one database never send the same message at the
/// same time.
async fn claim(store: &Store, webhook_id: &str, timeout: Duration) -> Result<Claim, StoreError> {
    let lease = timeout * CLAIM as u32 + Duration::from_secs(5);
    let started = Instant::now();
    let clock = store.clock().await?;
    let clock_read = Instant::now();
    let lease_until =
        clock + chrono::Duration::from_std(lease).unwrap_or(chrono::Duration::minutes(5));
    let mut tx = store.begin_write_rows().await?;
    let due = outbox::claim_due(
        &mut tx,
        webhook_id,
        &store::timestamp(clock),
        &store::timestamp(lease_until),
        CLAIM,
    )
    .await?;
    tx.commit().await?;
    Ok(Claim {
        due,
        clock,
        clock_read,
        lease_end: started + lease,
    })
}

/// One pass over one endpoint: its deliveries due now, oldest first, claimed a few at a time.
/// Returns how many attempts were made.
pub async fn deliver_due_to(
    store: &Store,
    client: &reqwest::Client,
    config: &WorkerConfig,
    shutdown: &Shutdown,
    webhook_id: &str,
) -> Result<usize, StoreError> {
    let mut n = 0;
    while n < PASS_LIMIT && !shutdown.is_requested() {
        let claim = claim(store, webhook_id, config.timeout).await?;
        let batch = &claim.due;
        if batch.is_empty() {
            break;
        }
        for (k, d) in batch.iter().enumerate() {
            if shutdown.is_requested() {
                give_back(store, &batch[k..], claim.now()).await?;
                return Ok(n);
            }
            // Not enough of the claim left for one more attempt (recording stalled, say): give
            // the rest back and claim afresh rather than send what another node may take over.
            if !claim.has_time_for(config.timeout) {
                give_back(store, &batch[k..], claim.now()).await?;
                break;
            }
            let started = claim.now();
            // signed with this node's time, which the receiver checks against its own
            let outcome = deliver(
                client,
                &d.url,
                &d.secret,
                &d.outbox_id,
                d.payload.as_bytes(),
                Utc::now(),
            )
            .await;
            record(store, d, &outcome, &config.retry, started).await?;
            n += 1;
            if outcome == DeliveryOutcome::Gone {
                // its other deliveries failed with it; the claimed ones are not sent
                return Ok(n);
            }
        }
    }
    Ok(n)
}

/// Gives back claimed deliveries not sent: due again at `now` (the store's clock), not when
/// their lease ends.
async fn give_back(
    store: &Store,
    unsent: &[DueDelivery],
    now: DateTime<Utc>,
) -> Result<(), StoreError> {
    let mut tx = store.begin_write_rows().await?;
    outbox::release(&mut tx, unsent, &store::timestamp(now)).await?;
    tx.commit().await?;
    Ok(())
}

/// The stored outcome of attempt number `attempts` made at `t` (the store's clock).
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
    let label = match (outcome, a.state) {
        (DeliveryOutcome::Delivered { .. }, _) => "ok",
        (_, "pending") => "retry",
        _ => "failed",
    };
    metrics::counter!("cliffwatch_webhook_deliveries_total", "outcome" => label).increment(1);
    let reason = a.error.as_deref().unwrap_or("");
    match label {
        // the first failure of a message is worth a line; its retries are not
        "retry" if a.attempts == 1 => tracing::warn!(
            webhook = %d.webhook_id, url = %crate::webhooks::loggable_origin(&d.url), message = %d.outbox_id, reason,
            "webhook delivery failed; retrying with backoff"
        ),
        "retry" => tracing::debug!(
            webhook = %d.webhook_id, message = %d.outbox_id, attempts = a.attempts, reason,
            "webhook delivery failed again"
        ),
        "failed" => tracing::error!(
            webhook = %d.webhook_id, url = %crate::webhooks::loggable_origin(&d.url), message = %d.outbox_id, attempts = a.attempts,
            reason, "webhook message given up: not delivered (GET /api/v1/webhooks counts it)"
        ),
        _ => {}
    }
    let mut tx = store.begin_write_rows().await?;
    if !outbox::record_attempt(&mut tx, d, &a).await? {
        tracing::warn!(webhook = %d.webhook_id, message = %d.outbox_id,
            "webhook attempt not recorded: its claim ran out and another node took it over");
    }
    if *outcome == DeliveryOutcome::Gone {
        tracing::error!(webhook = %d.webhook_id, url = %crate::webhooks::loggable_origin(&d.url),
            "410 Gone: endpoint disabled, its pending messages given up");
        outbox::endpoint_gone(&mut tx, &d.webhook_id).await?;
    }
    tx.commit().await?;
    Ok(())
}
