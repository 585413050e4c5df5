//! Endpoints of the configuration file across restarts: an edited endpoint (secret rotated,
//! level or format changed) keeps its id and its pending deliveries; one no longer configured
//! loses them; a new one is added.

use cliffwatch::store::webhooks::{list, replace_configured, NewWebhook};
use cliffwatch::store::{Store, StoreOptions};
use cliffwatch::webhooks::PayloadFormat;
use cliffwatch_core::analysis::AlertLevel;

const OLD: &str = "whsec_MfKQ9r8GKYqrTwjUPD8ILPZIo2LaLaSw";
const NEW: &str = "whsec_Y2xpZmZ3YXRjaC1hbS13ZWJob29rLXY0";

fn hook(url: &str, secret: &str, level: AlertLevel, format: PayloadFormat) -> NewWebhook {
    NewWebhook {
        url: url.into(),
        secret: secret.into(),
        min_level: Some(level),
        format,
    }
}

async fn configure(store: &Store, hooks: &[NewWebhook]) {
    let mut tx = store.begin_write().await.unwrap();
    replace_configured(&mut tx, hooks).await.unwrap();
    tx.commit().await.unwrap();
}

async fn id_of(store: &Store, url: &str) -> Option<String> {
    list(store.reader())
        .await
        .unwrap()
        .into_iter()
        .find(|w| w.url == url)
        .map(|w| w.id)
}

async fn pending_of(store: &Store, id: &str) -> i64 {
    sqlx::query_scalar(
        "SELECT COUNT(*) FROM webhook_deliveries WHERE webhook_id = $1 AND state = 'pending'",
    )
    .bind(id)
    .fetch_one(store.reader())
    .await
    .unwrap()
}

#[tokio::test]
async fn edited_endpoints_keep_their_pending_deliveries() {
    let dir = tempfile::tempdir().unwrap();
    let store = Store::open(&dir.path().join("cw.db"), &StoreOptions::default())
        .await
        .unwrap();
    let (a, b, c) = (
        "http://a.example/h",
        "http://b.example/h",
        "http://c.example/h",
    );
    configure(
        &store,
        &[
            hook(a, OLD, AlertLevel::Warning, PayloadFormat::Standard),
            hook(b, OLD, AlertLevel::Warning, PayloadFormat::Standard),
        ],
    )
    .await;
    let (id_a, id_b) = (
        id_of(&store, a).await.unwrap(),
        id_of(&store, b).await.unwrap(),
    );
    // One event waiting for both receivers (down at the time).
    let mut tx = store.begin_write().await.unwrap();
    sqlx::query(
        "INSERT INTO webhook_outbox (id, event_type, alert_id, level, payload, created_at) \
         VALUES ('o1', 'alert.raised', NULL, 'alarm', '{}', '2026-11-26T00:00:00Z')",
    )
    .execute(&mut *tx)
    .await
    .unwrap();
    for id in [&id_a, &id_b] {
        sqlx::query(
            "INSERT INTO webhook_deliveries (outbox_id, webhook_id, state, next_attempt_at) \
             VALUES ('o1', $1, 'pending', '2026-11-26T00:00:00Z')",
        )
        .bind(id)
        .execute(&mut *tx)
        .await
        .unwrap();
    }
    tx.commit().await.unwrap();

    // Restart with a's secret rotated, its level and format changed, b removed, c added.
    configure(
        &store,
        &[
            hook(
                a,
                NEW,
                AlertLevel::Alarm,
                PayloadFormat::AlertmanagerWebhook,
            ),
            hook(c, OLD, AlertLevel::Watch, PayloadFormat::Standard),
        ],
    )
    .await;
    assert_eq!(id_of(&store, a).await.as_deref(), Some(id_a.as_str()));
    assert_eq!(pending_of(&store, &id_a).await, 1, "a keeps its delivery");
    let secret: String = sqlx::query_scalar("SELECT secret FROM webhooks WHERE id = $1")
        .bind(&id_a)
        .fetch_one(store.reader())
        .await
        .unwrap();
    assert_eq!(
        secret, NEW,
        "the next attempt signs with the rotated secret"
    );
    let listed = list(store.reader()).await.unwrap();
    let shown = listed.iter().find(|w| w.id == id_a).unwrap();
    assert_eq!(shown.min_level, AlertLevel::Alarm);
    assert_eq!(
        shown.format,
        cliffwatch::webhooks::PayloadFormat::AlertmanagerWebhook
    );
    assert_eq!(id_of(&store, b).await, None);
    assert_eq!(
        pending_of(&store, &id_b).await,
        0,
        "b's deliveries go with it"
    );
    assert!(id_of(&store, c).await.is_some());
    assert_eq!(listed.len(), 2);
    store.close().await;
}
