//! What the store lets go, each after its own retention period (0 days: kept for ever):
//! - finished webhook deliveries (delivered or given up) older than
//!   `webhook_delivery_retention_days`. Pending deliveries are never deleted, and the outbox
//!   messages stay as the alerts' event history.
//! - the raw observations (image coordinates and residuals) of epochs observed more than
//!   `observation_retention_days` ago, the largest table of a long-running site. The epoch, its
//!   report, coordinates, covariances and displacements stay, so series, alerts and reference
//!   changes are unaffected; the epoch records when they went (`observations_pruned_at`).
//! - the folders the watched directory took (`<site>/.done/<folder>`, the images) last written
//!   more than `watch_done_retention_days` ago. `.failed/` folders stay for staff to look at;
//!   the epoch pages then draw the detections without the image.
//!
//! Run periodically by the daemon.

use std::path::{Path, PathBuf};
use std::time::{Duration, SystemTime};

use chrono::{DateTime, Utc};
use sqlx::AnyConnection;

use crate::shutdown::Shutdown;
use crate::store::{self, epochs, outbox, Store, StoreError};
use crate::watch::folders;

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
    /// The watched directory's taken folders (`<site>/.done/<folder>`), after they were last
    /// written, with the watched directory.
    pub done_folders: Option<(Duration, PathBuf)>,
}

impl Retention {
    /// The periods of the configuration's `webhook_delivery_retention_days`,
    /// `observation_retention_days` and `watch_done_retention_days` (0: none; the last only with
    /// a `watch_dir`).
    pub fn from_config(config: &crate::config::Config) -> Retention {
        let days = |d: u64| (d > 0).then(|| Duration::from_secs(d.saturating_mul(86_400)));
        Retention {
            deliveries: days(config.webhook_delivery_retention_days),
            observations: days(config.observation_retention_days),
            done_folders: days(config.watch_done_retention_days).zip(config.watch_dir.clone()),
        }
    }

    /// Whether anything is ever deleted.
    pub fn any(&self) -> bool {
        self.deliveries.is_some() || self.observations.is_some() || self.done_folders.is_some()
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
    async fn delete_batch(&self, tx: &mut AnyConnection) -> Result<u64, StoreError> {
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

/// Deletes every taken folder of the watched directory `dir` last written more than `retention`
/// before `now` ([`folders::done_folders_before`]). Returns how many went; a folder that cannot
/// be deleted is logged and left for the next pass, one already gone (another node) is skipped.
pub fn prune_done_folders(dir: &Path, retention: Duration, now: SystemTime) -> usize {
    let Some(cut) = now.checked_sub(retention) else {
        return 0;
    };
    let mut pruned = 0;
    for folder in folders::done_folders_before(dir, cut) {
        match std::fs::remove_dir_all(&folder) {
            Ok(()) => pruned += 1,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => {
                tracing::warn!(folder = %folder.display(), error = %e, "deleting a taken folder failed")
            }
        }
    }
    pruned
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
    if let Some((keep, dir)) = retention.done_folders.clone() {
        let pass = async {
            let Some(_held) = store.try_job_lock("watch retention").await? else {
                return Ok(0);
            };
            tokio::task::spawn_blocking(move || prune_done_folders(&dir, keep, SystemTime::now()))
                .await
                .map(|n| n as u64)
                .map_err(|e| StoreError::Io(std::io::Error::other(e)))
        };
        record(
            pass.await,
            "cliffwatch_watch_folders_pruned_total",
            "old taken folders of the watched directory",
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
    use crate::store::outbox::queue_delivery;
    use crate::store::outbox::tests::{at, insert_message, store_with_endpoint_and_alert};

    /// With 90 days' retention, a delivery made 100 days ago goes and one made 10 days ago
    /// stays.
    #[tokio::test]
    async fn deliveries_older_than_the_retention_go() {
        let (_dir, store, webhook) = store_with_endpoint_and_alert().await;
        let day = 86_400;
        let now = DateTime::UNIX_EPOCH + chrono::Duration::seconds(1000 * day);
        let mut tx = store.begin_write_rows().await.unwrap();
        for (id, t) in [("m_100_days", 900 * day), ("m_10_days", 990 * day)] {
            insert_message(&mut tx, id, t).await;
            assert!(queue_delivery(&mut tx, id, &webhook, &at(t), None)
                .await
                .unwrap());
        }
        sqlx::query("UPDATE webhook_deliveries SET state = 'delivered'")
            .execute(&mut *tx)
            .await
            .unwrap();
        tx.commit().await.unwrap();
        let retention = Duration::from_secs(90 * 86_400);
        assert_eq!(prune_deliveries(&store, retention, now).await.unwrap(), 1);
        assert_eq!(prune_deliveries(&store, retention, now).await.unwrap(), 0);
        let left: Vec<String> = sqlx::query_scalar("SELECT outbox_id FROM webhook_deliveries")
            .fetch_all(store.reader())
            .await
            .unwrap();
        assert_eq!(left, ["m_10_days"]);
    }
}
