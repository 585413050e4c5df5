//! End to end through the daemon binary: a monitoring series uploaded over HTTP → displacements
//! consistent with their σ, alerts rising level by level, every alert delivered to a signed webhook
//! receiver through 503s and a SIGKILL of the daemon; noise only → no displacement alert.

use crate::support;

use std::collections::BTreeSet;
use std::time::{Duration, Instant};

use reqwest::Method;
use serde_json::{json, Value};
use support::alerts::{
    create_site, day, mark_stable, outbox_ids, upload_new, watch_block_moving, write_config,
    write_webhook_config, Daemon, Receiver, Scene,
};

const SITE: &str = "cliff";

fn rank(level: &str) -> u8 {
    match level {
        "watch" => 1,
        "warning" => 2,
        "alarm" => 3,
        _ => 0,
    }
}

/// The highest open displacement alert level of the block's points.
async fn block_level(d: &Daemon) -> u8 {
    let (_, alerts) = d
        .get(&format!("/api/v1/alerts?site={SITE}&limit=1000"))
        .await;
    alerts["items"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|a| a["rule"] == "displacement_mm" && a["state"] != "resolved")
        .map(|a| rank(a["level"].as_str().unwrap()))
        .max()
        .unwrap_or(0)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn series_alerts_and_webhooks_survive_503_and_sigkill() {
    let dir = tempfile::tempdir().unwrap();
    let receiver = Receiver::start(12).await;
    let config = write_webhook_config(dir.path(), &receiver.url);
    let data = dir.path().join("data");
    let scene = Scene { n: 16, stable: 8 };
    let mut daemon = Daemon::start(&data, &config).await;
    create_site(
        &daemon,
        SITE,
        json!([
            {"level": "watch", "metric": "displacement_mm", "above": 5.0, "clear_below": 4.0},
            {"level": "warning", "metric": "displacement_mm", "above": 10.0},
            {"level": "alarm", "metric": "displacement_mm", "above": 20.0}]),
    )
    .await;
    mark_stable(&daemon, SITE, &scene).await;

    // 12 daily epochs; the block moves 2.5 mm a day towards the cameras.
    let n_epochs = 12;
    let step_mm = 2.5;
    let mut levels = Vec::new();
    for k in 0..n_epochs {
        if k == 6 {
            // Retries are pending (the receiver still refuses): SIGKILL, restart on the same data.
            daemon.kill9();
            daemon = Daemon::start(&data, &config).await;
        }
        let body = scene.epoch(&day(k), 1000 + k as u64, step_mm * k as f64);
        let (s, b) = daemon
            .send(
                Method::POST,
                &format!("/api/v1/sites/{SITE}/epochs"),
                Some(&body),
            )
            .await;
        assert_eq!(s, 201, "epoch {k}: {b}");
        levels.push(block_level(&daemon).await);
    }
    // Alerts rise level by level: none below 5 mm, watch, warning, then alarm above 20 mm.
    assert_eq!(levels[0], 0, "levels {levels:?}");
    assert!(levels.windows(2).all(|w| w[0] <= w[1]), "levels {levels:?}");
    for want in 1..=3u8 {
        assert!(
            levels.contains(&want),
            "level {want} never reached: {levels:?}"
        );
    }
    assert_eq!(*levels.last().unwrap(), 3, "levels {levels:?}");

    // The time series against the truth: every component within 3σ for ≥ 97 % of the samples.
    let (mut inside, mut total) = (0usize, 0usize);
    let mut worst: f64 = 0.0;
    for i in 0..scene.n {
        let (s, series) = daemon
            .get(&format!(
                "/api/v1/sites/{SITE}/points/{}/displacements",
                Scene::name(i)
            ))
            .await;
        assert_eq!(s, 200);
        let items = series["items"].as_array().unwrap();
        assert_eq!(items.len(), n_epochs, "point {i}");
        for (k, r) in items.iter().enumerate() {
            let truth = scene.truth_mm(i, step_mm * k as f64);
            for (c, name) in ["dx_mm", "dy_mm", "dz_mm"].iter().enumerate() {
                let sigma = r[format!("sigma_{}", &name[..2]) + "_mm"].as_f64().unwrap();
                let e = r[*name].as_f64().unwrap() - truth[c];
                if k == 0 {
                    assert_eq!(r[*name].as_f64().unwrap(), 0.0);
                    continue;
                }
                assert!(sigma > 0.0 && sigma < 5.0, "σ {sigma} mm");
                total += 1;
                if e.abs() <= 3.0 * sigma {
                    inside += 1;
                }
                worst = worst.max(e.abs() / sigma);
            }
        }
    }
    let share = inside as f64 / total as f64;
    eprintln!("displacement errors within 3σ: {inside}/{total} ({share:.3}), worst {worst:.2} σ");
    assert!(share >= 0.97, "{inside}/{total} within 3σ");

    // Every event of the outbox arrives (signed), each webhook-id accepted exactly once after
    // deduplication, despite 12 refusals and the SIGKILL.
    let deadline = Instant::now() + Duration::from_secs(60);
    let expected: BTreeSet<String> = loop {
        let expected: BTreeSet<String> = outbox_ids(&data)
            .await
            .into_iter()
            .map(|(id, _)| id)
            .collect();
        let got: BTreeSet<String> = receiver.accepted().keys().cloned().collect();
        if got == expected || Instant::now() > deadline {
            break expected;
        }
        tokio::time::sleep(Duration::from_millis(200)).await;
    };
    let accepted = receiver.accepted();
    let got: BTreeSet<String> = accepted.keys().cloned().collect();
    assert_eq!(got, expected, "every outbox event delivered");
    assert_eq!(
        receiver
            .bad_signatures
            .load(std::sync::atomic::Ordering::SeqCst),
        0
    );
    let log = receiver.log.lock().unwrap().clone();
    assert!(log.iter().any(|r| !r.accepted), "the receiver refused some");
    // Retries reused the webhook-id: refused ids are among the delivered ones.
    for r in log.iter().filter(|r| !r.accepted) {
        assert!(expected.contains(&r.id), "retry with a new id {}", r.id);
    }
    // Every alert of the API was announced by an alert.raised with the contract body.
    let (_, alerts) = daemon.get("/api/v1/alerts?limit=1000").await;
    let alerts = alerts["items"].as_array().unwrap().clone();
    assert!(!alerts.is_empty());
    for a in &alerts {
        let raised = accepted
            .values()
            .find(|b| b["type"] == "alert.raised" && b["data"]["alert_id"] == a["id"]);
        let b = raised.unwrap_or_else(|| panic!("no alert.raised for {a}"));
        assert_eq!(b["data"]["site"], SITE);
        assert_eq!(b["data"]["rule"], "displacement_mm");
        assert_eq!(b["data"]["unit"], "mm");
        assert!(b["data"]["value"].as_f64().unwrap() > b["data"]["threshold"].as_f64().unwrap());
    }
    // Each alert's summary states its value, in the API and in every webhook body, and the
    // active alerts carry the latest epoch's evaluation.
    let states_value = |v: &Value| {
        let value = v["value"].as_f64().expect("value");
        v["message"]
            .as_str()
            .expect("message")
            .contains(&format!("{value:.2} mm"))
    };
    for a in &alerts {
        assert!(states_value(a), "{a}");
    }
    for b in accepted.values() {
        assert!(states_value(&b["data"]), "{b}");
    }
    let (_, epochs) = daemon.get(&format!("/api/v1/sites/{SITE}/epochs")).await;
    let newest = epochs["items"]
        .as_array()
        .expect("epochs")
        .iter()
        .filter_map(|e| e["id"].as_i64())
        .max();
    for a in alerts.iter().filter(|a| a["state"] != "resolved") {
        assert_eq!(a["epoch"].as_i64(), newest, "{a}");
    }
    let escalated = accepted
        .values()
        .filter(|b| b["type"] == "alert.escalated")
        .count();
    assert!(escalated > 0, "escalations delivered");
    // Only block points alert.
    for a in &alerts {
        let p = a["point"].as_str().unwrap();
        let i: usize = p[1..].parse::<usize>().unwrap() - 1;
        assert!(i >= scene.stable, "stable point {p} alerted");
    }

    // Acknowledging queues alert.acknowledged, delivered with its own id.
    // Alert ids are "site/point/rule/epoch": one path segment once percent-encoded.
    let id = alerts[0]["id"].as_str().unwrap();
    let (s, b) = daemon
        .send(
            Method::POST,
            &format!("/api/v1/alerts/{}/ack", id.replace('/', "%2F")),
            Some(&json!({"by": "geologist", "comment": "seen"})),
        )
        .await;
    assert_eq!(s, 200, "{b}");
    assert_eq!(b["state"], "acknowledged");
    let deadline = Instant::now() + Duration::from_secs(20);
    loop {
        let acked = receiver
            .accepted()
            .into_values()
            .find(|b| b["type"] == "alert.acknowledged" && b["data"]["alert_id"] == id);
        if let Some(ack) = acked {
            // who acknowledged, and why, reach the staff on duty with it
            assert_eq!(ack["data"]["acknowledged_by"], "geologist", "{ack}");
            assert_eq!(ack["data"]["comment"], "seen", "{ack}");
            for b in receiver.accepted().values() {
                assert!(states_value(&b["data"]), "{b}");
            }
            break;
        }
        assert!(
            Instant::now() < deadline,
            "alert.acknowledged not delivered"
        );
        tokio::time::sleep(Duration::from_millis(100)).await;
    }

    // The alert's history: the bodies its webhook received, oldest first, the acknowledgement
    // last (`accepted` keeps one body per webhook-id).
    let (s, h) = daemon
        .get(&format!("/api/v1/alerts/{}/events", id.replace('/', "%2F")))
        .await;
    assert_eq!(s, 200, "{h}");
    let items = h["items"].as_array().unwrap();
    let sent: Vec<Value> = receiver
        .accepted()
        .into_values()
        .filter(|b| b["data"]["alert_id"] == id)
        .collect();
    assert_eq!(items.len(), sent.len(), "{h}");
    for b in &sent {
        assert!(items.contains(b), "{b} is not in {h}");
    }
    assert_eq!(items[0]["type"], "alert.raised", "{h}");
    let last = items.last().unwrap();
    assert_eq!(last["type"], "alert.acknowledged", "{h}");
    assert_eq!(last["data"]["acknowledged_by"], "geologist", "{h}");
    let (s, b) = daemon.get("/api/v1/alerts/nope/events").await;
    assert_eq!(s, 404, "{b}");

    // Moving the reference recomputes the series: against epoch 6 the block moved 2.5 mm/day since.
    let (s, b) = daemon
        .send(
            Method::PUT,
            &format!("/api/v1/sites/{SITE}/reference"),
            Some(&json!({"epoch": 7})),
        )
        .await;
    assert_eq!(s, 200, "{b}");
    let (_, series) = daemon
        .get(&format!(
            "/api/v1/sites/{SITE}/points/{}/displacements",
            Scene::name(scene.n - 1)
        ))
        .await;
    let items = series["items"].as_array().unwrap();
    let at7 = items.iter().find(|r| r["epoch"] == 7).unwrap();
    assert_eq!(at7["d_mm"].as_f64().unwrap(), 0.0);
    let last = items.last().unwrap();
    let want = step_mm * 5.0;
    let got = -last["dy_mm"].as_f64().unwrap();
    assert!(
        (got - want).abs() < 3.0 * last["sigma_dy_mm"].as_f64().unwrap() + 0.1,
        "after the reference change {got} mm, want {want} mm"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn noise_only_raises_no_displacement_alert_at_5_sigma() {
    let dir = tempfile::tempdir().unwrap();
    let config = write_config(dir.path(), "");
    let data = dir.path().join("data");
    let scene = Scene { n: 16, stable: 8 };
    let daemon = Daemon::start(&data, &config).await;

    // A probe site gives the displacement σ of this geometry.
    create_site(&daemon, "probe", json!([])).await;
    mark_stable(&daemon, "probe", &scene).await;
    for k in 0..2 {
        let (s, b) = daemon
            .send(
                Method::POST,
                "/api/v1/sites/probe/epochs",
                Some(&scene.epoch(&day(k), 500 + k as u64, 0.0)),
            )
            .await;
        assert_eq!(s, 201, "{b}");
    }
    let mut sigma: f64 = 0.0;
    for i in 0..scene.n {
        let (_, s) = daemon
            .get(&format!(
                "/api/v1/sites/probe/points/{}/displacements",
                Scene::name(i)
            ))
            .await;
        sigma = sigma.max(s["items"][1]["sigma_mm"].as_f64().unwrap());
    }
    assert!(sigma > 0.0);
    let threshold = 5.0 * sigma;
    eprintln!("largest σ of d: {sigma:.3} mm; threshold {threshold:.3} mm");

    create_site(
        &daemon,
        "quiet",
        json!([
            {"level": "watch", "metric": "displacement_mm", "above": threshold},
            {"level": "warning", "metric": "displacement_mm", "above": 2.0 * threshold}]),
    )
    .await;
    mark_stable(&daemon, "quiet", &scene).await;
    for k in 0..12 {
        let (s, b) = daemon
            .send(
                Method::POST,
                "/api/v1/sites/quiet/epochs",
                Some(&scene.epoch(&day(k), 7000 + k as u64, 0.0)),
            )
            .await;
        assert_eq!(s, 201, "{b}");
    }
    let (_, alerts) = daemon.get("/api/v1/alerts?site=quiet").await;
    assert_eq!(alerts["items"], json!([]), "no alert on noise");
    // The series exists and is noise-sized.
    let (_, s) = daemon
        .get(&format!(
            "/api/v1/sites/quiet/points/{}/displacements",
            Scene::name(scene.n - 1)
        ))
        .await;
    let items = s["items"].as_array().unwrap();
    assert_eq!(items.len(), 12);
    assert!(items
        .iter()
        .all(|r| r["d_mm"].as_f64().unwrap() < threshold));
}

/// An alert rule removed from the configuration file: at the next start the site is recomputed
/// and the alerts of that rule resolve instead of staying open for good.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_rule_removed_from_the_configuration_resolves_its_alerts() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    let scene = Scene { n: 16, stable: 8 };
    let config = |rules: &str| {
        write_config(
            dir.path(),
            &format!("[[sites]]\nid = \"cfg\"\nalert_rules = [{rules}]\n"),
        )
    };
    let displacement = |alerts: &Value, state: &str| {
        alerts["items"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|a| a["rule"] == "displacement_mm" && a["state"] == state)
            .count()
    };
    let rule = r#"{level = "watch", metric = "displacement_mm", above = 5.0}"#;
    let daemon = Daemon::start(&data, &config(rule)).await;
    mark_stable(&daemon, "cfg", &scene).await;
    for k in 0..2 {
        let body = scene.epoch(&day(k), 40 + k as u64, 10.0 * k as f64);
        upload_new(&daemon, "cfg", &body).await;
    }
    let (_, alerts) = daemon.get("/api/v1/alerts?site=cfg&limit=1000").await;
    let raised = displacement(&alerts, "open");
    assert!(raised >= 4, "{alerts}");
    daemon.kill9();

    let daemon = Daemon::start(&data, &config("")).await;
    let (_, alerts) = daemon.get("/api/v1/alerts?site=cfg&limit=1000").await;
    assert_eq!(displacement(&alerts, "open"), 0, "{alerts}");
    assert_eq!(displacement(&alerts, "resolved"), raised, "{alerts}");
    let first = &alerts["items"][0];
    assert!(
        first["message"]
            .as_str()
            .unwrap()
            .contains("alert rules changed"),
        "{first}"
    );
}

/// Stable points confirmed as moved by later epochs join the open `reference_unstable` alert:
/// its row lists them all, not only the first.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn reference_unstable_lists_every_excluded_stable_point() {
    let dir = tempfile::tempdir().unwrap();
    let config = write_config(dir.path(), "");
    let data = dir.path().join("data");
    let scene = Scene { n: 16, stable: 8 };
    let daemon = Daemon::start(&data, &config).await;
    create_site(&daemon, "drift", json!([])).await;
    mark_stable(&daemon, "drift", &scene).await;
    // Day 0 still; day 1: T008 moves with the block; day 2: T007 as well; day 3 confirms
    // T007 (excluded twice, as T008 was by day 2).
    for (k, still) in [(0, 8), (1, 7), (2, 6), (3, 6)] {
        let moving = Scene {
            n: 16,
            stable: still,
        };
        let (s, b) = daemon
            .send(
                Method::POST,
                "/api/v1/sites/drift/epochs",
                Some(&moving.epoch(&day(k), 900 + k as u64, 20.0 * k.min(1) as f64)),
            )
            .await;
        assert_eq!(s, 201, "{b}");
    }
    let (_, alerts) = daemon.get("/api/v1/alerts?site=drift").await;
    let unstable: Vec<&Value> = alerts["items"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|a| a["rule"] == "reference_unstable")
        .collect();
    assert_eq!(unstable.len(), 1, "{alerts}");
    let points = unstable[0]["points"].as_array().unwrap();
    let message = unstable[0]["message"].as_str().unwrap();
    for p in ["T007", "T008"] {
        assert!(points.contains(&json!(p)), "{p} missing: {}", unstable[0]);
        assert!(message.contains(p), "{p} not in the message: {message}");
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn overdue_campaign_raises_a_site_level_alert() {
    let dir = tempfile::tempdir().unwrap();
    let config = write_config(dir.path(), "overdue_check_secs = 1");
    let data = dir.path().join("data");
    let scene = Scene { n: 16, stable: 8 };
    let daemon = Daemon::start(&data, &config).await;
    let (s, b) = daemon
        .send(
            Method::POST,
            "/api/v1/sites",
            Some(&json!({"id": "late", "schedule_hours": 24})),
        )
        .await;
    assert_eq!(s, 201, "{b}");
    // The only campaign was observed weeks ago: more than 24 h × 1.25 have passed.
    let (s, b) = daemon
        .send(
            Method::POST,
            "/api/v1/sites/late/epochs",
            Some(&scene.epoch(&day(0), 42, 0.0)),
        )
        .await;
    assert_eq!(s, 201, "{b}");
    let deadline = Instant::now() + Duration::from_secs(20);
    let alert = loop {
        let (_, alerts) = daemon.get("/api/v1/alerts?site=late").await;
        if let Some(a) = alerts["items"]
            .as_array()
            .unwrap()
            .iter()
            .find(|a| a["rule"] == "campaign_overdue")
        {
            break a.clone();
        }
        assert!(Instant::now() < deadline, "no campaign_overdue alert");
        tokio::time::sleep(Duration::from_millis(200)).await;
    };
    assert!(alert["point"].is_null());
    assert_eq!(alert["level"], "watch");
    assert_eq!(alert["state"], "open");
}

/// The campaign that ends an overdue spell may be the second epoch of a reference of two (it is
/// ingested by recomputing the site): it resolves `campaign_overdue` all the same.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_epoch_joining_the_reference_ends_an_overdue_campaign() {
    let dir = tempfile::tempdir().unwrap();
    let config = write_config(dir.path(), "overdue_check_secs = 1");
    let data = dir.path().join("data");
    let scene = Scene { n: 16, stable: 8 };
    let daemon = Daemon::start(&data, &config).await;
    let site = json!({"id": "late2", "schedule_hours": 24, "reference_epochs": 2});
    let (s, b) = daemon
        .send(Method::POST, "/api/v1/sites", Some(&site))
        .await;
    assert_eq!(s, 201, "{b}");
    let ago = |hours: i64| {
        (chrono::Utc::now() - chrono::Duration::hours(hours))
            .to_rfc3339_opts(chrono::SecondsFormat::Secs, true)
    };
    // 40 h since the only campaign: more than 24 h × 1.25.
    upload_new(&daemon, "late2", &scene.epoch(&ago(40), 61, 0.0)).await;
    let overdue = |alerts: &Value, state: &str| {
        alerts["items"]
            .as_array()
            .unwrap()
            .iter()
            .any(|a| a["rule"] == "campaign_overdue" && a["state"] == state)
    };
    let deadline = Instant::now() + Duration::from_secs(20);
    loop {
        let (_, alerts) = daemon.get("/api/v1/alerts?site=late2").await;
        if overdue(&alerts, "open") {
            break;
        }
        assert!(
            Instant::now() < deadline,
            "no campaign_overdue alert: {alerts}"
        );
        tokio::time::sleep(Duration::from_millis(200)).await;
    }
    // The next campaign, an hour ago: the second epoch of the reference.
    upload_new(&daemon, "late2", &scene.epoch(&ago(1), 62, 0.0)).await;
    let (_, alerts) = daemon.get("/api/v1/alerts?site=late2").await;
    assert!(overdue(&alerts, "resolved"), "{alerts}");
    assert!(!overdue(&alerts, "open"), "{alerts}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn gone_disables_the_endpoint() {
    let dir = tempfile::tempdir().unwrap();
    let receiver = Receiver::start(0).await;
    receiver
        .gone
        .store(true, std::sync::atomic::Ordering::SeqCst);
    let config = write_webhook_config(dir.path(), &receiver.url);
    let data = dir.path().join("data");
    let scene = Scene { n: 16, stable: 8 };
    let daemon = Daemon::start(&data, &config).await;
    watch_block_moving(&daemon, SITE, &scene, 300).await;
    let deadline = Instant::now() + Duration::from_secs(20);
    while support::alerts::endpoints_enabled(&data).await != vec![false] {
        assert!(Instant::now() < deadline, "endpoint not disabled");
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    // One attempt, then nothing more for that endpoint.
    tokio::time::sleep(Duration::from_millis(500)).await;
    assert_eq!(receiver.log.lock().unwrap().len(), 1);
}
