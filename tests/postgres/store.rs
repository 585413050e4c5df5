//! The same daemon on PostgreSQL: a throwaway cluster (`support::pg`) serves a monitoring series
//! (stable points, a declared block moving to alarm, an epoch out of order, a reference change,
//! an acknowledgement), and every API answer is compared with the same scenario on SQLite. The
//! data must survive a restart on the same database, move between the backends with
//! `migrate-store`, and two daemons must share one database.

use crate::support;

use std::collections::BTreeMap;

use serde_json::{json, Value};
use support::day;
use support::server::{synthetic_epoch, TestServer};

const SITE: &str = "cliff";
/// Targets of the scene; the first `STABLE` never move, the others are block B1.
const POINTS: usize = 16;
const STABLE: usize = 8;
/// Epochs, one a day; the block moves `STEP_MM` a day towards the cameras.
const EPOCHS: usize = 9;
const STEP_MM: f64 = 3.0;

fn name(i: usize) -> String {
    format!("T{:03}", i + 1)
}

async fn send(s: &TestServer, method: reqwest::Method, path: &str, body: Value) -> (u16, Value) {
    let r = s
        .client
        .request(method, s.url(path))
        .json(&body)
        .send()
        .await
        .unwrap();
    let status = r.status().as_u16();
    (status, r.json().await.unwrap_or(Value::Null))
}

async fn text(s: &TestServer, path: &str) -> (u16, String) {
    let r = s.client.get(s.url(path)).send().await.unwrap();
    (r.status().as_u16(), r.text().await.unwrap())
}

/// The scenario, the same on every backend.
async fn run_scenario(s: &TestServer) {
    let rules = json!([
        {"level": "watch", "metric": "displacement_mm", "above": 5.0, "clear_below": 4.0},
        {"level": "warning", "metric": "displacement_mm", "above": 10.0},
        {"level": "alarm", "metric": "displacement_mm", "above": 20.0}]);
    let (st, b) = send(
        s,
        reqwest::Method::POST,
        "/api/v1/sites",
        json!({"id": SITE, "name": "Cliff", "alert_rules": rules}),
    )
    .await;
    assert_eq!(st, 201, "{b}");
    for i in 0..STABLE {
        let path = format!("/api/v1/sites/{SITE}/points/{}", name(i));
        let (st, b) = send(s, reqwest::Method::PUT, &path, json!({"role": "stable"})).await;
        assert_eq!(st, 200, "{b}");
    }
    let block: Vec<String> = (STABLE..POINTS).map(name).collect();
    let (st, b) = send(
        s,
        reqwest::Method::PUT,
        &format!("/api/v1/sites/{SITE}/groups/B1"),
        json!({"kind": "block", "direction": [0.0, -1.0, 0.0], "points": block}),
    )
    .await;
    assert_eq!(st, 200, "{b}");
    // Epoch 4 arrives after 5: the series is recomputed when it comes.
    let order = [0, 1, 2, 3, 5, 4, 6, 7, 8];
    for k in order {
        let body = synthetic_epoch(
            4,
            POINTS,
            &day(k),
            500 + k as u64,
            STEP_MM * k as f64,
            STABLE,
        );
        let (st, b) = s.upload(SITE, &body).await;
        assert_eq!(st, 201, "epoch {k}: {b}");
    }
    // The same body again is the stored epoch; another body for the same time a conflict.
    let again = synthetic_epoch(4, POINTS, &day(8), 508, STEP_MM * 8.0, STABLE);
    assert_eq!(s.upload(SITE, &again).await.0, 200);
    let other = synthetic_epoch(4, POINTS, &day(8), 999, STEP_MM * 8.0, STABLE);
    assert_eq!(s.upload(SITE, &other).await.0, 409);
    // A reference change and back: both recompute the site.
    let (_, epochs) = s
        .get(&format!("/api/v1/sites/{SITE}/epochs?limit=100"))
        .await;
    let second = epochs["items"]
        .as_array()
        .unwrap()
        .iter()
        .find(|e| e["observed_at"] == day(1).as_str())
        .unwrap()["id"]
        .clone();
    let path = format!("/api/v1/sites/{SITE}/reference");
    let (st, b) = send(s, reqwest::Method::PUT, &path, json!({"epoch": second})).await;
    assert_eq!(st, 200, "{b}");
    let (st, b) = send(s, reqwest::Method::PUT, &path, json!({"epoch": null})).await;
    assert_eq!(st, 200, "{b}");
    // Point settings: a member left out is kept, a null one cleared (CASE flags in the upsert).
    // X1 was never measured: on a site with epochs it is set up only when declared planned.
    let path = format!("/api/v1/sites/{SITE}/points/X1");
    let (st, b) = send(s, reqwest::Method::PUT, &path, json!({"role": "stable"})).await;
    assert_eq!(st, 422, "{b}");
    assert!(b.to_string().contains("never measured"), "{b}");
    let (st, b) = send(
        s,
        reqwest::Method::PUT,
        &path,
        json!({"group": "G9", "direction": [1.0, 0.0, 0.0], "planned": true}),
    )
    .await;
    assert_eq!(st, 200, "{b}");
    let (st, b) = send(s, reqwest::Method::PUT, &path, json!({"role": "stable"})).await;
    assert_eq!(st, 200, "{b}");
    assert_eq!(
        (&b["role"], &b["group"], &b["direction"]),
        (&json!("stable"), &json!("G9"), &json!([1.0, 0.0, 0.0])),
        "left out: kept"
    );
    let (st, b) = send(s, reqwest::Method::PUT, &path, json!({"group": null})).await;
    assert_eq!(st, 200, "{b}");
    assert_eq!(
        (&b["group"], &b["direction"]),
        (&Value::Null, &json!([1.0, 0.0, 0.0])),
        "null: cleared"
    );
    let (st, b) = send(
        s,
        reqwest::Method::PUT,
        &path,
        json!({"direction": null, "role": "monitored"}),
    )
    .await;
    assert_eq!(st, 200, "{b}");
    assert_eq!(
        (&b["role"], &b["group"], &b["direction"]),
        (&json!("monitored"), &Value::Null, &Value::Null)
    );
    // Staff acknowledge the block's alarm.
    let (_, alerts) = s
        .get(&format!("/api/v1/alerts?site={SITE}&limit=1000"))
        .await;
    let alarm = alerts["items"]
        .as_array()
        .unwrap()
        .iter()
        .find(|a| a["level"] == "alarm" && a["state"] == "open")
        .expect("an open alarm")["id"]
        .as_str()
        .unwrap()
        .to_string();
    let (st, b) = send(
        s,
        reqwest::Method::POST,
        &format!("/api/v1/alerts/{alarm}/ack"),
        json!({"by": "on call", "comment": "seen"}),
    )
    .await;
    assert_eq!(st, 200, "{b}");
    // Observation retention of 3 days on 8 November at noon: the epochs of 1 to 5 November lose
    // their observations (the same rows and answers on every backend, and after a move).
    let now = chrono::DateTime::parse_from_rfc3339("2026-11-08T12:00:00Z")
        .unwrap()
        .to_utc();
    let keep = std::time::Duration::from_secs(3 * 86_400);
    let pruned = cliffwatch::workers::retention::prune_observations(&s.store, keep, now)
        .await
        .unwrap();
    assert_eq!(pruned, 5);
}

/// Removes what differs between two runs by construction: wall-clock times and random ids;
/// and writes −0 as 0 (SQLite stores a REAL −0.0 as 0, PostgreSQL keeps its sign).
fn normalize(v: &mut Value) {
    match v {
        Value::Number(n) if n.as_f64() == Some(0.0) && n.is_f64() => *v = json!(0.0),
        Value::Object(m) => {
            for key in ["created_at", "raised_at", "updated_at", "taken_at"] {
                m.remove(key);
            }
            if m.contains_key("rule") && m.contains_key("level") {
                m.remove("id");
            }
            for (_, x) in m.iter_mut() {
                normalize(x);
            }
        }
        Value::Array(a) => {
            for x in a.iter_mut() {
                normalize(x);
            }
        }
        _ => {}
    }
}

/// Every answer a user sees of the site, by request.
async fn answers(s: &TestServer) -> BTreeMap<String, String> {
    let mut out = BTreeMap::new();
    let mut json_paths = vec![
        "/api/v1/sites".to_string(),
        format!("/api/v1/sites/{SITE}"),
        format!("/api/v1/sites/{SITE}/epochs?limit=100"),
        format!("/api/v1/sites/{SITE}/points"),
        format!("/api/v1/sites/{SITE}/groups"),
        format!("/api/v1/sites/{SITE}/groups/B1/motion?limit=1000"),
    ];
    let (_, epochs) = s
        .get(&format!("/api/v1/sites/{SITE}/epochs?limit=100"))
        .await;
    for e in epochs["items"].as_array().unwrap() {
        json_paths.push(format!("/api/v1/sites/{SITE}/epochs/{}", e["id"]));
    }
    for i in 0..POINTS {
        json_paths.push(format!(
            "/api/v1/sites/{SITE}/points/{}/displacements?limit=3",
            name(i)
        ));
        json_paths.push(format!(
            "/api/v1/sites/{SITE}/points/{}/displacements?limit=1000",
            name(i)
        ));
    }
    for path in json_paths {
        let (st, mut v) = s.get(&path).await;
        assert_eq!(st, 200, "{path}: {v}");
        normalize(&mut v);
        out.insert(path, serde_json::to_string_pretty(&v).unwrap());
    }
    let (st, mut alerts) = s
        .get(&format!("/api/v1/alerts?site={SITE}&limit=1000"))
        .await;
    assert_eq!(st, 200);
    // Each alert's history (`store::alerts::history`), in order, keyed by the alert without its
    // id; the events' times (wall clock for an acknowledgement) left out.
    let mut histories = Vec::new();
    for a in alerts["items"].as_array().unwrap() {
        let path = format!("/api/v1/alerts/{}/events", a["id"].as_str().unwrap());
        let (st, mut events) = s.get(&path).await;
        assert_eq!(st, 200, "{path}: {events}");
        // No event lost: the history ends at the alert's level (an alert that de-escalated on
        // the reference change and escalated back within one second once lost the second
        // escalation's message).
        let last = events["items"].as_array().unwrap().last().cloned();
        assert_eq!(
            last.as_ref().map(|e| &e["data"]["level"]),
            Some(&a["level"]),
            "{path}: {events}"
        );
        for e in events["items"].as_array_mut().unwrap() {
            e.as_object_mut().unwrap().remove("timestamp");
            e["data"].as_object_mut().unwrap().remove("alert_id");
        }
        normalize(&mut events);
        let mut key = a.clone();
        normalize(&mut key);
        histories.push(format!("{key}: {events}"));
    }
    histories.sort();
    out.insert("alert histories".into(), histories.join("\n"));
    normalize(&mut alerts);
    let mut items: Vec<String> = alerts["items"]
        .as_array()
        .unwrap()
        .iter()
        .map(|a| a.to_string())
        .collect();
    items.sort();
    out.insert("alerts".into(), items.join("\n"));
    for i in [0, STABLE, POINTS - 1] {
        let path = format!(
            "/api/v1/sites/{SITE}/points/{}/displacements?format=csv",
            name(i)
        );
        let (st, body) = text(s, &path).await;
        assert_eq!(st, 200, "{path}");
        let zero = |f: &str| match f.parse::<f64>() {
            Ok(0.0) => "0".to_string(),
            _ => f.to_string(),
        };
        let body: Vec<String> = body
            .lines()
            .map(|l| l.split(',').map(zero).collect::<Vec<_>>().join(","))
            .collect();
        out.insert(path, body.join("\n"));
    }
    out
}

/// Fails with the first line where `have` and `want` differ.
fn assert_same(what: &str, have: &str, want: &str) {
    if have == want {
        return;
    }
    let (h, w): (Vec<&str>, Vec<&str>) = (have.lines().collect(), want.lines().collect());
    let k = (0..h.len().max(w.len()))
        .find(|&k| h.get(k) != w.get(k))
        .unwrap_or(0);
    let context = |v: &[&str]| v[k.saturating_sub(3)..(k + 2).min(v.len())].join("\n");
    panic!(
        "{what}: PostgreSQL answers differently at line {k}:\n--- PostgreSQL\n{}\n--- SQLite\n{}",
        context(&h),
        context(&w)
    );
}

/// A history read of `records` rows per point, every row since `since` (an API time, or
/// a text after every stored time for none), at most `cap`.
fn reach(records: usize, since: &str, cap: usize) -> cliffwatch::store::displacements::Reach {
    let since = cliffwatch::store::parse_timestamp(since)
        .map(cliffwatch::store::timestamp)
        .unwrap_or_else(|| since.to_string());
    cliffwatch::store::displacements::Reach {
        records,
        since,
        cap,
    }
}

/// The analysis' history of an epoch after the scenario's last (`displacements::recent`, read
/// natively on each backend: SQLite's C API, PostgreSQL's own driver) as `reach` covers it.
async fn history(
    s: &TestServer,
    reach: &cliffwatch::store::displacements::Reach,
) -> Vec<(String, Vec<cliffwatch::store::displacements::Displacement>)> {
    cliffwatch::store::displacements::recent(&s.store, SITE, "9999", reach)
        .await
        .expect("history")
}

/// The reads [`history`] is compared on: the last 4 rows; the last 2 and every row since
/// day 3 (the reach of a site sampled more often than its forecast bins); the same capped at 3.
fn reaches() -> [cliffwatch::store::displacements::Reach; 3] {
    [
        reach(4, "9999", 1000),
        reach(2, &day(3), 1000),
        reach(2, &day(0), 3),
    ]
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn postgres_serves_what_sqlite_serves_and_keeps_it() {
    let _ = tracing_subscriber::fmt().with_test_writer().try_init();
    let cluster = support::pg::PgCluster::start();
    let url = cluster.create_database("cliffwatch");

    let sqlite = TestServer::start(|_| {}).await;
    assert_eq!(sqlite.store.backend(), cliffwatch::store::Backend::Sqlite);
    run_scenario(&sqlite).await;
    let expected = answers(&sqlite).await;
    let mut expected_history = vec![];
    for r in &reaches() {
        expected_history.push(history(&sqlite, r).await);
    }
    sqlite.stop().await;

    let pg_url = url.clone();
    let pg = TestServer::start(move |c| c.database_url = Some(pg_url)).await;
    assert_eq!(pg.store.backend(), cliffwatch::store::Backend::Postgres);
    assert_eq!(pg.store.checkpoint_wal().await.expect("no-op"), None);
    let (st, ready) = pg.get("/readyz").await;
    assert_eq!(st, 200, "{ready}");
    run_scenario(&pg).await;
    let got = answers(&pg).await;

    // What the scenario must have produced at all (so that equal answers mean something).
    let list = &got[&format!("/api/v1/sites/{SITE}/epochs?limit=100")];
    assert_eq!(
        list.matches("\"observations_pruned_at\": \"2026-11-08T12:00:00Z\"")
            .count(),
        5,
        "{list}"
    );
    let alerts = &got["alerts"];
    assert!(alerts.contains("\"alarm\""), "no alarm: {alerts}");
    assert!(alerts.contains("\"acknowledged\""), "no acknowledgement");
    let histories = &got["alert histories"];
    assert!(
        histories.contains("alert.raised") && histories.contains("alert.acknowledged"),
        "{histories}"
    );
    let series = &got[&format!(
        "/api/v1/sites/{SITE}/points/{}/displacements?limit=1000",
        name(POINTS - 1)
    )];
    assert_eq!(
        series.matches("\"observed_at\"").count(),
        EPOCHS,
        "{series}"
    );
    // The history the next epoch's analysis would read: every point with 4 rows, newest first,
    // the same values to the bit on both backends (booleans and nulls included).
    // With a reach in time too, every row since day 3 (days 3–8), and no more than the cap.
    let [last4, since3, capped] = reaches();
    let since_day3 =
        cliffwatch::store::timestamp(cliffwatch::store::parse_timestamp(&day(3)).expect("day 3"));
    for (k, (reach, want)) in [(&last4, 4), (&since3, 6), (&capped, 3)]
        .into_iter()
        .enumerate()
    {
        let got_history = history(&pg, reach).await;
        assert_eq!(got_history.len(), POINTS);
        for (point, rows) in &got_history {
            assert_eq!(rows.len(), want, "{point}, {reach:?}");
            assert!(
                rows.windows(2).all(|w| w[0].observed_at > w[1].observed_at),
                "{point}"
            );
            if k == 1 {
                assert!(rows.iter().all(|r| r.observed_at >= since_day3), "{point}");
            }
        }
        let rows = got_history.iter().flat_map(|(_, r)| r);
        assert!(rows.clone().any(|r| r.significant) && rows.clone().any(|r| !r.significant));
        assert!(rows.clone().any(|r| r.velocity_mm_per_day.is_some()));
        assert_eq!(got_history, expected_history[k], "{reach:?}");
    }
    assert_eq!(got.len(), expected.len());
    for (path, want) in &expected {
        let have = got.get(path).unwrap_or_else(|| panic!("{path} missing"));
        assert_same(path, have, want);
    }

    // Free text with NUL, which PostgreSQL cannot store: 422 before the database, as on SQLite
    // (tests/service/api.rs).
    pg.assert_nul_text_refused().await;
    // A site id with NUL names no site (404, as on SQLite), not a value PostgreSQL refuses.
    let (st, body) = send(
        &pg,
        reqwest::Method::GET,
        "/api/v1/alerts?site=a%00b",
        Value::Null,
    )
    .await;
    assert_eq!(st, 404, "{body}");
    // A NUL that reaches PostgreSQL is a 400 naming the cause, never a 500.
    let (st, body) = send(
        &pg,
        reqwest::Method::GET,
        "/api/v1/alerts/a%00b/events",
        Value::Null,
    )
    .await;
    assert_eq!(st, 400, "{body}");
    assert!(body.to_string().contains("cannot be stored"), "{body}");

    // A restart on the same database: nothing lost, the migrations not applied twice. The
    // series are left unpacked, as migration 20261125000300 left them: the start packs them again.
    for sql in ["DELETE FROM series_blocks", "DELETE FROM series_seals"] {
        sqlx::query(sql).execute(pg.store.reader()).await.unwrap();
    }
    pg.stop().await;
    let pg_url = url.clone();
    let again = TestServer::start(move |c| c.database_url = Some(pg_url)).await;
    let sealed: Vec<String> = sqlx::query_scalar("SELECT site_id FROM series_seals")
        .fetch_all(again.store.reader())
        .await
        .unwrap();
    assert_eq!(sealed, [SITE], "the series packed again at start");
    let after = answers(&again).await;
    for (path, want) in &got {
        assert_same(&format!("{path} after a restart"), &after[path], want);
    }
    again.stop().await;
}

/// Runs `cliffwatch migrate-store --from FROM --to TO`; returns its stderr.
fn migrate_store(from: &str, to: &str) -> String {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_cliffwatch"))
        .args(["migrate-store", "--from", from, "--to", to])
        .output()
        .expect("run cliffwatch migrate-store");
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(
        out.status.success(),
        "migrate-store {from} → {to}: {stderr}"
    );
    stderr
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn migrate_store_moves_an_installation_both_ways() {
    let cluster = support::pg::PgCluster::start();
    let pg_url = cluster.create_database("moved");
    let dir = tempfile::tempdir().unwrap();
    let first = format!("sqlite://{}", dir.path().join("first.db").display());
    let back = format!("sqlite://{}", dir.path().join("back.db").display());

    let url = first.clone();
    let original = TestServer::start(move |c| c.database_url = Some(url)).await;
    run_scenario(&original).await;
    let expected = answers(&original).await;
    original.stop().await;

    let log = migrate_store(&first, &pg_url);
    assert!(log.contains("displacements"), "{log}");
    let url = pg_url.clone();
    let on_pg = TestServer::start(move |c| c.database_url = Some(url)).await;
    assert_eq!(on_pg.store.backend(), cliffwatch::store::Backend::Postgres);
    let got = answers(&on_pg).await;
    on_pg.stop().await;
    for (path, want) in &expected {
        assert_same(&format!("{path} on PostgreSQL"), &got[path], want);
    }

    // A second copy into the same (no longer empty) store is refused and writes nothing.
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_cliffwatch"))
        .args(["migrate-store", "--from", &first, "--to", &pg_url])
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("empty store only"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );

    // A target whose only rows are a webhook (registered by a daemon started on it) is not
    // empty either: its hook would be merged with the source's and every alert sent twice.
    let busy = format!("sqlite://{}", dir.path().join("busy.db").display());
    let url = busy.clone();
    let started = TestServer::start(move |c| c.database_url = Some(url)).await;
    let (status, _) = started
        .post(
            "/api/v1/webhooks",
            &json!({"url": "http://127.0.0.1:9/hook", "secret": "whsec_MfKQ9r8GKYqrTwjUPD8ILPZIo2LaLaSw"}),
        )
        .await;
    assert_eq!(status, 201);
    started.stop().await;
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_cliffwatch"))
        .args(["migrate-store", "--from", &pg_url, "--to", &busy])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("table webhooks holds 1 row"), "{err}");

    migrate_store(&pg_url, &back);
    let url = back.clone();
    let returned = TestServer::start(move |c| c.database_url = Some(url)).await;
    let got = answers(&returned).await;
    returned.stop().await;
    for (path, want) in &expected {
        assert_same(&format!("{path} back on SQLite"), &got[path], want);
    }
}

/// Two daemons on one PostgreSQL database, as behind a load balancer: uploads go to either,
/// the same epoch to both at once is stored once, both serve the same answers, and every alert
/// message reaches the webhook exactly once although both delivery workers run.
#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn two_nodes_share_one_database() {
    let cluster = support::pg::PgCluster::start();
    let url = cluster.create_database("nodes");
    let receiver = support::alerts::Receiver::start(3).await;
    let node = |url: String| {
        TestServer::start(move |c| {
            c.database_url = Some(url);
            c.webhook_poll_ms = 20;
            c.webhook_timeout_secs = 2;
        })
    };
    let a = node(url.clone()).await;
    let b = node(url.clone()).await;
    let (st, w) = send(
        &a,
        reqwest::Method::POST,
        "/api/v1/webhooks",
        json!({"url": receiver.url, "secret": support::alerts::SECRET, "min_level": "watch"}),
    )
    .await;
    assert_eq!(st, 201, "{w}");
    let rules = json!([
        {"level": "watch", "metric": "displacement_mm", "above": 5.0, "clear_below": 4.0},
        {"level": "warning", "metric": "displacement_mm", "above": 10.0},
        {"level": "alarm", "metric": "displacement_mm", "above": 20.0}]);
    let (st, b0) = send(
        &b,
        reqwest::Method::POST,
        "/api/v1/sites",
        json!({"id": SITE, "name": "Cliff", "alert_rules": rules}),
    )
    .await;
    assert_eq!(st, 201, "{b0}");
    for i in 0..STABLE {
        let path = format!("/api/v1/sites/{SITE}/points/{}", name(i));
        let node = if i % 2 == 0 { &a } else { &b };
        let (st, r) = send(node, reqwest::Method::PUT, &path, json!({"role": "stable"})).await;
        assert_eq!(st, 200, "{r}");
    }
    let block: Vec<String> = (STABLE..POINTS).map(name).collect();
    let (st, g) = send(
        &b,
        reqwest::Method::PUT,
        &format!("/api/v1/sites/{SITE}/groups/B1"),
        json!({"kind": "block", "direction": [0.0, -1.0, 0.0], "points": block}),
    )
    .await;
    assert_eq!(st, 200, "{g}");
    let epoch = |k: usize| {
        synthetic_epoch(
            4,
            POINTS,
            &day(k),
            700 + k as u64,
            STEP_MM * k as f64,
            STABLE,
        )
    };
    // The reference first, then two epochs at a time, one to each node.
    assert_eq!(a.upload(SITE, &epoch(0)).await.0, 201);
    for k in (1..EPOCHS - 2).step_by(2) {
        let (ea, eb) = (epoch(k), epoch(k + 1));
        let ((sa, ba), (sb, bb)) = tokio::join!(a.upload(SITE, &ea), b.upload(SITE, &eb));
        assert_eq!((sa, sb), (201, 201), "{} {}", ba["error"], bb["error"]);
    }
    assert_eq!(b.upload(SITE, &epoch(EPOCHS - 2)).await.0, 201);
    // A new epoch to both nodes at once: stored once, the other answer is the stored epoch.
    let last = epoch(EPOCHS - 1);
    let ((s1, e1), (s2, e2)) = tokio::join!(a.upload(SITE, &last), b.upload(SITE, &last));
    let mut statuses = [s1, s2];
    statuses.sort();
    assert_eq!(statuses, [200, 201], "{} {}", e1["error"], e2["error"]);
    assert_eq!(e1["epoch"], e2["epoch"]);

    let (_, epochs) = a
        .get(&format!("/api/v1/sites/{SITE}/epochs?limit=100"))
        .await;
    assert_eq!(epochs["items"].as_array().unwrap().len(), EPOCHS);
    let (from_a, from_b) = (answers(&a).await, answers(&b).await);
    for (path, want) in &from_a {
        assert_same(&format!("{path} from the second node"), &from_b[path], want);
    }
    assert!(
        from_a["alerts"].contains("\"alarm\""),
        "{}",
        from_a["alerts"]
    );

    // Every message delivered, each exactly once, through the receiver's first 503s.
    let pending = || async {
        let n: i64 =
            sqlx::query_scalar("SELECT COUNT(*) FROM webhook_deliveries WHERE state = 'pending'")
                .fetch_one(a.store.reader())
                .await
                .unwrap();
        n
    };
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(60);
    while pending().await > 0 {
        assert!(
            std::time::Instant::now() < deadline,
            "deliveries still pending"
        );
        tokio::time::sleep(std::time::Duration::from_millis(100)).await;
    }
    let messages: i64 = sqlx::query_scalar("SELECT COUNT(*) FROM webhook_outbox")
        .fetch_one(a.store.reader())
        .await
        .unwrap();
    assert!(messages >= 8, "only {messages} messages");
    let log = receiver.log.lock().unwrap().clone();
    let mut accepted: BTreeMap<String, usize> = BTreeMap::new();
    for r in log.iter().filter(|r| r.accepted) {
        *accepted.entry(r.id.clone()).or_default() += 1;
    }
    assert_eq!(accepted.len() as i64, messages);
    let twice: Vec<_> = accepted.iter().filter(|(_, n)| **n > 1).collect();
    assert!(twice.is_empty(), "delivered more than once: {twice:?}");
    assert_eq!(
        receiver
            .bad_signatures
            .load(std::sync::atomic::Ordering::SeqCst),
        0
    );
    a.stop().await;
    b.stop().await;
}

/// The plot of a long history from PostgreSQL reads the blocks' extremes as SQLite does
/// ([`support::plot::long_history_plot`]).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn long_history_plot_on_postgres() {
    let cluster = support::pg::PgCluster::start();
    let url = cluster.create_database("plot");
    let pg = TestServer::start(move |c| c.database_url = Some(url)).await;
    assert_eq!(pg.store.backend(), cliffwatch::store::Backend::Postgres);
    support::plot::long_history_plot(&pg.store, &pg.url("")).await;
    pg.stop().await;
}
