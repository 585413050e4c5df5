//! Several daemons on one PostgreSQL database (`support::pg`'s throwaway cluster), checked against
//! one SQLite daemon fed the same uploads:
//! - 20 concurrent uploaders across 3 nodes and 5 sites: no lost or duplicated epoch, no 5xx, and
//!   every site's series equal to a sequential single-node run;
//! - two nodes taking a 40-epoch series alternately, one killed with SIGKILL mid-upload and
//!   restarted: both serve the single node's series, the webhooks announce the same alert events,
//!   and no `webhook-id` is delivered twice except what the killed node had in flight.

use crate::support;

use std::collections::{BTreeMap, BTreeSet, VecDeque};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use reqwest::{Client, Method};
use serde_json::{json, Value};
use support::alerts::Receiver;
use support::server::{synthetic_epoch, Daemon, TestServer};

/// Targets of each site; the first `STABLE` never move, the others are block B1.
const POINTS: usize = 16;
const STABLE: usize = 8;
/// The block moves `STEP_MM` a day towards the cameras.
const STEP_MM: f64 = 1.5;

fn name(i: usize) -> String {
    format!("T{:03}", i + 1)
}

fn site_id(s: usize) -> String {
    format!("cliff-{}", s + 1)
}

/// Epoch `k` of site `s`: day `k`, its own noise.
pub(super) fn epoch(s: usize, k: usize) -> Value {
    synthetic_epoch(
        4,
        POINTS,
        &support::alerts::day(k),
        10_000 * s as u64 + k as u64,
        STEP_MM * k as f64,
        STABLE,
    )
}

async fn send(
    client: &Client,
    base: &str,
    method: Method,
    path: &str,
    body: Option<&Value>,
) -> Result<(u16, Value), reqwest::Error> {
    let mut rq = client.request(method, format!("{base}{path}"));
    if let Some(b) = body {
        rq = rq.json(b);
    }
    let r = rq.send().await?;
    let status = r.status().as_u16();
    Ok((status, r.json().await.unwrap_or(Value::Null)))
}

pub(super) async fn call(
    client: &Client,
    base: &str,
    method: Method,
    path: &str,
    body: Value,
) -> Value {
    let (st, b) = send(client, base, method.clone(), path, Some(&body))
        .await
        .unwrap();
    assert!((200..300).contains(&st), "{method} {path}: {st} {b}");
    b
}

/// A site with the contract's displacement rules, 8 stable points and block B1.
pub(super) async fn set_up_site(client: &Client, base: &str, site: &str) {
    let rules = json!([
        {"level": "watch", "metric": "displacement_mm", "above": 5.0, "clear_below": 4.0},
        {"level": "warning", "metric": "displacement_mm", "above": 10.0},
        {"level": "alarm", "metric": "displacement_mm", "above": 20.0}]);
    call(
        client,
        base,
        Method::POST,
        "/api/v1/sites",
        json!({"id": site, "name": site, "alert_rules": rules}),
    )
    .await;
    for i in 0..STABLE {
        let path = format!("/api/v1/sites/{site}/points/{}", name(i));
        call(client, base, Method::PUT, &path, json!({"role": "stable"})).await;
    }
    let block: Vec<String> = (STABLE..POINTS).map(name).collect();
    call(
        client,
        base,
        Method::PUT,
        &format!("/api/v1/sites/{site}/groups/B1"),
        json!({"kind": "block", "direction": [0.0, -1.0, 0.0], "points": block}),
    )
    .await;
}

/// Every displacement series of a site (each point's and the block's), rows without epoch ids
/// (ids follow arrival order, which differs between runs; `observed_at` identifies the row), and
/// each point's plot data.
async fn series(client: &Client, base: &str, site: &str) -> BTreeMap<String, Value> {
    let mut out = BTreeMap::new();
    let mut paths: Vec<String> = (0..POINTS)
        .map(|i| format!("/api/v1/sites/{site}/points/{}/displacements", name(i)))
        .collect();
    paths.push(format!("/api/v1/sites/{site}/groups/B1/motion"));
    for path in paths {
        let (st, mut b) = send(
            client,
            base,
            Method::GET,
            &format!("{path}?limit=1000"),
            None,
        )
        .await
        .unwrap();
        assert_eq!(st, 200, "{path}: {b}");
        for row in b["items"].as_array_mut().unwrap() {
            let row = row.as_object_mut().unwrap();
            row.remove("epoch");
            row.remove("reference_epoch");
        }
        out.insert(path, b["items"].take());
    }
    // the dashboard's plot data of every point (read through the same series path), without
    // epoch ids and alert events (ids and wall-clock times)
    for i in 0..POINTS {
        let path = format!("/dashboard/plot/{site}/{}?width=100", name(i));
        let (st, mut b) = send(client, base, Method::GET, &path, None).await.unwrap();
        assert_eq!(st, 200, "{path}: {b}");
        let plot = b.as_object_mut().unwrap();
        assert!(plot["total"].as_u64().unwrap() > 0, "{path}: {b}");
        plot.remove("epoch");
        plot.remove("events");
        out.insert(path, b);
    }
    out
}

/// Equal as JSON, numbers within `tol` relative (the adjustments of a series uploaded out of
/// order start from other approximations and converge to the same optimum, not the same bits).
fn same(a: &Value, b: &Value, tol: f64) -> bool {
    match (a, b) {
        (Value::Number(x), Value::Number(y)) => {
            let (x, y) = (x.as_f64().unwrap(), y.as_f64().unwrap());
            (x - y).abs() <= tol * (1.0 + x.abs().max(y.abs()))
        }
        (Value::Array(x), Value::Array(y)) => {
            x.len() == y.len() && x.iter().zip(y).all(|(p, q)| same(p, q, tol))
        }
        (Value::Object(x), Value::Object(y)) => {
            x.len() == y.len()
                && x.iter()
                    .all(|(k, v)| y.get(k).is_some_and(|w| same(v, w, tol)))
        }
        _ => a == b,
    }
}

fn assert_same_series(
    what: &str,
    have: &BTreeMap<String, Value>,
    want: &BTreeMap<String, Value>,
    tol: f64,
) {
    assert_eq!(have.len(), want.len(), "{what}");
    for (path, w) in want {
        let h = &have[path];
        assert!(
            same(h, w, tol),
            "{what}: {path} differs\nhave {h}\nwant {w}"
        );
    }
}

/// Observation times of a site's epochs as a node serves them.
async fn epoch_times(client: &Client, base: &str, site: &str) -> Vec<String> {
    let (st, b) = send(
        client,
        base,
        Method::GET,
        &format!("/api/v1/sites/{site}/epochs?limit=1000"),
        None,
    )
    .await
    .unwrap();
    assert_eq!(st, 200, "{b}");
    let mut t: Vec<String> = b["items"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| e["observed_at"].as_str().unwrap().to_string())
        .collect();
    t.sort();
    t
}

/// One upload's answer: site, epoch, status, body.
type Answer = (usize, usize, u16, Value);

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn twenty_uploaders_three_nodes_five_sites() {
    const SITES: usize = 5;
    const EPOCHS: usize = 10;
    const UPLOADERS: usize = 20;
    let cluster = support::pg::PgCluster::start();
    let url = cluster.create_database("uploaders");
    let mut nodes = Vec::new();
    for _ in 0..3 {
        let url = url.clone();
        nodes.push(TestServer::start(move |c| c.database_url = Some(url)).await);
    }
    let client = Client::new();
    for s in 0..SITES {
        set_up_site(&client, &nodes[s % 3].base, &site_id(s)).await;
    }
    // Each site's epochs in time order, sites interleaved; epoch 3 of every site twice.
    let mut jobs: VecDeque<(usize, usize)> = VecDeque::new();
    for k in 0..EPOCHS {
        for s in 0..SITES {
            jobs.push_back((s, k));
            if k == 4 {
                jobs.push_back((s, 3));
            }
        }
    }
    let jobs = Arc::new(Mutex::new(jobs));
    let results: Arc<Mutex<Vec<Answer>>> = Arc::default();
    let bases: Vec<String> = nodes.iter().map(|n| n.base.clone()).collect();
    let mut tasks = Vec::new();
    for u in 0..UPLOADERS {
        let (jobs, results, base, client) = (
            jobs.clone(),
            results.clone(),
            bases[u % 3].clone(),
            client.clone(),
        );
        tasks.push(tokio::spawn(async move {
            loop {
                let Some((s, k)) = jobs.lock().unwrap().pop_front() else {
                    break;
                };
                let path = format!("/api/v1/sites/{}/epochs", site_id(s));
                let (st, b) = send(&client, &base, Method::POST, &path, Some(&epoch(s, k)))
                    .await
                    .expect("the node answers");
                results.lock().unwrap().push((s, k, st, b));
            }
        }));
    }
    for t in tasks {
        t.await.unwrap();
    }
    let results = results.lock().unwrap().clone();
    assert_eq!(results.len(), SITES * (EPOCHS + 1));
    let mut ids: BTreeMap<(usize, usize), Vec<(u16, Value)>> = BTreeMap::new();
    for (s, k, st, b) in results {
        assert!(st == 200 || st == 201, "{} epoch {k}: {st} {b}", site_id(s));
        ids.entry((s, k))
            .or_default()
            .push((st, b["epoch"].clone()));
    }
    for ((s, k), answers) in &ids {
        let created = answers.iter().filter(|(st, _)| *st == 201).count();
        assert_eq!(created, 1, "{} epoch {k}: {answers:?}", site_id(*s));
        assert!(
            answers.iter().all(|(_, e)| *e == answers[0].1),
            "{} epoch {k}: {answers:?}",
            site_id(*s)
        );
    }

    // The same uploads, one at a time in time order, on one SQLite node.
    let single = TestServer::start(|_| {}).await;
    for s in 0..SITES {
        set_up_site(&client, &single.base, &site_id(s)).await;
        for k in 0..EPOCHS {
            assert_eq!(single.upload(&site_id(s), &epoch(s, k)).await.0, 201);
        }
    }
    let expected_times: Vec<String> = (0..EPOCHS).map(support::alerts::day).collect();
    for s in 0..SITES {
        let site = site_id(s);
        let want = series(&client, &single.base, &site).await;
        for (path, rows) in &want {
            // Points and the block's motion alike have a row at the reference epoch.
            let n = EPOCHS;
            let n_rows = match rows {
                Value::Array(a) => a.len(),
                plot => plot["t"].as_array().unwrap().len(),
            };
            assert_eq!(n_rows, n, "{path}");
        }
        let first = series(&client, &bases[0], &site).await;
        for (n, base) in bases.iter().enumerate() {
            assert_eq!(
                epoch_times(&client, base, &site).await,
                expected_times,
                "{site} on node {n}"
            );
            let have = series(&client, base, &site).await;
            assert_same_series(&format!("{site}, node {n} vs node 0"), &have, &first, 0.0);
            assert_same_series(
                &format!("{site}, node {n} vs one SQLite node"),
                &have,
                &want,
                1e-6,
            );
        }
    }
    for n in nodes {
        n.stop().await;
    }
    single.stop().await;
}

/// A daemon's configuration: the database, fast webhook retries, a short delivery time limit
/// (the lease of a claimed delivery is 4 × 1 s + 5 s), due deliveries looked for every 50 ms.
fn node_config(dir: &std::path::Path, database_url: Option<&str>) -> std::path::PathBuf {
    polling_node_config(dir, database_url, 50)
}

/// [`node_config`], due deliveries looked for every `poll_ms`.
pub(super) fn polling_node_config(
    dir: &std::path::Path,
    database_url: Option<&str>,
    poll_ms: u64,
) -> std::path::PathBuf {
    let path = dir.join("cliffwatch.toml");
    let db = database_url
        .map(|u| format!("database_url = \"{u}\"\n"))
        .unwrap_or_default();
    std::fs::write(
        &path,
        format!(
            "{db}webhook_poll_ms = {poll_ms}\nwebhook_timeout_secs = 1\n\
             [webhook_retry]\nbase_seconds = 0.2\nmax_delay_seconds = 1.0\nmax_attempts = 50\n"
        ),
    )
    .unwrap();
    path
}

/// Pending deliveries of a database.
pub(super) async fn pending(url: &str) -> i64 {
    let pool = sqlx::any::AnyPoolOptions::new()
        .max_connections(1)
        .connect(url)
        .await
        .unwrap();
    let n = sqlx::query_scalar("SELECT COUNT(*) FROM webhook_deliveries WHERE state = 'pending'")
        .fetch_one(&pool)
        .await
        .unwrap();
    pool.close().await;
    n
}

/// Waits until nothing is pending in database `url`, at most `limit`; returns how long that took.
pub(super) async fn until_delivered(url: &str, limit: Duration) -> Duration {
    let start = Instant::now();
    while pending(url).await > 0 {
        assert!(
            start.elapsed() < limit,
            "deliveries still pending in {url} after {limit:?}"
        );
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    start.elapsed()
}

/// The alert events a receiver accepted, without ids and wall-clock times.
fn events(r: &Receiver) -> BTreeSet<String> {
    r.accepted()
        .values()
        .map(|b| {
            let d = &b["data"];
            format!(
                "{} {} {} {} {} {} {}",
                b["type"],
                d["site"],
                d["point"],
                d["group"],
                d["level"],
                d["rule"],
                d["observed_at"]
            )
        })
        .collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn a_node_killed_mid_series_changes_nothing() {
    const EPOCHS: usize = 40;
    const KILL_AT: usize = 20;
    const SITE: &str = "cliff-1";
    sqlx::any::install_default_drivers();
    let cluster = support::pg::PgCluster::start();
    let url = cluster.create_database("killed");
    let dirs: Vec<tempfile::TempDir> = (0..3).map(|_| tempfile::tempdir().unwrap()).collect();
    let shared = node_config(dirs[0].path(), Some(&url));
    let sqlite_config = node_config(dirs[2].path(), None);
    let mut a = Some(Daemon::start(dirs[0].path(), &shared).await);
    let b = Daemon::start(dirs[1].path(), &shared).await;
    let single = Daemon::start(dirs[2].path(), &sqlite_config).await;
    let (to_nodes, to_single) = (Receiver::start(3).await, Receiver::start(3).await);
    let client = Client::new();
    for (base, rx) in [
        (&a.as_ref().unwrap().base, &to_nodes),
        (&single.base, &to_single),
    ] {
        set_up_site(&client, base, SITE).await;
        call(
            &client,
            base,
            Method::POST,
            "/api/v1/webhooks",
            json!({"url": rx.url, "secret": support::alerts::SECRET, "min_level": "watch"}),
        )
        .await;
    }
    let path = format!("/api/v1/sites/{SITE}/epochs");
    for k in 0..EPOCHS {
        let body = epoch(0, k);
        let (st, r) = send(&client, &single.base, Method::POST, &path, Some(&body))
            .await
            .unwrap();
        assert_eq!(st, 201, "single node, epoch {k}: {r}");
        if k == KILL_AT {
            // SIGKILL while the upload is in flight; the client sends it again to the other
            // node, as behind a load balancer.
            let node_a = a.take().unwrap();
            let (c, base, p, bd) = (
                client.clone(),
                node_a.base.clone(),
                path.clone(),
                body.clone(),
            );
            let inflight =
                tokio::spawn(async move { send(&c, &base, Method::POST, &p, Some(&bd)).await });
            tokio::time::sleep(Duration::from_millis(3)).await;
            node_a.kill9();
            let answer = inflight.await.unwrap();
            eprintln!(
                "the killed node's in-flight upload: {:?}",
                answer.map(|(st, _)| st)
            );
            let (st, r) = send(&client, &b.base, Method::POST, &path, Some(&body))
                .await
                .unwrap();
            assert!(st == 200 || st == 201, "epoch {k} again: {st} {r}");
            a = Some(Daemon::start(dirs[0].path(), &shared).await);
            continue;
        }
        let node = if k % 2 == 0 { a.as_ref().unwrap() } else { &b };
        let (st, r) = send(&client, &node.base, Method::POST, &path, Some(&body))
            .await
            .unwrap();
        assert_eq!(st, 201, "epoch {k}: {r}");
    }
    let a = a.unwrap();
    // Each node labels its metrics with its name (default: host name and port).
    let port = b.base.rsplit(':').next().unwrap();
    let metrics = client
        .get(format!("{}/metrics", b.base))
        .send()
        .await
        .unwrap()
        .text()
        .await
        .unwrap();
    assert!(
        metrics.lines().any(
            |l| l.starts_with("cliffwatch_uploads_total{") && l.contains(&format!(":{port}\""))
        ),
        "{metrics}"
    );
    let want = series(&client, &single.base, SITE).await;
    for (n, base) in [("restarted", &a.base), ("survivor", &b.base)] {
        assert_eq!(epoch_times(&client, base, SITE).await.len(), EPOCHS, "{n}");
        let have = series(&client, base, SITE).await;
        assert_same_series(&format!("{n} node vs one SQLite node"), &have, &want, 1e-12);
    }

    let sqlite_url = format!(
        "sqlite://{}/cliffwatch.db?mode=ro",
        dirs[2].path().display()
    );
    until_delivered(&url, Duration::from_secs(90)).await;
    until_delivered(&sqlite_url, Duration::from_secs(90)).await;
    let (have, want) = (events(&to_nodes), events(&to_single));
    assert!(
        want.iter().any(|e| e.contains("\"alarm\"")),
        "the block reaches alarm: {want:?}"
    );
    assert_eq!(have, want, "alert events announced by webhook");
    // Each message once; a message sent twice only from the killed node's claim (at most the 4
    // deliveries one claim takes), with the same id and the same bytes.
    let log = to_nodes.log.lock().unwrap().clone();
    let mut bodies: BTreeMap<String, Vec<Vec<u8>>> = BTreeMap::new();
    for r in log.iter().filter(|r| r.accepted) {
        bodies.entry(r.id.clone()).or_default().push(r.raw.clone());
    }
    let twice: Vec<&String> = bodies
        .iter()
        .filter(|(_, v)| v.len() > 1)
        .map(|(k, _)| k)
        .collect();
    assert!(twice.len() <= 4, "delivered more than once: {twice:?}");
    for (id, v) in &bodies {
        assert!(v.len() <= 2, "{id} delivered {} times", v.len());
        assert!(v.iter().all(|x| *x == v[0]), "{id}: retries differ");
    }
    assert_eq!(
        to_nodes
            .bad_signatures
            .load(std::sync::atomic::Ordering::SeqCst),
        0
    );
}
