//! What the store lets go, each after its own retention period (0 days: kept for ever):
//! - finished webhook deliveries (delivered or given up) older than
//!   `webhook_delivery_retention_days`. Pending deliveries are never deleted, and the outbox
//!   messages stay as the alerts' event history.
//! - the raw observations (image coordinates and residuals) of epochs observed more than
//!   `observation_retention_days` ago, the largest table of a long-running site. The epoch, its
//!   report, coordinates, covariances and displacements stay, so series, alerts and reference
//!   changes are unaffected; the epoch records when they went (`observations_pruned_at`).
//!
//! Run periodically by the daemon. (The watched directory's taken folders have their own
//! retention, [`super::watch_retention`].)

use std::time::Duration;

use chrono::{DateTime, Utc};

use crate::shutdown::Shutdown;
use crate::store::{self, epochs, outbox, Connection, Store, StoreError};

/// Deliveries deleted per transaction, so that a first pass over years of history holds the
/// write lock for milliseconds at a time, not for the whole deletion.
const BATCH: i64 = 1000;

/// Epochs whose observations are deleted per transaction (a few hundred rows each).
const EPOCH_BATCH: i64 = 50;

/// How often the pass runs.
const EVERY: Duration = Duration::from_secs(3600);

/// What is kept how long; `None`: for ever.
#[derive(Debug, Clone, Default)]
pub struct Retention {
    /// Finished webhook deliveries, after their last attempt.
    pub deliveries: Option<Duration>,
    /// Epochs' observations, after the epoch's observation time.
    pub observations: Option<Duration>,
}

impl Retention {
    /// The periods of the configuration's `webhook_delivery_retention_days` and
    /// `observation_retention_days` (0: none).
    pub fn from_config(config: &crate::config::Config) -> Retention {
        let days = |d: u64| (d > 0).then(|| Duration::from_secs(d.saturating_mul(86_400)));
        Retention {
            deliveries: days(config.webhook_delivery_retention_days),
            observations: days(config.observation_retention_days),
        }
    }

    /// Whether anything is ever deleted.
    pub fn any(&self) -> bool {
        self.deliveries.is_some() || self.observations.is_some()
    }
}

/// The store time `retention` before `now`; `None` when that is before the calendar's start
/// (nothing is old enough).
fn cut(retention: Duration, now: DateTime<Utc>) -> Option<String> {
    let keep = chrono::Duration::from_std(retention).unwrap_or(chrono::Duration::MAX);
    now.checked_sub_signed(keep).map(store::timestamp)
}

/// Rows the retention deletes in batches, each in a write transaction of its own.
enum Prunable<'a> {
    /// Finished deliveries whose last attempt was before `cut` (store time).
    Deliveries { cut: &'a str },
    /// The observations of epochs observed before `cut`, the epochs marked at `pruned_at`.
    Observations { cut: &'a str, pruned_at: &'a str },
}

impl Prunable<'_> {
    /// Most items one transaction deletes.
    fn batch(&self) -> i64 {
        match self {
            Prunable::Deliveries { .. } => BATCH,
            Prunable::Observations { .. } => EPOCH_BATCH,
        }
    }

    /// Deletes one batch in `tx`; returns how many items went.
    async fn delete_batch(&self, tx: &mut Connection) -> Result<u64, StoreError> {
        match *self {
            Prunable::Deliveries { cut } => outbox::prune_finished(tx, cut, BATCH).await,
            Prunable::Observations { cut, pruned_at } => {
                epochs::prune_observations(tx, cut, pruned_at, EPOCH_BATCH).await
            }
        }
    }

    /// Deletes every batch, one transaction each, until one holds fewer than
    /// [`Prunable::batch`]. Returns how many items went.
    async fn delete_all(&self, store: &Store) -> Result<u64, StoreError> {
        let mut pruned = 0;
        loop {
            let mut tx = store.begin_write_rows().await?;
            let n = self.delete_batch(&mut tx).await?;
            tx.commit().await?;
            pruned += n;
            if n < self.batch() as u64 {
                return Ok(pruned);
            }
        }
    }
}

/// Deletes every finished delivery whose last attempt is older than `retention` at `now`, in
/// transactions of [`BATCH`]. Returns how many went.
pub async fn prune_deliveries(
    store: &Store,
    retention: Duration,
    now: DateTime<Utc>,
) -> Result<u64, StoreError> {
    let Some(cut) = cut(retention, now) else {
        return Ok(0);
    };
    Prunable::Deliveries { cut: &cut }.delete_all(store).await
}

/// Deletes the observations of every epoch observed more than `retention` before `now`, marking
/// each epoch as pruned at `now`, in transactions of [`EPOCH_BATCH`] epochs. Returns how many
/// epochs lost theirs.
pub async fn prune_observations(
    store: &Store,
    retention: Duration,
    now: DateTime<Utc>,
) -> Result<u64, StoreError> {
    let Some(cut) = cut(retention, now) else {
        return Ok(0);
    };
    let pruned_at = store::timestamp(now);
    let what = Prunable::Observations {
        cut: &cut,
        pruned_at: &pruned_at,
    };
    what.delete_all(store).await
}

/// One pass of every retention in force, at the store's clock. The observations' pass runs on
/// one node at a time ([`Store::try_job_lock`]); the deliveries' on any (a deletion another node
/// made first deletes nothing).
async fn prune_once(store: &Store, retention: &Retention) {
    let now = match store.clock().await {
        Ok(now) => now,
        Err(e) => {
            tracing::warn!(error = %e, "retention: reading the store's clock failed");
            return;
        }
    };
    if let Some(keep) = retention.deliveries {
        let pass = prune_deliveries(store, keep, now).await;
        record(
            pass,
            "cliffwatch_webhook_deliveries_pruned_total",
            "finished webhook deliveries",
        );
    }
    if let Some(keep) = retention.observations {
        let pass = async {
            match store.try_job_lock("observation retention").await? {
                Some(_held) => prune_observations(store, keep, now).await,
                None => Ok(0),
            }
        };
        record(
            pass.await,
            "cliffwatch_epoch_observations_pruned_total",
            "the observations of old epochs",
        );
    }
}

/// Counts on `counter` and logs what one retention pass deleted (`what`), or why it failed.
fn record(pass: Result<u64, StoreError>, counter: &'static str, what: &str) {
    match pass {
        Ok(0) => {}
        Ok(n) => {
            metrics::counter!(counter).increment(n);
            tracing::info!(deleted = n, "retention: deleted {what}");
        }
        Err(e) => tracing::warn!(error = %e, "retention: deleting {what} failed"),
    }
}

/// Runs the retentions in force at start and every hour until shutdown.
pub async fn run(store: Store, retention: Retention, shutdown: Shutdown) {
    loop {
        prune_once(&store, &retention).await;
        if shutdown.sleep(EVERY).await {
            break;
        }
    }
    tracing::info!("retention stopped");
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::store::outbox::tests::{at, insert_message, store_with_endpoint_and_alert};
    use crate::store::outbox::{claim_due, queue_delivery, record_attempt, Attempt};

    /// With 90 days' retention, a delivery made 100 days ago goes and one made 10 days ago
    /// stays.
    #[tokio::test]
    async fn deliveries_older_than_the_retention_go() {
        let (_dir, store, webhook) = store_with_endpoint_and_alert().await;
        let day = 86_400;
        let now = DateTime::UNIX_EPOCH + chrono::Duration::seconds(1000 * day);
        let made = [("m_100_days", 900 * day), ("m_10_days", 990 * day)];
        let mut tx = store.begin_write_rows().await.unwrap();
        for (id, t) in made {
            insert_message(&mut tx, id, t).await;
            assert!(queue_delivery(&mut tx, id, &webhook, &at(t), None)
                .await
                .unwrap());
        }
        // each delivered at the time it was queued (one alert's deliveries are claimed one at a
        // time, in order)
        for _ in 0..made.len() {
            let due = claim_due(&mut tx, &webhook, &at(995 * day), &at(996 * day), 10)
                .await
                .unwrap();
            assert_eq!(due.len(), 1);
            let d = &due[0];
            let t = made.iter().find(|(id, _)| *id == d.outbox_id).unwrap().1;
            let attempt = Attempt {
                state: "delivered",
                attempts: 1,
                next_attempt_at: at(t),
                status: Some(200),
                error: None,
                delivered_at: Some(at(t)),
            };
            assert!(record_attempt(&mut tx, d, &attempt).await.unwrap());
        }
        tx.commit().await.unwrap();
        let retention = Duration::from_secs(90 * 86_400);
        assert_eq!(prune_deliveries(&store, retention, now).await.unwrap(), 1);
        assert_eq!(prune_deliveries(&store, retention, now).await.unwrap(), 0);
        // the one left is the 10 days' one: 11 days' retention keeps it, 9 days' does not
        let keep = |days: u64| Duration::from_secs(days * 86_400);
        assert_eq!(prune_deliveries(&store, keep(11), now).await.unwrap(), 0);
        assert_eq!(prune_deliveries(&store, keep(9), now).await.unwrap(), 1);
    }
}
