//! A failed analysis is visible: an epoch with too few points in common with the reference is
//! stored (status `analysis_failed`, the reason in its report), the site-level `analysis_failed`
//! alert reaches the API and a signed webhook, and the next analysed epoch resolves it.

use crate::support;

use std::time::{Duration, Instant};

use reqwest::Method;
use serde_json::{json, Value};
use support::alerts::{day, mark_stable, write_webhook_config, Daemon, Receiver, Scene};

/// Renames every point of an upload except the first `keep` targets (T001…), so that only those
/// are in common with earlier epochs.
fn rename_points(mut body: Value, keep: usize) -> Value {
    let rename = |p: &mut Value| {
        let name = p.as_str().unwrap().to_string();
        let i: usize = name[1..].parse().unwrap();
        if i > keep {
            *p = json!(format!("U{:03}", i));
        }
    };
    for im in body["images"].as_array_mut().unwrap() {
        for o in im["observations"].as_array_mut().unwrap() {
            rename(&mut o["point"]);
        }
    }
    for a in body["approx"].as_array_mut().unwrap() {
        rename(&mut a["point"]);
    }
    body
}

async fn wait_for(receiver: &Receiver, what: &str, f: impl Fn(&Value) -> bool) -> Value {
    let deadline = Instant::now() + Duration::from_secs(20);
    loop {
        if let Some(b) = receiver.accepted().values().find(|b| f(b)) {
            return b.clone();
        }
        assert!(Instant::now() < deadline, "{what} not delivered");
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_failed_analysis_raises_an_alert_and_says_why() {
    let dir = tempfile::tempdir().unwrap();
    let receiver = Receiver::start(0).await;
    let config = write_webhook_config(dir.path(), &receiver.url);
    let daemon = Daemon::start(&dir.path().join("data"), &config).await;
    let scene = Scene { n: 16, stable: 8 };
    let (s, b) = daemon
        .send(Method::POST, "/api/v1/sites", Some(&json!({"id": "cliff"})))
        .await;
    assert_eq!(s, 201, "{b}");
    mark_stable(&daemon, "cliff", &scene).await;
    let upload = |k: usize, body: Value| {
        let d = &daemon;
        async move {
            let (s, b) = d
                .send(Method::POST, "/api/v1/sites/cliff/epochs", Some(&body))
                .await;
            assert_eq!(s, 201, "epoch {k}: {b}");
            b["epoch"].as_i64().or_else(|| b["id"].as_i64()).unwrap()
        }
    };
    upload(0, scene.epoch(&day(0), 1, 0.0)).await;
    // Only T001 and T002 in common with the reference: no datum for the S-transformation.
    let bad = upload(1, rename_points(scene.epoch(&day(1), 2, 0.0), 2)).await;

    let (s, e) = daemon
        .get(&format!("/api/v1/sites/cliff/epochs/{bad}"))
        .await;
    assert_eq!(s, 200, "{e}");
    assert_eq!(e["status"], "analysis_failed", "{e}");
    let why = e["analysis_error"].as_str().unwrap();
    assert!(why.contains("too few datum points"), "{why}");
    assert_eq!(e["displacements"], json!([]));

    let (_, alerts) = daemon.get("/api/v1/alerts?site=cliff").await;
    let items = alerts["items"].as_array().unwrap();
    assert_eq!(items.len(), 1, "{alerts}");
    let a = &items[0];
    assert_eq!(a["rule"], "analysis_failed");
    assert_eq!(a["level"], "warning");
    assert_eq!(a["state"], "open");
    assert!(a["point"].is_null());
    assert_eq!(a["epoch"], bad);
    assert!(a["message"].as_str().unwrap().contains(why), "{a}");
    let id = a["id"].as_str().unwrap().to_string();
    let raised = wait_for(&receiver, "alert.raised", |b| {
        b["type"] == "alert.raised" && b["data"]["alert_id"] == id.as_str()
    })
    .await;
    assert_eq!(raised["data"]["rule"], "analysis_failed");
    assert_eq!(raised["data"]["epoch"], bad);

    // The next epoch is analysed again: the alert resolves, and staff are told.
    let good = upload(2, scene.epoch(&day(2), 3, 0.0)).await;
    let (_, e) = daemon
        .get(&format!("/api/v1/sites/cliff/epochs/{good}"))
        .await;
    assert_eq!(e["status"], "adjusted");
    assert_eq!(e["displacements"].as_array().unwrap().len(), scene.n);
    let (_, alerts) = daemon.get("/api/v1/alerts?site=cliff").await;
    let a = &alerts["items"].as_array().unwrap()[0];
    assert_eq!(a["state"], "resolved", "{a}");
    wait_for(&receiver, "alert.resolved", |b| {
        b["type"] == "alert.resolved" && b["data"]["alert_id"] == id.as_str()
    })
    .await;
    assert_eq!(
        receiver
            .bad_signatures
            .load(std::sync::atomic::Ordering::SeqCst),
        0
    );
}
