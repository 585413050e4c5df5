//! Load and crash benchmark of the daemon as a deployment meets it (figures in
//! `docs/performance.md`, section "Load"): `cargo bench --bench load [-- SECONDS]`.
//!
//! 1. **Load:** the release binary (`cliffwatch serve`, a separate process, SQLite) with 20
//!    sites; 20 uploaders, one per site, each posting 4-station × 16-target epochs back to back,
//!    and 50 readers cycling through the pages and API reads staff and scripts make (site page,
//!    point list, incidents, alerts, a point's series, metrics), for SECONDS (default 60). Per
//!    route: requests, 5xx, other refusals, p50 and p99 latency.
//! 2. **kill -9:** 20 uploads at once, the daemon killed with SIGKILL 1 s into the burst, started
//!    again on the same data: every upload answered 201 before the kill is there, every stored
//!    epoch reads back whole (its report and its points), and the database passes SQLite's
//!    `integrity_check`. SQLite only.

#[path = "../tests/support/mod.rs"]
mod support;

use std::collections::BTreeMap;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use reqwest::Method;
use serde_json::json;
use support::alerts::write_config;
use support::server::{synthetic_epoch, Daemon};

const SITES: usize = 20;
const READERS: usize = 50;
const POINTS: usize = 16;
const STABLE: usize = 8;

/// A read: its route's name and the path it asks for of site `k`.
type Read = (&'static str, fn(usize) -> String);

/// `(route, status, latency)` of every request.
type Log = Arc<Mutex<Vec<(&'static str, u16, Duration)>>>;

fn observed_at(k: usize) -> String {
    (chrono::DateTime::parse_from_rfc3339("2026-01-01T00:00:00Z").unwrap()
        + chrono::Duration::hours(k as i64))
    .to_rfc3339_opts(chrono::SecondsFormat::Secs, true)
}

/// Epoch `k` of site `s`: 4 stations, the block moving 0.3 mm an epoch.
fn epoch(s: usize, k: usize) -> serde_json::Value {
    synthetic_epoch(
        4,
        POINTS,
        &observed_at(k),
        (s * 10_000 + k) as u64,
        0.3 * k as f64,
        STABLE,
    )
}

async fn timed(
    client: &reqwest::Client,
    method: Method,
    url: String,
    body: Option<&serde_json::Value>,
) -> (u16, Duration) {
    let start = Instant::now();
    let mut rq = client.request(method, url);
    if let Some(b) = body {
        rq = rq.json(b);
    }
    let status = match rq.send().await {
        Ok(r) => {
            let s = r.status().as_u16();
            let _ = r.bytes().await;
            s
        }
        Err(_) => 599,
    };
    (status, start.elapsed())
}

async fn setup_sites(d: &Daemon) {
    for s in 0..SITES {
        let (st, b) = d
            .send(
                Method::POST,
                "/api/v1/sites",
                Some(&json!({"id": format!("s{s}"), "alert_rules": [
                    {"level": "watch", "metric": "displacement_mm", "above": 5.0, "clear_below": 4.0},
                    {"level": "warning", "metric": "velocity_mm_per_day", "above": 1.0}]})),
            )
            .await;
        assert_eq!(st, 201, "{b}");
        for i in 0..STABLE {
            d.send(
                Method::PUT,
                &format!("/api/v1/sites/s{s}/points/T{:03}", i + 1),
                Some(&json!({"role": "stable"})),
            )
            .await;
        }
    }
}

fn percentile(sorted: &[Duration], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let i = ((sorted.len() as f64 - 1.0) * p).round() as usize;
    sorted[i].as_secs_f64() * 1000.0
}

async fn load(seconds: u64) {
    let dir = tempfile::tempdir().unwrap();
    let config = write_config(dir.path(), "");
    let d = Daemon::start(&dir.path().join("data"), &config).await;
    setup_sites(&d).await;
    let base = d.base.clone();
    let log: Log = Arc::default();
    let end = Instant::now() + Duration::from_secs(seconds);
    let mut tasks = vec![];
    for s in 0..SITES {
        let (log, base) = (log.clone(), base.clone());
        tasks.push(tokio::spawn(async move {
            let client = reqwest::Client::new();
            let mut k = 0;
            while Instant::now() < end {
                let body = epoch(s, k);
                let url = format!("{base}/api/v1/sites/s{s}/epochs");
                let (st, t) = timed(&client, Method::POST, url, Some(&body)).await;
                log.lock()
                    .unwrap()
                    .push(("POST /api/v1/sites/{site}/epochs", st, t));
                k += 1;
            }
        }));
    }
    let reads: [Read; 6] = [
        ("GET /sites/{site} (page)", |s| format!("/sites/s{s}")),
        ("GET /api/v1/sites/{site}/points", |s| {
            format!("/api/v1/sites/s{s}/points")
        }),
        ("GET /api/v1/sites/{site}/incidents", |s| {
            format!("/api/v1/sites/s{s}/incidents")
        }),
        ("GET /api/v1/alerts?site=", |s| {
            format!("/api/v1/alerts?site=s{s}")
        }),
        ("GET .../points/{point}/displacements", |s| {
            format!("/api/v1/sites/s{s}/points/T012/displacements")
        }),
        ("GET /metrics", |_| "/metrics".to_string()),
    ];
    for r in 0..READERS {
        let (log, base) = (log.clone(), base.clone());
        tasks.push(tokio::spawn(async move {
            let client = reqwest::Client::new();
            let mut k = r;
            while Instant::now() < end {
                let (route, path) = reads[k % reads.len()];
                let (st, t) = timed(
                    &client,
                    Method::GET,
                    format!("{base}{}", path(k % SITES)),
                    None,
                )
                .await;
                log.lock().unwrap().push((route, st, t));
                k += 7;
            }
        }));
    }
    for t in tasks {
        t.await.unwrap();
    }
    let log = log.lock().unwrap().clone();
    let mut by_route: BTreeMap<&str, Vec<(u16, Duration)>> = BTreeMap::new();
    for (route, st, t) in &log {
        by_route.entry(route).or_default().push((*st, *t));
    }
    println!("\nLoad: {SITES} uploaders, {READERS} readers, {seconds} s, SQLite, release binary");
    println!("| route | requests | 5xx | other non-2xx | p50 (ms) | p99 (ms) |");
    println!("|---|---|---|---|---|---|");
    let (mut all, mut all5) = (0, 0);
    for (route, rows) in &by_route {
        let mut lat: Vec<Duration> = rows.iter().map(|r| r.1).collect();
        lat.sort();
        let five = rows.iter().filter(|r| r.0 >= 500).count();
        let other = rows.iter().filter(|r| r.0 >= 300 && r.0 < 500).count();
        all += rows.len();
        all5 += five;
        println!(
            "| `{route}` | {} | {five} | {other} | {:.1} | {:.1} |",
            rows.len(),
            percentile(&lat, 0.5),
            percentile(&lat, 0.99)
        );
    }
    println!("| all | {all} | {all5} | | | |");
    let statuses: BTreeMap<u16, usize> = log.iter().fold(BTreeMap::new(), |mut m, r| {
        *m.entry(r.1).or_default() += 1;
        m
    });
    println!("statuses: {statuses:?}");
}

async fn kill9() {
    let dir = tempfile::tempdir().unwrap();
    let config = write_config(dir.path(), "");
    let data = dir.path().join("data");
    let d = Daemon::start(&data, &config).await;
    setup_sites(&d).await;
    let base = d.base.clone();
    let mut tasks = vec![];
    for s in 0..SITES {
        let base = base.clone();
        tasks.push(tokio::spawn(async move {
            let client = reqwest::Client::new();
            let mut acknowledged = vec![];
            for k in 0..1000 {
                let body = epoch(s, k);
                match client
                    .post(format!("{base}/api/v1/sites/s{s}/epochs"))
                    .json(&body)
                    .send()
                    .await
                {
                    Ok(r) if r.status().as_u16() == 201 => acknowledged.push(observed_at(k)),
                    _ => break,
                }
            }
            (s, acknowledged)
        }));
    }
    tokio::time::sleep(Duration::from_secs(1)).await;
    d.kill9();
    let mut acknowledged = vec![];
    for t in tasks {
        acknowledged.push(t.await.unwrap());
    }
    let d = Daemon::start(&data, &config).await;
    let (mut missing, mut stored, mut unreadable) = (0, 0, 0);
    for (s, acked) in &acknowledged {
        let (_, list) = d
            .get(&format!("/api/v1/sites/s{s}/epochs?limit=1000"))
            .await;
        let items = list["items"].as_array().cloned().unwrap_or_default();
        stored += items.len();
        for at in acked {
            if !items
                .iter()
                .any(|e| e["observed_at"].as_str() == Some(at.as_str()))
            {
                missing += 1;
            }
        }
        for e in &items {
            let (st, report) = d
                .get(&format!("/api/v1/sites/s{s}/epochs/{}", e["id"]))
                .await;
            let points = report["points"].as_array().map_or(0, Vec::len);
            if st != 200 || points != POINTS {
                unreadable += 1;
            }
        }
    }
    let acked: usize = acknowledged.iter().map(|(_, a)| a.len()).sum();
    drop(d);
    let check: String = {
        use sqlx::ConnectOptions;
        let mut conn = sqlx::sqlite::SqliteConnectOptions::new()
            .filename(data.join("cliffwatch.db"))
            .read_only(true)
            .connect()
            .await
            .unwrap();
        sqlx::query_scalar("PRAGMA integrity_check")
            .fetch_one(&mut conn)
            .await
            .unwrap()
    };
    println!(
        "\nkill -9 one second into 20 concurrent upload streams, then a restart on the same data:"
    );
    println!("- answered 201 before the kill: {acked}; missing after the restart: {missing}");
    println!(
        "- epochs stored: {stored}; not readable whole (report and {POINTS} points): {unreadable}"
    );
    println!("- PRAGMA integrity_check: {check}");
}

fn main() {
    let seconds: u64 = std::env::args()
        .skip(1)
        .find_map(|a| a.parse().ok())
        .unwrap_or(60);
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap();
    rt.block_on(load(seconds));
    rt.block_on(kill9());
}
