//! Delivery order and isolation through the daemon: an endpoint sees each alert's events in the
//! order they happened although their first attempts failed, an endpoint that hangs delays no
//! other endpoint, and `GET /api/v1/webhooks` shows what is still pending and why.

use crate::support;

use std::collections::{BTreeMap, BTreeSet};
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use serde_json::{json, Value};
use support::alerts::{
    create_site, day, mark_stable, outbox_events, upload_new, write_config, Daemon, Receiver,
    Scene, SECRET,
};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn each_alert_arrives_in_order_and_a_hanging_endpoint_delays_no_other() {
    let dir = tempfile::tempdir().unwrap();
    // The healthy endpoint refuses its first 24 requests (503): the 8 `raised` messages are
    // still being retried when the next epoch escalates the same alerts.
    let healthy = Receiver::start(24).await;
    let hanging = Receiver::start(0).await;
    hanging.hang.store(true, Ordering::SeqCst);
    let config = write_config(
        dir.path(),
        &format!(
            "[[webhooks]]\nurl = \"{}\"\nsecret = \"{SECRET}\"\nmin_level = \"watch\"\n\
             [[webhooks]]\nurl = \"{}\"\nsecret = \"{SECRET}\"\nmin_level = \"watch\"\n",
            healthy.url, hanging.url
        ),
    );
    let data = dir.path().join("data");
    let d = Daemon::start(&data, &config).await;
    let site = "ordered";
    create_site(
        &d,
        site,
        json!([{"level": "watch", "metric": "displacement_mm", "above": 5.0},
               {"level": "warning", "metric": "displacement_mm", "above": 10.0}]),
    )
    .await;
    let scene = Scene { n: 16, stable: 8 };
    mark_stable(&d, site, &scene).await;
    // The block: 0, 10 mm (watch raised), 20 mm (escalated to warning), 20 mm (nothing new),
    // one epoch after another. Each upload answer lists the alerts that epoch raised or
    // escalated, not those it only kept active.
    for (k, block_mm, listed) in [(0, 0.0, 0), (1, 10.0, 8), (2, 20.0, 8), (3, 20.0, 0)] {
        let summary = upload_new(&d, site, &scene.epoch(&day(k), 900 + k as u64, block_mm)).await;
        let alerts = summary["alerts"].as_array().unwrap();
        assert_eq!(alerts.len(), listed, "epoch {k}: {alerts:?}");
        let (_, again) = d
            .get(&format!("/api/v1/sites/{site}/epochs/{}", summary["id"]))
            .await;
        assert_eq!(
            again["alerts"].as_array().unwrap().len(),
            listed,
            "epoch {k}"
        );
    }
    let (_, active) = d
        .get(&format!("/api/v1/alerts?site={site}&state=open"))
        .await;
    assert_eq!(active["items"].as_array().unwrap().len(), 8, "{active}");
    let uploaded = Instant::now();
    let events = outbox_events(&data).await;
    let expected: BTreeSet<String> = events.iter().map(|(id, _, _)| id.clone()).collect();
    let kinds: BTreeMap<&str, usize> = events.iter().fold(BTreeMap::new(), |mut m, e| {
        *m.entry(e.1.as_str()).or_default() += 1;
        m
    });
    assert_eq!(
        kinds,
        BTreeMap::from([("alert.escalated", 8), ("alert.raised", 8)]),
        "{events:?}"
    );
    // Every message reaches the healthy endpoint while the other one hangs: 16 messages to it,
    // each held 5 s by the POST timeout, would take 80 s if the endpoints were served in turn.
    let deadline = uploaded + Duration::from_secs(30);
    loop {
        let got: BTreeSet<String> = healthy.accepted().into_keys().collect();
        if got == expected {
            break;
        }
        assert!(
            Instant::now() < deadline,
            "healthy endpoint has {} of {} messages 30 s after the uploads",
            got.len(),
            expected.len()
        );
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    // Each alert's `escalated` was never attempted before its `raised` was accepted.
    let log = healthy.log.lock().unwrap().clone();
    assert!(log.iter().filter(|r| !r.accepted).count() >= 24);
    let mut raised_done: BTreeSet<String> = BTreeSet::new();
    for r in &log {
        let alert = r.body["data"]["alert_id"].as_str().unwrap().to_string();
        match r.body["type"].as_str().unwrap() {
            "alert.raised" if r.accepted => {
                raised_done.insert(alert);
            }
            "alert.escalated" => assert!(
                raised_done.contains(&alert),
                "escalated sent before raised was delivered: {alert}"
            ),
            _ => {}
        }
    }
    assert_eq!(healthy.bad_signatures.load(Ordering::SeqCst), 0);
    // The API says which endpoint is behind, and why.
    let (s, hooks) = d.get("/api/v1/webhooks").await;
    assert_eq!(s, 200, "{hooks}");
    let by_url: BTreeMap<&str, &Value> = hooks["items"]
        .as_array()
        .unwrap()
        .iter()
        .map(|h| (h["url"].as_str().unwrap(), h))
        .collect();
    let h = by_url[healthy.url.as_str()];
    assert_eq!(
        (
            h["pending_deliveries"].as_i64(),
            h["failed_deliveries"].as_i64()
        ),
        (Some(0), Some(0)),
        "{h}"
    );
    assert_eq!(h["enabled"], true, "{h}");
    let slow = by_url[hanging.url.as_str()];
    assert!(slow["pending_deliveries"].as_i64().unwrap() > 0, "{slow}");
    assert_eq!(slow["failed_deliveries"].as_i64(), Some(0), "{slow}");
}

/// A node whose clock runs an hour ahead wrote the alerts' `raised`; the `escalated` written
/// afterwards (by a node with the right time) still comes after it in the outbox, the order the
/// worker delivers each alert's events in.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_alert_event_follows_the_one_before_whatever_the_clocks() {
    use sqlx::ConnectOptions;
    let dir = tempfile::tempdir().unwrap();
    let config = write_config(dir.path(), "");
    let data = dir.path().join("data");
    let d = Daemon::start(&data, &config).await;
    let site = "skewed";
    create_site(
        &d,
        site,
        json!([{"level": "watch", "metric": "displacement_mm", "above": 5.0},
               {"level": "warning", "metric": "displacement_mm", "above": 10.0}]),
    )
    .await;
    let scene = Scene { n: 16, stable: 8 };
    mark_stable(&d, site, &scene).await;
    for (k, block_mm) in [(0, 0.0), (1, 10.0)] {
        upload_new(&d, site, &scene.epoch(&day(k), 900 + k as u64, block_mm)).await;
    }
    let mut db = sqlx::sqlite::SqliteConnectOptions::new()
        .filename(data.join("cliffwatch.db"))
        .busy_timeout(Duration::from_secs(10))
        .connect()
        .await
        .unwrap();
    let ahead = (chrono::Utc::now() + chrono::Duration::hours(1))
        .to_rfc3339_opts(chrono::SecondsFormat::Micros, true);
    let shifted = sqlx::query("UPDATE webhook_outbox SET created_at = $1")
        .bind(&ahead)
        .execute(&mut db)
        .await
        .unwrap()
        .rows_affected();
    assert_eq!(shifted, 8, "one raised per block point");
    upload_new(&d, site, &scene.epoch(&day(2), 902, 20.0)).await;
    let rows: Vec<(String, String, String)> = sqlx::query_as(
        "SELECT alert_id, event_type, created_at FROM webhook_outbox ORDER BY alert_id, created_at",
    )
    .fetch_all(&mut db)
    .await
    .unwrap();
    let mut per_alert: BTreeMap<String, Vec<String>> = BTreeMap::new();
    for (alert, event, _) in &rows {
        per_alert
            .entry(alert.clone())
            .or_default()
            .push(event.clone());
    }
    assert_eq!(per_alert.len(), 8, "{rows:?}");
    for (alert, events) in &per_alert {
        assert_eq!(
            events,
            &["alert.raised", "alert.escalated"],
            "{alert} in created_at order: {rows:?}"
        );
    }
}
