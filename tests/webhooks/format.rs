//! Webhook body formats end to end through the daemon binary: three endpoints, the contract body
//! (`standard`, from the configuration file), Alertmanager's webhook body (`alertmanager_webhook`,
//! from `POST /api/v1/webhooks`) and Alertmanager's API v2 body (`alertmanager_api_v2`, from the
//! configuration file), each with its own secret. Epochs that raise alerts are uploaded; the
//! first two receivers get every event under the same `webhook-id`, in their format, signed with
//! their endpoint's secret, and a refused message comes back byte for byte on the retry; the
//! Alertmanager API receiver is told the state (every open alert, signed) by the re-post loop.

use crate::support;

use std::collections::{BTreeMap, BTreeSet};
use std::time::{Duration, Instant};

use reqwest::Method;
use serde_json::{json, Value};
use support::alerts::{outbox_ids, watch_block_moving, write_config, Daemon, Receiver, Scene};

const SITE: &str = "cliff";
const SECRET_V4: &str = "whsec_Y2xpZmZ3YXRjaC1hbS13ZWJob29rLXY0";
const SECRET_V2: &str = "whsec_Y2xpZmZ3YXRjaC1hbS1hcGktdjIta2V5";

fn keys(v: &Value) -> BTreeSet<&str> {
    v.as_object()
        .unwrap_or_else(|| panic!("not an object: {v}"))
        .keys()
        .map(String::as_str)
        .collect()
}

fn time(v: &Value) -> chrono::DateTime<chrono::Utc> {
    chrono::DateTime::parse_from_rfc3339(v.as_str().unwrap_or_else(|| panic!("not a string: {v}")))
        .unwrap_or_else(|e| panic!("{v}: not RFC 3339: {e}"))
        .to_utc()
}

/// Waits until `receiver` accepted every id of `expected`; returns the accepted bodies.
async fn accepted_all(
    receiver: &Receiver,
    expected: &BTreeSet<String>,
    what: &str,
) -> BTreeMap<String, Value> {
    let deadline = Instant::now() + Duration::from_secs(60);
    loop {
        let got = receiver.accepted();
        let ids: BTreeSet<String> = got.keys().cloned().collect();
        if &ids == expected {
            return got;
        }
        assert!(
            Instant::now() < deadline,
            "{what}: accepted {ids:?}, outbox {expected:?}"
        );
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn each_endpoint_gets_its_format_signed_and_unchanged_on_retry() {
    let dir = tempfile::tempdir().unwrap();
    let standard = Receiver::start(0).await;
    // The Alertmanager webhook receiver refuses its first 3 requests: retries must resend the
    // same bytes under the same id.
    let am_webhook = Receiver::start_with_secret(3, SECRET_V4).await;
    let am_api = Receiver::start_with_secret(0, SECRET_V2).await;
    let config = write_config(
        dir.path(),
        &format!(
            "[[webhooks]]\nurl = \"{}\"\nsecret = \"{}\"\nmin_level = \"watch\"\n\
             [[webhooks]]\nurl = \"{}\"\nsecret = \"{}\"\nmin_level = \"watch\"\n\
             format = \"alertmanager_api_v2\"\n",
            standard.url,
            support::alerts::SECRET,
            am_api.url,
            SECRET_V2
        ),
    );
    let data = dir.path().join("data");
    let daemon = Daemon::start(&data, &config).await;

    // The API: an unknown format is refused naming the field; a known one is stored and listed.
    let (s, b) = daemon
        .send(
            Method::POST,
            "/api/v1/webhooks",
            Some(
                &json!({"url": am_webhook.url, "secret": SECRET_V4, "min_level": "watch",
                         "format": "alertmanager_v4"}),
            ),
        )
        .await;
    assert_eq!(s, 422, "{b}");
    assert!(
        b["error"]["message"].as_str().unwrap().contains("format"),
        "{b}"
    );
    let (s, created) = daemon
        .send(
            Method::POST,
            "/api/v1/webhooks",
            Some(
                &json!({"url": am_webhook.url, "secret": SECRET_V4, "min_level": "watch",
                         "format": "alertmanager_webhook"}),
            ),
        )
        .await;
    assert_eq!(s, 201, "{created}");
    assert_eq!(created["format"], "alertmanager_webhook");
    let v4_id = created["id"].as_str().unwrap().to_string();
    let (_, hooks) = daemon.get("/api/v1/webhooks").await;
    let formats: BTreeMap<String, String> = hooks["items"]
        .as_array()
        .unwrap()
        .iter()
        .map(|h| {
            (
                h["url"].as_str().unwrap().to_string(),
                h["format"].as_str().unwrap().to_string(),
            )
        })
        .collect();
    assert_eq!(
        formats,
        BTreeMap::from([
            (standard.url.clone(), "standard".to_string()),
            (am_webhook.url.clone(), "alertmanager_webhook".to_string()),
            (am_api.url.clone(), "alertmanager_api_v2".to_string()),
        ])
    );

    // A site whose block of 8 points moves 10 mm between two epochs: watch alerts above 5 mm.
    let scene = Scene { n: 16, stable: 8 };
    watch_block_moving(&daemon, SITE, &scene, 700).await;

    let expected: BTreeSet<String> = outbox_ids(&data)
        .await
        .into_iter()
        .map(|(id, _)| id)
        .collect();
    assert!(expected.len() >= 8, "outbox {expected:?}");
    let block: BTreeSet<String> = (scene.stable..scene.n).map(Scene::name).collect();
    let std_bodies = accepted_all(&standard, &expected, "standard").await;
    let v4_bodies = accepted_all(&am_webhook, &expected, "alertmanager_webhook").await;
    for r in [&standard, &am_webhook, &am_api] {
        assert_eq!(
            r.bad_signatures.load(std::sync::atomic::Ordering::SeqCst),
            0,
            "{}: a signature did not verify with the endpoint's secret",
            r.url
        );
    }

    // The standard receiver: the contract body, one alert.raised per block point.
    let mut raised_points = BTreeSet::new();
    for (id, b) in &std_bodies {
        assert_eq!(
            keys(b),
            BTreeSet::from(["data", "timestamp", "type"]),
            "{id}"
        );
        time(&b["timestamp"]);
        let d = &b["data"];
        for k in [
            "alert_id",
            "site",
            "point",
            "level",
            "rule",
            "value",
            "threshold",
            "unit",
            "epoch",
            "observed_at",
            "message",
        ] {
            assert!(d.get(k).is_some(), "{id}: data lacks {k}: {b}");
        }
        assert_eq!(d["site"], SITE);
        if b["type"] == "alert.raised" && d["rule"] == "displacement_mm" {
            assert_eq!(d["level"], "watch");
            assert!(d["value"].as_f64().unwrap() > 5.0, "{b}");
            raised_points.insert(d["point"].as_str().unwrap().to_string());
        }
    }
    assert_eq!(raised_points, block, "one alert.raised per moved point");

    // The Alertmanager webhook receiver: version 4 bodies of the same events.
    for (id, b) in &v4_bodies {
        let s = &std_bodies[id];
        assert_eq!(
            keys(b),
            BTreeSet::from([
                "alerts",
                "commonAnnotations",
                "commonLabels",
                "externalURL",
                "groupKey",
                "groupLabels",
                "receiver",
                "status",
                "truncatedAlerts",
                "version"
            ]),
            "{id}"
        );
        assert_eq!(b["version"], "4");
        assert_eq!(b["receiver"], v4_id.as_str());
        let status = if s["type"] == "alert.resolved" {
            "resolved"
        } else {
            "firing"
        };
        assert_eq!(b["status"], status, "{id}");
        let alerts = b["alerts"].as_array().expect("alerts is an array");
        assert_eq!(alerts.len(), 1, "{id}");
        let a = &alerts[0];
        assert_eq!(
            keys(a),
            BTreeSet::from([
                "annotations",
                "endsAt",
                "fingerprint",
                "generatorURL",
                "labels",
                "startsAt",
                "status"
            ])
        );
        assert_eq!(a["status"], status);
        let labels: BTreeMap<String, String> = serde_json::from_value(a["labels"].clone()).unwrap();
        assert_eq!(a["fingerprint"], cliffwatch::webhooks::fingerprint(&labels));
        assert_eq!(a["annotations"]["alert_id"], s["data"]["alert_id"]);
        let l = &a["labels"];
        assert!(l.as_object().unwrap().values().all(Value::is_string), "{l}");
        assert_eq!(
            l["alertname"].as_str().unwrap(),
            format!("cliffwatch_{}", s["data"]["rule"].as_str().unwrap())
        );
        assert_eq!(l["severity"], s["data"]["level"]);
        assert_eq!(l["site"], SITE);
        if !s["data"]["point"].is_null() {
            assert_eq!(l["point"], s["data"]["point"]);
        }
        time(&a["startsAt"]);
        time(&a["endsAt"]);
    }

    // The Alertmanager API v2 receiver: the re-post loop's JSON array of postable alerts, not
    // the outbox's events; after the second epoch, the 8 watch alerts firing, held 4 periods
    // (4 × 60 s by default), each with its alert id.
    let deadline = Instant::now() + Duration::from_secs(30);
    let open_ids: BTreeSet<String> = std_bodies
        .values()
        .filter(|b| b["type"] == "alert.raised")
        .map(|b| b["data"]["alert_id"].as_str().unwrap().to_string())
        .collect();
    loop {
        let latest = am_api
            .log
            .lock()
            .unwrap()
            .iter()
            .rev()
            .find(|r| r.accepted)
            .map(|r| r.body.clone());
        let ids: BTreeSet<String> = latest
            .iter()
            .flat_map(|b| b.as_array().cloned().unwrap_or_default())
            .map(|a| {
                a["annotations"]["alert_id"]
                    .as_str()
                    .unwrap_or("")
                    .to_string()
            })
            .collect();
        if ids == open_ids {
            let body = latest.unwrap();
            for a in body.as_array().unwrap() {
                let k = keys(a);
                assert_eq!(
                    k,
                    BTreeSet::from(["annotations", "endsAt", "labels", "startsAt"]),
                    "no generatorURL without public_url: {a}"
                );
                for m in ["labels", "annotations"] {
                    assert!(
                        a[m].as_object().unwrap().values().all(Value::is_string),
                        "{m}: {a}"
                    );
                }
                assert_eq!(a["labels"]["site"], SITE);
                assert_eq!(a["labels"]["severity"], "watch");
                let held = time(&a["endsAt"]) - chrono::Utc::now();
                assert!(
                    held > chrono::Duration::seconds(200) && held <= chrono::Duration::seconds(240),
                    "endsAt 4 periods ahead: {a}"
                );
            }
            break;
        }
        assert!(
            Instant::now() < deadline,
            "Alertmanager receiver: latest body holds {ids:?}, open {open_ids:?}"
        );
        tokio::time::sleep(Duration::from_millis(100)).await;
    }

    eprintln!(
        "{} events, each delivered in 2 formats; {} requests to the Alertmanager webhook receiver",
        expected.len(),
        am_webhook.log.lock().unwrap().len()
    );
    // Retries: the refused messages came again under the same id with the same bytes.
    let log = am_webhook.log.lock().unwrap().clone();
    let refused: Vec<_> = log.iter().filter(|r| !r.accepted).collect();
    assert_eq!(refused.len(), 3);
    for r in refused {
        let ok = log
            .iter()
            .find(|o| o.accepted && o.id == r.id)
            .unwrap_or_else(|| panic!("{} refused, never delivered", r.id));
        assert_eq!(ok.raw, r.raw, "{}: the retry changed the body", r.id);
    }
}

/// A database made before the format column (migrations up to version 5) with an endpoint and a
/// pending delivery: after the migration the endpoint has the standard format and the delivery
/// no body of its own (the worker sends the outbox's contract body).
#[tokio::test]
async fn endpoints_from_before_the_migration_keep_the_standard_body() {
    use sqlx::ConnectOptions;
    let dir = tempfile::tempdir().unwrap();
    let old = dir.path().join("old-migrations");
    std::fs::create_dir(&old).unwrap();
    let all = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("migrations")
        .join("sqlite");
    let mut copied = 0;
    for e in std::fs::read_dir(&all).unwrap() {
        let e = e.unwrap();
        let name = e.file_name().to_string_lossy().to_string();
        if name.as_str() <= "20261122000500_watch_state.sql" {
            std::fs::copy(e.path(), old.join(&name)).unwrap();
            copied += 1;
        }
    }
    assert_eq!(copied, 4);
    let db = dir.path().join("cliffwatch.db");
    {
        let mut conn = sqlx::sqlite::SqliteConnectOptions::new()
            .filename(&db)
            .create_if_missing(true)
            .connect()
            .await
            .unwrap();
        sqlx::migrate::Migrator::new(old.as_path())
            .await
            .unwrap()
            .run(&mut conn)
            .await
            .unwrap();
        sqlx::query(
            "INSERT INTO webhooks (id, url, secret, min_level, source, created_at) \
             VALUES ('old', 'http://127.0.0.1:9/hook', ?, 'watch', 'api', '2026-11-01T00:00:00.000000Z')",
        )
        .bind(support::alerts::SECRET)
        .execute(&mut conn)
        .await
        .unwrap();
        sqlx::query(
            "INSERT INTO webhook_outbox (id, event_type, alert_id, level, payload, created_at) \
             VALUES ('msg_old', 'alert.raised', NULL, 'watch', '{\"type\":\"alert.raised\"}', \
             '2026-11-01T00:00:00.000000Z')",
        )
        .execute(&mut conn)
        .await
        .unwrap();
        sqlx::query(
            "INSERT INTO webhook_deliveries (outbox_id, webhook_id, state, next_attempt_at) \
             VALUES ('msg_old', 'old', 'pending', '2026-11-01T00:00:00.000000Z')",
        )
        .execute(&mut conn)
        .await
        .unwrap();
    }
    let store = cliffwatch::store::Store::open(&db, &Default::default())
        .await
        .unwrap();
    let listed = cliffwatch::store::webhooks::list(store.reader())
        .await
        .unwrap();
    assert_eq!(listed.len(), 1);
    assert_eq!(
        listed[0].format,
        cliffwatch::webhooks::PayloadFormat::Standard
    );
    let mut tx = store.begin_write().await.unwrap();
    let endpoints = cliffwatch::store::webhooks::enabled_endpoints(&mut tx)
        .await
        .unwrap();
    assert_eq!(
        endpoints[0].format,
        cliffwatch::webhooks::PayloadFormat::Standard
    );
    let own: Option<String> =
        sqlx::query_scalar("SELECT payload FROM webhook_deliveries WHERE outbox_id = 'msg_old'")
            .fetch_one(&mut *tx)
            .await
            .unwrap();
    assert_eq!(own, None);
    // The schema refuses a format the code does not know.
    let bad = sqlx::query("UPDATE webhooks SET format = 'alertmanager' WHERE id = 'old'")
        .execute(&mut *tx)
        .await;
    assert!(bad.is_err(), "CHECK on webhooks.format");
}
