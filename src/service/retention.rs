//! What the store lets go: finished webhook deliveries (delivered or given up) once they are
//! older than `webhook_delivery_retention_days`. Pending deliveries are never deleted, and the
//! outbox messages stay as the alerts' event history. Run periodically by the daemon.

use std::time::Duration;

use chrono::{DateTime, Utc};

use crate::shutdown::Shutdown;
use crate::store::{self, outbox, Store, StoreError};

/// Deliveries deleted per transaction, so that a first pass over years of history holds the
/// write lock for milliseconds at a time, not for the whole deletion.
const BATCH: i64 = 1000;

/// How often the pass runs.
const EVERY: Duration = Duration::from_secs(3600);

/// Deletes every finished delivery whose last attempt is older than `retention` at `now`, in
/// transactions of [`BATCH`]. Returns how many went.
pub async fn prune_deliveries(
    store: &Store,
    retention: Duration,
    now: DateTime<Utc>,
) -> Result<u64, StoreError> {
    let keep = chrono::Duration::from_std(retention).unwrap_or(chrono::Duration::MAX);
    let Some(cut) = now.checked_sub_signed(keep) else {
        return Ok(0);
    };
    let cut = store::timestamp(cut);
    let mut pruned = 0;
    loop {
        let mut tx = store.begin_write_rows().await?;
        let n = outbox::prune_finished(&mut tx, &cut, BATCH).await?;
        tx.commit().await?;
        pruned += n;
        if n < BATCH as u64 {
            return Ok(pruned);
        }
    }
}

/// Runs [`prune_deliveries`] at start and every hour until shutdown. Any node may: a deletion
/// that another node made first deletes nothing.
pub async fn run(store: Store, retention: Duration, shutdown: Shutdown) {
    loop {
        match prune_deliveries(&store, retention, Utc::now()).await {
            Ok(0) => {}
            Ok(n) => {
                metrics::counter!("cliffwatch_webhook_deliveries_pruned_total").increment(n);
                tracing::info!(deliveries = n, "pruned finished webhook deliveries");
            }
            Err(e) => tracing::warn!(error = %e, "pruning finished webhook deliveries failed"),
        }
        if shutdown.sleep(EVERY).await {
            break;
        }
    }
    tracing::info!("webhook delivery retention stopped");
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
