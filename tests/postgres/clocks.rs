//! Nodes whose wall clocks disagree: webhook leases and due times, the campaign schedule and the
//! times rows record are read on the database's clock. So a node whose clock runs ahead takes
//! over no live claim and raises no overdue campaign early, a node whose clock runs behind
//! neither holds back a message another node queued nor misses an overdue campaign, and an
//! alert is never acknowledged before it was raised. The skewed nodes run under libfaketime
//! (Debian's `faketime`), their clocks 10 or 30 minutes off; the database's is true.

use crate::nodes::{call, epoch, pending, polling_node_config, set_up_site, until_delivered};
use crate::support;
use crate::support::alerts::{Daemon, Receiver, Scene};

use std::time::{Duration, Instant};

use reqwest::{Client, Method};
use serde_json::{json, Value};

const SITE: &str = "cliff-1";

/// libfaketime's preload library; a missing one fails the test (`.ci/run` installs it).
fn faketime_library() -> &'static str {
    const LIB: &str = "/usr/lib/x86_64-linux-gnu/faketime/libfaketime.so.1";
    assert!(
        std::path::Path::new(LIB).exists(),
        "{LIB} missing: install Debian's `faketime`, as .ci/run does"
    );
    LIB
}

/// The environment of a node whose wall clock is `offset` off (`-10m`, `+10m`); its monotonic
/// clock, which times its sleeps and claims, stays true.
fn skewed(offset: &'static str) -> [(&'static str, &'static str); 3] {
    [
        ("LD_PRELOAD", faketime_library()),
        ("FAKETIME", offset),
        ("FAKETIME_DONT_FAKE_MONOTONIC", "1"),
    ]
}

/// How far a node's wall clock is off, in seconds, read from its answers' `date` header.
async fn clock_offset(node: &Daemon) -> i64 {
    let r = node.client.get(node.url("/readyz")).send().await.unwrap();
    let date = r.headers()["date"].to_str().unwrap().to_string();
    let theirs = chrono::DateTime::parse_from_rfc2822(&date).unwrap();
    theirs.timestamp() - chrono::Utc::now().timestamp()
}

/// Asserts that `node`'s clock is `minutes` off (libfaketime took), to a few seconds.
async fn assert_skewed(node: &Daemon, minutes: i64) {
    let off = clock_offset(node).await;
    assert!(
        (off - 60 * minutes).abs() <= 5,
        "the node's clock is {off} s off, not {minutes} min"
    );
}

/// A node's configuration: the shared database, webhooks looked for every `poll_ms`.
fn config(dir: &std::path::Path, url: &str, poll_ms: u64) -> std::path::PathBuf {
    polling_node_config(dir, Some(url), poll_ms)
}

/// Uploads epochs `ks` through a node with a true clock whose delivery worker does not look
/// again for an hour, then kills it: the alert messages stay queued for another node.
async fn queue_through_true_node(dir: &std::path::Path, url: &str, ks: std::ops::Range<usize>) {
    let node = Daemon::start(dir, &config(dir, url, 3_600_000)).await;
    let path = format!("/api/v1/sites/{SITE}/epochs");
    for k in ks {
        let (st, r) = node.send(Method::POST, &path, Some(&epoch(0, k))).await;
        assert_eq!(st, 201, "epoch {k}: {r}");
    }
    node.kill9();
    assert!(pending(url).await > 0, "the uploads queued alert messages");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn node_clocks_decide_no_webhook_lease() {
    sqlx::any::install_default_drivers();
    let cluster = support::pg::PgCluster::start();
    let url = cluster.create_database("clocks");
    let dir = tempfile::tempdir().unwrap();
    let rx = Receiver::start(0).await;
    let client = Client::new();
    {
        let node = Daemon::start(dir.path(), &config(dir.path(), &url, 3_600_000)).await;
        set_up_site(&client, &node.base, SITE).await;
        call(
            &client,
            &node.base,
            Method::POST,
            "/api/v1/webhooks",
            json!({"url": rx.url, "secret": support::alerts::SECRET, "min_level": "watch"}),
        )
        .await;
        node.kill9();
    }

    // 1. A claim held by another node: its lease, 12 s on the database's clock, is what a claim
    //    writes. A node 10 minutes ahead must leave it until the lease ends.
    queue_through_true_node(dir.path(), &url, 0..6).await;
    let pool = sqlx::any::AnyPoolOptions::new()
        .max_connections(1)
        .connect(&url)
        .await
        .unwrap();
    let claimed_at = Instant::now();
    sqlx::query(
        "UPDATE webhook_deliveries SET next_attempt_at = to_char(clock_timestamp() \
         AT TIME ZONE 'UTC' + interval '12 seconds', 'YYYY-MM-DD\"T\"HH24:MI:SS.US\"Z\"') \
         WHERE state = 'pending'",
    )
    .execute(&pool)
    .await
    .unwrap();
    pool.close().await;
    let ahead =
        Daemon::start_with_env(dir.path(), &config(dir.path(), &url, 50), &skewed("+10m")).await;
    assert_skewed(&ahead, 10).await;
    tokio::time::sleep(Duration::from_secs(6).saturating_sub(claimed_at.elapsed())).await;
    let looked = claimed_at.elapsed();
    assert!(
        looked < Duration::from_secs(11),
        "the node took {looked:?} to start: too late to tell"
    );
    assert!(
        rx.log.lock().unwrap().is_empty(),
        "a node 10 minutes ahead took over a claim whose lease runs to 12 s (after {looked:?})"
    );
    until_delivered(&url, Duration::from_secs(30)).await;
    assert!(
        claimed_at.elapsed() >= Duration::from_secs(12),
        "delivered before the lease ended"
    );
    let watch = rx.accepted();
    assert!(!watch.is_empty(), "the watch alert was announced");
    ahead.kill9();

    // 2. A message queued by a node with a true clock is due at once for a node 10 minutes
    //    behind, not in 10 minutes.
    queue_through_true_node(dir.path(), &url, 6..9).await;
    let behind =
        Daemon::start_with_env(dir.path(), &config(dir.path(), &url, 50), &skewed("-10m")).await;
    assert_skewed(&behind, -10).await;
    let took = until_delivered(&url, Duration::from_secs(20)).await;
    assert!(
        rx.accepted().len() > watch.len(),
        "the warning was announced"
    );
    eprintln!("delivered by the node 10 minutes behind in {took:?}");
    assert_eq!(
        rx.bad_signatures.load(std::sync::atomic::Ordering::SeqCst),
        0
    );
}

/// The alerts of `site` (any state, newest first), read through `node`.
async fn site_alerts(node: &Daemon, site: &str) -> Vec<Value> {
    let (st, alerts) = node.get(&format!("/api/v1/alerts?site={site}")).await;
    assert_eq!(st, 200, "{alerts}");
    alerts["items"].as_array().expect("an alert list").clone()
}

/// How many `campaign_overdue` alerts `site` has had (any state), read through `node`.
async fn overdue_alerts(node: &Daemon, site: &str) -> usize {
    site_alerts(node, site)
        .await
        .iter()
        .filter(|a| a["rule"] == "campaign_overdue")
        .count()
}

/// Waits until `node` has raised `campaign_overdue` on `site`; fails after 20 s.
async fn until_overdue(node: &Daemon, site: &str, why: &str) {
    let deadline = Instant::now() + Duration::from_secs(20);
    while overdue_alerts(node, site).await == 0 {
        assert!(Instant::now() < deadline, "{why}");
        tokio::time::sleep(Duration::from_millis(200)).await;
    }
}

/// The campaign schedule (one hour, so overdue after 75 min) is checked on the database's clock:
/// a node 30 minutes behind raises a campaign 90 min old, which its own clock puts at 60 min, and
/// a node 30 minutes ahead does not raise one 60 min old, which its own clock puts at 90 min.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn node_clocks_decide_no_overdue_campaign() {
    sqlx::any::install_default_drivers();
    let cluster = support::pg::PgCluster::start();
    let url = cluster.create_database("schedule");
    let dir = tempfile::tempdir().unwrap();
    let config = dir.path().join("cliffwatch.toml");
    std::fs::write(
        &config,
        format!("database_url = \"{url}\"\noverdue_check_secs = 1\n"),
    )
    .unwrap();
    let scene = Scene { n: 16, stable: 8 };
    let ago = |minutes: i64| {
        (chrono::Utc::now() - chrono::Duration::minutes(minutes))
            .to_rfc3339_opts(chrono::SecondsFormat::Secs, true)
    };

    // 1. A node 30 minutes behind, sites whose last campaigns are 90 and 60 min old.
    let behind = Daemon::start_with_env(dir.path(), &config, &skewed("-30m")).await;
    assert_skewed(&behind, -30).await;
    for (site, minutes) in [("late", 90), ("on-time", 60)] {
        let site_form = json!({"id": site, "schedule_hours": 1});
        let (st, b) = behind
            .send(Method::POST, "/api/v1/sites", Some(&site_form))
            .await;
        assert_eq!(st, 201, "{b}");
        let path = format!("/api/v1/sites/{site}/epochs");
        let (st, b) = behind
            .send(
                Method::POST,
                &path,
                Some(&scene.epoch(&ago(minutes), 7, 0.0)),
            )
            .await;
        assert_eq!(st, 201, "{site}: {b}");
    }
    until_overdue(
        &behind,
        "late",
        "a node 30 minutes behind missed a campaign 90 min old on a 1-hour schedule",
    )
    .await;
    behind.kill9();

    // 2. A node 30 minutes ahead: a third site, 90 min old, shows that its checks run; the site
    //    60 min old stays quiet through them.
    let ahead = Daemon::start_with_env(dir.path(), &config, &skewed("+30m")).await;
    assert_skewed(&ahead, 30).await;
    let site_form = json!({"id": "late-too", "schedule_hours": 1});
    let (st, b) = ahead
        .send(Method::POST, "/api/v1/sites", Some(&site_form))
        .await;
    assert_eq!(st, 201, "{b}");
    let (st, b) = ahead
        .send(
            Method::POST,
            "/api/v1/sites/late-too/epochs",
            Some(&scene.epoch(&ago(90), 8, 0.0)),
        )
        .await;
    assert_eq!(st, 201, "{b}");
    until_overdue(
        &ahead,
        "late-too",
        "the node 30 minutes ahead checked no schedule",
    )
    .await;
    // two more checks (one a second) over every site
    tokio::time::sleep(Duration::from_millis(2500)).await;
    assert_eq!(
        overdue_alerts(&ahead, "on-time").await,
        0,
        "a node 30 minutes ahead raised a campaign 60 min old on a 1-hour schedule"
    );
    assert_eq!(overdue_alerts(&ahead, "late").await, 1, "raised once");
    ahead.kill9();
}

/// A time the API shows (RFC 3339).
fn shown_time(shown: &Value) -> chrono::DateTime<chrono::FixedOffset> {
    chrono::DateTime::parse_from_rfc3339(shown.as_str().expect("a time"))
        .unwrap_or_else(|e| panic!("{shown}: {e}"))
}

/// Seconds between a time the API shows and the true time now (positive: the shown time is
/// ahead).
fn seconds_off(shown: &Value) -> i64 {
    shown_time(shown).timestamp() - chrono::Utc::now().timestamp()
}

/// The times rows record (an epoch's `created_at`, an alert's `raised_at` and `updated_at`) are
/// the database's: with one node 30 minutes ahead and one 30 minutes behind taking turns, each
/// is within a minute of the true time, an alert's `raised_at` is its epoch's `created_at` (one
/// time per upload), and an alert raised through the node behind and
/// acknowledged through the node ahead is not acknowledged an hour before it was raised.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn node_clocks_stamp_no_recorded_time() {
    sqlx::any::install_default_drivers();
    let cluster = support::pg::PgCluster::start();
    let url = cluster.create_database("stamps");
    let dirs = [tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap()];
    let config = |d: &tempfile::TempDir| config(d.path(), &url, 3_600_000);
    let ahead = Daemon::start_with_env(dirs[0].path(), &config(&dirs[0]), &skewed("+30m")).await;
    let behind = Daemon::start_with_env(dirs[1].path(), &config(&dirs[1]), &skewed("-30m")).await;
    assert_skewed(&ahead, 30).await;
    assert_skewed(&behind, -30).await;
    set_up_site(&ahead.client, &ahead.base, SITE).await;

    // Days 0–5, 1.5 mm a day: the watch rule (above 5 mm) fires on day 4, which the node behind
    // takes; the nodes alternate.
    let path = format!("/api/v1/sites/{SITE}/epochs");
    for k in 0..6 {
        let node = if k % 2 == 0 { &ahead } else { &behind };
        let (st, r) = node.send(Method::POST, &path, Some(&epoch(0, k))).await;
        assert_eq!(st, 201, "epoch {k}: {r}");
    }
    let (st, epochs) = behind.get(&format!("{path}?limit=100")).await;
    assert_eq!(st, 200, "{epochs}");
    let epochs = epochs["items"].as_array().expect("epoch list");
    assert_eq!(epochs.len(), 6);
    for e in epochs {
        let off = seconds_off(&e["created_at"]);
        assert!(
            off.abs() <= 60,
            "epoch {} was stamped created_at {} ({off} s off the true time)",
            e["id"],
            e["created_at"]
        );
    }

    let alerts = site_alerts(&ahead, SITE).await;
    let alert = alerts
        .iter()
        .find(|a| a["rule"] == "displacement_mm")
        .unwrap_or_else(|| panic!("no displacement alert: {alerts:?}"))
        .clone();
    let raised = seconds_off(&alert["raised_at"]);
    assert!(
        raised.abs() <= 60,
        "raised_at {} is {raised} s off the true time",
        alert["raised_at"]
    );
    // One time per upload: the alert was raised when its epoch was stored.
    let raising = epochs
        .iter()
        .find(|e| e["id"] == alert["epoch"])
        .unwrap_or_else(|| panic!("the raising epoch {} is listed", alert["epoch"]));
    assert_eq!(
        shown_time(&raising["created_at"]),
        shown_time(&alert["raised_at"]),
        "epoch {} stored at {}, its alert raised at {}",
        raising["id"],
        raising["created_at"],
        alert["raised_at"]
    );
    let id = alert["id"].as_str().unwrap();
    let (st, acked) = ahead
        .send(
            Method::POST,
            &format!("/api/v1/alerts/{id}/ack"),
            Some(&json!({"by": "on duty"})),
        )
        .await;
    assert_eq!(st, 200, "{acked}");
    let alert = site_alerts(&behind, SITE)
        .await
        .into_iter()
        .find(|a| a["id"] == id)
        .expect("the alert is listed");
    assert_eq!(alert["state"], "acknowledged");
    let updated = seconds_off(&alert["updated_at"]);
    assert!(
        updated.abs() <= 60 && shown_time(&alert["updated_at"]) >= shown_time(&alert["raised_at"]),
        "acknowledged at {} ({updated} s off the true time), raised at {}",
        alert["updated_at"],
        alert["raised_at"]
    );
    ahead.kill9();
    behind.kill9();
}
