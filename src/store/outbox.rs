//! The webhook outbox: one message per alert event (`webhook_outbox`, its id the `webhook-id`
//! of every retry) and one delivery per endpoint that takes it (`webhook_deliveries`, with its
//! attempts, next attempt and outcome). Written in the transaction of the event; the delivery
//! worker reads what is due and records each attempt in its own transaction.

use sqlx::{AnyConnection, AnyExecutor, FromRow};

use super::StoreError;

/// One outbox message.
#[derive(Debug, Clone)]
pub struct OutboxMessage<'a> {
    /// Message id (`webhook-id`), derived from the event.
    pub id: &'a str,
    /// `alert.raised`, `alert.escalated`, …
    pub event_type: &'a str,
    /// The alert's id.
    pub alert_id: &'a str,
    /// The alert's level after the event.
    pub level: &'a str,
    /// The contract body (JSON).
    pub payload: &'a str,
    /// When it was written (store timestamp).
    pub created_at: &'a str,
    /// The epoch whose analysis caused the event, if one did.
    pub epoch: Option<i64>,
}

/// True when message `id` is in the outbox already (an event written twice is sent once).
pub async fn contains(db: &mut AnyConnection, id: &str) -> Result<bool, StoreError> {
    let found: Option<String> = sqlx::query_scalar("SELECT id FROM webhook_outbox WHERE id = $1")
        .bind(id)
        .fetch_optional(&mut *db)
        .await?;
    Ok(found.is_some())
}

/// The time of the latest message of alert `alert_id` (store timestamp), if it has one.
pub async fn latest_of_alert(
    db: &mut AnyConnection,
    alert_id: &str,
) -> Result<Option<String>, StoreError> {
    Ok(
        sqlx::query_scalar("SELECT MAX(created_at) FROM webhook_outbox WHERE alert_id = $1")
            .bind(alert_id)
            .fetch_one(&mut *db)
            .await?,
    )
}

/// Adds a message to the outbox.
pub async fn insert(db: &mut AnyConnection, m: &OutboxMessage<'_>) -> Result<(), StoreError> {
    sqlx::query(
        "INSERT INTO webhook_outbox (id, event_type, alert_id, level, payload, created_at, epoch_id) \
         VALUES ($1, $2, $3, $4, $5, $6, $7)",
    )
    .bind(m.id)
    .bind(m.event_type)
    .bind(m.alert_id)
    .bind(m.level)
    .bind(m.payload)
    .bind(m.created_at)
    .bind(m.epoch)
    .execute(&mut *db)
    .await?;
    Ok(())
}

/// Queues message `outbox_id` for endpoint `webhook_id`, due at `at` (store timestamp), with
/// the endpoint's own body when it is not the contract's (`None`: the outbox's body). Only while
/// the endpoint is enabled: `Ok(false)`, and nothing queued, once a 410 has disabled it, even
/// when the caller read it as enabled earlier in its transaction. PostgreSQL: the endpoint's row
/// is read `FOR SHARE`, so an [`endpoint_gone`] running at the same time either comes first
/// (nothing queued) or waits for this transaction and then fails what it queued.
pub async fn queue_delivery(
    db: &mut AnyConnection,
    outbox_id: &str,
    webhook_id: &str,
    at: &str,
    payload: Option<&str>,
) -> Result<bool, StoreError> {
    const QUEUE: &str =
        "INSERT INTO webhook_deliveries (outbox_id, webhook_id, state, next_attempt_at, payload) \
         SELECT $1, id, 'pending', $3, $4 FROM webhooks WHERE id = $2 AND enabled = TRUE";
    const QUEUE_LOCKED: &str = concat!(
        "INSERT INTO webhook_deliveries (outbox_id, webhook_id, state, next_attempt_at, payload) \
         SELECT $1, id, 'pending', $3, $4 FROM webhooks WHERE id = $2 AND enabled = TRUE",
        " FOR SHARE"
    );
    let sql = if super::is_postgres(db) {
        QUEUE_LOCKED
    } else {
        QUEUE
    };
    let done = sqlx::query(sql)
        .bind(outbox_id)
        .bind(webhook_id)
        .bind(at)
        .bind(payload)
        .execute(&mut *db)
        .await?;
    Ok(done.rows_affected() == 1)
}

/// A delivery that is due, with what its POST needs.
/// No `Debug`: it holds the signing secret, which must never reach a log.
#[derive(Clone, FromRow)]
pub struct DueDelivery {
    /// The message id (`webhook-id`).
    pub outbox_id: String,
    /// The endpoint's id.
    pub webhook_id: String,
    /// Attempts made so far.
    pub attempts: i64,
    /// The body to send: the endpoint's own, else the contract body.
    pub payload: String,
    /// The endpoint's URL.
    pub url: String,
    /// The endpoint's signing secret.
    pub secret: String,
    /// Until when this node holds the claim (store timestamp; set by [`claim_due`]): the fence
    /// of [`record_attempt`] and [`release`].
    #[sqlx(skip)]
    pub lease_until: String,
}

/// Which deliveries are due at `$1`: pending, to enabled endpoints, and each only once every
/// earlier message of its alert to the same endpoint is no longer pending, so that an endpoint
/// sees each alert's events in the order they happened whatever the retries in between
/// (`raised` before `escalated`). Earlier is by `created_at`, then id: the writer keeps each
/// alert's `created_at` increasing whatever the nodes' clocks (`alert_outcome::message_time`),
/// and the messages of one transaction are a microsecond apart. A macro, so that every query
/// built on it is a constant.
macro_rules! due_from {
    () => {
        " FROM webhook_deliveries d JOIN webhook_outbox o ON o.id = d.outbox_id \
     JOIN webhooks w ON w.id = d.webhook_id \
     WHERE d.state = 'pending' AND d.next_attempt_at <= $1 AND w.enabled = TRUE \
     AND NOT EXISTS (SELECT 1 FROM webhook_deliveries d2 JOIN webhook_outbox o2 ON o2.id = d2.outbox_id \
     WHERE d2.webhook_id = d.webhook_id AND d2.state = 'pending' AND o2.alert_id = o.alert_id \
     AND (o2.created_at < o.created_at OR (o2.created_at = o.created_at AND o2.id < o.id)))"
    };
}

/// What a due delivery's POST needs.
macro_rules! due_columns {
    () => {
        "SELECT d.outbox_id, d.webhook_id, d.attempts, COALESCE(d.payload, o.payload) AS payload, \
     w.url, w.secret"
    };
}

/// The deliveries due at `$1` to endpoint `$3`, oldest first, at most `$2`.
macro_rules! due_to {
    () => {
        concat!(
            due_columns!(),
            due_from!(),
            " AND d.webhook_id = $3 ORDER BY d.next_attempt_at, o.created_at, d.outbox_id LIMIT $2"
        )
    };
}

/// The endpoints with a delivery due at `$1`.
const DUE_ENDPOINTS: &str = concat!(
    "SELECT DISTINCT d.webhook_id",
    due_from!(),
    " ORDER BY d.webhook_id"
);

/// The deliveries due at `$1` to endpoint `$3`, oldest first, at most `$2`.
const DUE_TO: &str = due_to!();

/// [`DUE_TO`], the rows locked for this transaction and skipped by others (PostgreSQL).
const CLAIM_DUE_TO: &str = concat!(due_to!(), " FOR UPDATE OF d SKIP LOCKED");

/// The endpoints that have a delivery due at `now` (store timestamp).
pub async fn due_endpoints(db: impl AnyExecutor<'_>, now: &str) -> Result<Vec<String>, StoreError> {
    Ok(sqlx::query_scalar(DUE_ENDPOINTS)
        .bind(now)
        .fetch_all(db)
        .await?)
}

/// Claims at most `limit` deliveries due at `now` to endpoint `webhook_id` for this node
/// (oldest first, each alert's in order, see [`due_from`]): their next attempt moves to
/// `lease_until` (store timestamps), so no other node (or pass) picks them while this one sends
/// them; recording the attempt sets the real next attempt. A node that dies holding a claim
/// leaves it to be retried when the lease ends (at least once). PostgreSQL: the rows are read
/// `FOR UPDATE SKIP LOCKED`, so nodes claiming at once get different rows. Call in a write
/// transaction ([`crate::store::Store::begin_write_rows`]).
pub async fn claim_due(
    db: &mut AnyConnection,
    webhook_id: &str,
    now: &str,
    lease_until: &str,
    limit: i64,
) -> Result<Vec<DueDelivery>, StoreError> {
    let sql = if super::is_postgres(db) {
        CLAIM_DUE_TO
    } else {
        DUE_TO
    };
    let mut due: Vec<DueDelivery> = sqlx::query_as(sql)
        .bind(now)
        .bind(limit)
        .bind(webhook_id)
        .fetch_all(&mut *db)
        .await?;
    for d in &mut due {
        set_next_attempt(db, d, lease_until, None).await?;
        d.lease_until = lease_until.to_string();
    }
    Ok(due)
}

/// Moves the next attempt of pending delivery `d` to `at` (store timestamp); with `held`, only
/// while `d` is still held under that lease (see [`release`]).
async fn set_next_attempt(
    db: &mut AnyConnection,
    d: &DueDelivery,
    at: &str,
    held: Option<&str>,
) -> Result<(), StoreError> {
    const PENDING: &str = "UPDATE webhook_deliveries SET next_attempt_at = $1 \
         WHERE outbox_id = $2 AND webhook_id = $3 AND state = 'pending'";
    const HELD: &str = "UPDATE webhook_deliveries SET next_attempt_at = $1 \
         WHERE outbox_id = $2 AND webhook_id = $3 AND state = 'pending' AND next_attempt_at = $4";
    let query = sqlx::query(if held.is_some() { HELD } else { PENDING })
        .bind(at)
        .bind(&d.outbox_id)
        .bind(&d.webhook_id);
    match held {
        Some(lease) => query.bind(lease).execute(&mut *db).await?,
        None => query.execute(&mut *db).await?,
    };
    Ok(())
}

/// Gives back claimed deliveries that were not attempted: due again at `now` (store timestamp).
/// A delivery whose lease ran out and was claimed by another node is left to that node.
pub async fn release(
    db: &mut AnyConnection,
    claimed: &[DueDelivery],
    now: &str,
) -> Result<(), StoreError> {
    for d in claimed {
        set_next_attempt(db, d, now, Some(&d.lease_until)).await?;
    }
    Ok(())
}

/// The outcome of one delivery attempt as stored.
#[derive(Debug, Clone, PartialEq)]
pub struct Attempt {
    /// `pending` (to be retried), `delivered` or `failed`.
    pub state: &'static str,
    /// Attempts made, this one included.
    pub attempts: i64,
    /// When to try next (store timestamp; the attempt's time when no retry follows).
    pub next_attempt_at: String,
    /// HTTP status of the answer, if one came.
    pub status: Option<i64>,
    /// Why it did not succeed.
    pub error: Option<String>,
    /// When it was delivered.
    pub delivered_at: Option<String>,
}

/// Records an attempt at the claimed delivery `d`. Fenced by the claim's lease: `Ok(false)`, and
/// nothing written, when the lease ran out and another node claimed the delivery since (its
/// outcome is the one that counts), or the delivery is no longer pending.
pub async fn record_attempt(
    db: &mut AnyConnection,
    d: &DueDelivery,
    a: &Attempt,
) -> Result<bool, StoreError> {
    let done = sqlx::query(
        "UPDATE webhook_deliveries SET state = $1, attempts = $2, next_attempt_at = $3, \
         last_status = $4, last_error = $5, delivered_at = $6 WHERE outbox_id = $7 AND webhook_id = $8 \
         AND state = 'pending' AND next_attempt_at = $9",
    )
    .bind(a.state)
    .bind(a.attempts)
    .bind(&a.next_attempt_at)
    .bind(a.status)
    .bind(&a.error)
    .bind(&a.delivered_at)
    .bind(&d.outbox_id)
    .bind(&d.webhook_id)
    .bind(&d.lease_until)
    .execute(&mut *db)
    .await?;
    Ok(done.rows_affected() == 1)
}

/// An endpoint answered 410 Gone: it is disabled and its pending deliveries fail.
pub async fn endpoint_gone(db: &mut AnyConnection, webhook_id: &str) -> Result<(), StoreError> {
    sqlx::query("UPDATE webhooks SET enabled = FALSE WHERE id = $1")
        .bind(webhook_id)
        .execute(&mut *db)
        .await?;
    sqlx::query(
        "UPDATE webhook_deliveries SET state = 'failed', last_error = 'endpoint gone (410)' \
         WHERE webhook_id = $1 AND state = 'pending'",
    )
    .bind(webhook_id)
    .execute(&mut *db)
    .await?;
    Ok(())
}

/// Deletes at most `limit` deliveries that finished (delivered or given up) before `before`
/// (store format); pending ones are kept however old. Returns how many went. Their outbox
/// messages stay: they are the alerts' event history (the CAP feed reads their levels).
pub async fn prune_finished(
    db: &mut AnyConnection,
    before: &str,
    limit: i64,
) -> Result<u64, StoreError> {
    // A finished delivery's next_attempt_at is the time of its last attempt (or, for one failed
    // by a 410, of its last scheduled retry): the index on (state, next_attempt_at) finds them.
    let done = sqlx::query(
        "DELETE FROM webhook_deliveries WHERE (outbox_id, webhook_id) IN \
         (SELECT outbox_id, webhook_id FROM webhook_deliveries \
          WHERE state IN ('delivered', 'failed') AND next_attempt_at < $1 LIMIT $2)",
    )
    .bind(before)
    .bind(limit)
    .execute(&mut *db)
    .await?;
    Ok(done.rows_affected())
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::store::webhooks::{self, NewWebhook, WebhookSource};
    use crate::store::{Store, StoreOptions};

    /// The store timestamp `secs` seconds after 1970.
    pub(crate) fn at(secs: i64) -> String {
        crate::store::timestamp(chrono::DateTime::UNIX_EPOCH + chrono::Duration::seconds(secs))
    }

    /// A store holding one endpoint (its id returned) and alert `a` of site `s`.
    pub(crate) async fn store_with_endpoint_and_alert() -> (tempfile::TempDir, Store, String) {
        let dir = tempfile::tempdir().unwrap();
        let store = Store::open(&dir.path().join("t.db"), &StoreOptions::default())
            .await
            .unwrap();
        let mut tx = store.begin_write_rows().await.unwrap();
        let hook = NewWebhook {
            url: "http://127.0.0.1:9/hook".into(),
            secret: "whsec_c2VjcmV0".into(),
            min_level: None,
            format: Default::default(),
        };
        let webhook = webhooks::insert(&mut tx, &hook, WebhookSource::Api)
            .await
            .unwrap();
        for sql in [
            "INSERT INTO sites (id, name, created_at) VALUES ('s', 's', '1970-01-01T00:00:00Z')",
            "INSERT INTO alerts (id, site_id, level, rule, message, state, raised_at, updated_at) \
             VALUES ('a', 's', 'warning', 'displacement_mm', 'm', 'open', '1970-01-01T00:00:00Z', \
             '1970-01-01T00:00:00Z')",
        ] {
            sqlx::query(sql).execute(&mut *tx).await.unwrap();
        }
        tx.commit().await.unwrap();
        (dir, store, webhook)
    }

    /// Outbox message `id` of alert `a`, created `t` seconds after 1970.
    pub(crate) async fn insert_message(tx: &mut AnyConnection, id: &str, t: i64) {
        let message = OutboxMessage {
            id,
            event_type: "alert.raised",
            alert_id: "a",
            level: "warning",
            payload: "{}",
            created_at: &at(t),
            epoch: None,
        };
        insert(tx, &message).await.unwrap();
    }

    /// A node whose claim ran out while another node took the delivery over cannot overwrite the
    /// other's outcome, nor give the delivery back.
    #[tokio::test]
    async fn an_expired_claim_neither_records_nor_releases() {
        let (_dir, store, webhook) = store_with_endpoint_and_alert().await;
        let mut tx = store.begin_write_rows().await.unwrap();
        insert_message(&mut tx, "msg_1", 0).await;
        assert!(queue_delivery(&mut tx, "msg_1", &webhook, &at(0), None)
            .await
            .unwrap());
        tx.commit().await.unwrap();

        let claim = |now: i64, lease: i64| {
            let store = store.clone();
            let webhook = webhook.clone();
            async move {
                let mut tx = store.begin_write_rows().await.unwrap();
                let due = claim_due(&mut tx, &webhook, &at(now), &at(lease), 4)
                    .await
                    .unwrap();
                tx.commit().await.unwrap();
                due
            }
        };
        let a = claim(1, 10).await;
        assert_eq!(a.len(), 1);
        assert!(
            claim(5, 15).await.is_empty(),
            "claimed while A's lease runs"
        );
        let b = claim(20, 30).await;
        assert_eq!(
            b.len(),
            1,
            "A's lease ran out at 10: B takes the delivery over"
        );

        let outcome = |state: &'static str, next: i64| Attempt {
            state,
            attempts: 1,
            next_attempt_at: at(next),
            status: Some(200),
            error: None,
            delivered_at: None,
        };
        let mut tx = store.begin_write_rows().await.unwrap();
        assert!(record_attempt(&mut tx, &b[0], &outcome("delivered", 21))
            .await
            .unwrap());
        assert!(!record_attempt(&mut tx, &a[0], &outcome("pending", 60))
            .await
            .unwrap());
        release(&mut tx, &a, &at(22)).await.unwrap();
        tx.commit().await.unwrap();
        let (state, next): (String, String) = sqlx::query_as(
            "SELECT state, next_attempt_at FROM webhook_deliveries WHERE outbox_id = 'msg_1'",
        )
        .fetch_one(store.reader())
        .await
        .unwrap();
        assert_eq!((state.as_str(), next), ("delivered", at(21)));
        assert!(
            claim(100, 110).await.is_empty(),
            "delivered once, not again"
        );
    }

    /// An endpoint disabled by a 410 gets nothing more queued, even for a transaction that read
    /// it as enabled: no delivery is left pending that the worker would never attempt.
    #[tokio::test]
    async fn nothing_is_queued_for_a_gone_endpoint() {
        let (_dir, store, webhook) = store_with_endpoint_and_alert().await;
        let mut tx = store.begin_write_rows().await.unwrap();
        for id in ["msg_1", "msg_2"] {
            insert_message(&mut tx, id, 0).await;
        }
        assert!(queue_delivery(&mut tx, "msg_1", &webhook, &at(0), None)
            .await
            .unwrap());
        endpoint_gone(&mut tx, &webhook).await.unwrap();
        assert!(!queue_delivery(&mut tx, "msg_2", &webhook, &at(0), None)
            .await
            .unwrap());
        tx.commit().await.unwrap();
        let states: Vec<(String, String)> =
            sqlx::query_as("SELECT outbox_id, state FROM webhook_deliveries ORDER BY outbox_id")
                .fetch_all(store.reader())
                .await
                .unwrap();
        assert_eq!(states, [("msg_1".to_string(), "failed".to_string())]);
        assert_eq!(webhooks::pending(store.reader()).await.unwrap(), 0);
    }

    /// Finished deliveries older than the cut go, in batches; pending ones stay however old, and
    /// so does every outbox message.
    #[tokio::test]
    async fn only_finished_deliveries_before_the_cut_are_pruned() {
        let (_dir, store, webhook) = store_with_endpoint_and_alert().await;
        let mut tx = store.begin_write_rows().await.unwrap();
        // (message, state, time of its last attempt or next one)
        let rows = [
            ("old_delivered_1", "delivered", 10),
            ("old_delivered_2", "delivered", 20),
            ("old_failed", "failed", 30),
            ("old_pending", "pending", 40),
            ("new_delivered", "delivered", 200),
            ("new_failed", "failed", 300),
        ];
        for (id, state, t) in rows {
            insert_message(&mut tx, id, 0).await;
            assert!(queue_delivery(&mut tx, id, &webhook, &at(t), None)
                .await
                .unwrap());
            sqlx::query("UPDATE webhook_deliveries SET state = $1 WHERE outbox_id = $2")
                .bind(state)
                .bind(id)
                .execute(&mut *tx)
                .await
                .unwrap();
        }
        // Two per batch: the three old finished ones take two batches.
        assert_eq!(prune_finished(&mut tx, &at(100), 2).await.unwrap(), 2);
        assert_eq!(prune_finished(&mut tx, &at(100), 2).await.unwrap(), 1);
        assert_eq!(prune_finished(&mut tx, &at(100), 2).await.unwrap(), 0);
        tx.commit().await.unwrap();
        let left: Vec<String> =
            sqlx::query_scalar("SELECT outbox_id FROM webhook_deliveries ORDER BY outbox_id")
                .fetch_all(store.reader())
                .await
                .unwrap();
        assert_eq!(left, ["new_delivered", "new_failed", "old_pending"]);
        let messages: i64 = sqlx::query_scalar("SELECT COUNT(*) FROM webhook_outbox")
            .fetch_one(store.reader())
            .await
            .unwrap();
        assert_eq!(messages, 6);
    }
}
