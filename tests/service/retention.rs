//! Observation retention: a daemon started with `observation_retention_days` deletes the image
//! observations of the epochs older than that (its pass at start) and nothing else. The series,
//! the site and the alerts answer as before, an upload of a pruned epoch's body is still known,
//! and the epoch says when its observations went.

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

use chrono::{SecondsFormat, Utc};
use serde_json::Value;

use crate::support::server::{synthetic_epoch, TestServer};

const SITE: &str = "ledge";
const POINTS: usize = 12;

/// The epochs: two years ago (pruned by a 30-day retention) and one an hour ago (kept).
fn bodies() -> Vec<Value> {
    let recent =
        (Utc::now() - chrono::Duration::hours(1)).to_rfc3339_opts(SecondsFormat::Secs, true);
    [
        "2024-06-01T09:00:00Z",
        "2024-06-02T09:00:00Z",
        recent.as_str(),
    ]
    .iter()
    .enumerate()
    .map(|(k, t)| synthetic_epoch(4, POINTS, t, 700 + k as u64, 4.0 * k as f64, 6))
    .collect()
}

/// What a user reads of the site, by request: the site, its epochs' list and details, every
/// point's series (JSON and CSV), the alerts.
async fn answers(s: &TestServer) -> BTreeMap<String, Value> {
    let mut paths = vec![
        format!("/api/v1/sites/{SITE}"),
        format!("/api/v1/sites/{SITE}/epochs?limit=100"),
        format!("/api/v1/alerts?site={SITE}&limit=1000"),
    ];
    let (_, list) = s.get(&paths[1]).await;
    for e in list["items"].as_array().unwrap() {
        paths.push(format!("/api/v1/sites/{SITE}/epochs/{}", e["id"]));
    }
    for i in 0..POINTS {
        paths.push(format!(
            "/api/v1/sites/{SITE}/points/T{:03}/displacements?limit=1000",
            i + 1
        ));
    }
    let mut out = BTreeMap::new();
    for path in paths {
        let (st, v) = s.get(&path).await;
        assert_eq!(st, 200, "{path}: {v}");
        out.insert(path, v);
    }
    for i in 0..POINTS {
        let path = format!(
            "/api/v1/sites/{SITE}/points/T{:03}/displacements?format=csv",
            i + 1
        );
        let r = s.client.get(s.url(&path)).send().await.unwrap();
        assert_eq!(r.status(), 200, "{path}");
        out.insert(path, Value::String(r.text().await.unwrap()));
    }
    out
}

/// Observation rows per epoch id.
async fn observation_rows(s: &TestServer) -> BTreeMap<i64, i64> {
    let rows: Vec<(i64, i64)> =
        sqlx::query_as("SELECT epoch_id, COUNT(*) FROM observations GROUP BY epoch_id")
            .fetch_all(s.store.reader())
            .await
            .unwrap();
    rows.into_iter().collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn old_epochs_lose_their_observations_and_nothing_else() {
    let dir = tempfile::tempdir().unwrap();
    let url = format!("sqlite://{}", dir.path().join("kept.db").display());
    let u = url.clone();
    let first = TestServer::start(move |c| c.database_url = Some(u)).await;
    first.create_site(SITE).await;
    let bodies = bodies();
    let mut ids = vec![];
    for body in &bodies {
        let (st, b) = first.upload(SITE, body).await;
        assert_eq!(st, 201, "{b}");
        ids.push(b["id"].as_i64().unwrap());
    }
    let before = answers(&first).await;
    let rows_before = observation_rows(&first).await;
    assert_eq!(rows_before.len(), 3, "{rows_before:?}");
    first.stop().await;

    // The same database under a daemon that keeps observations 30 days: its pass at start.
    let u = url.clone();
    let second = TestServer::start(move |c| {
        c.database_url = Some(u);
        c.observation_retention_days = 30;
    })
    .await;
    let list_path = format!("/api/v1/sites/{SITE}/epochs?limit=100");
    let start = Instant::now();
    let list = loop {
        let (_, list) = second.get(&list_path).await;
        let pruned = list["items"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|e| e["observations_pruned_at"].is_string())
            .count();
        if pruned == 2 {
            break list;
        }
        assert!(
            start.elapsed() < Duration::from_secs(30),
            "the pass at start pruned {pruned} epochs: {list}"
        );
        tokio::time::sleep(Duration::from_millis(100)).await;
    };
    let after = answers(&second).await;

    // The rows: the two old epochs' observations gone, the recent one's all there.
    let rows_after = observation_rows(&second).await;
    assert_eq!(
        rows_after,
        BTreeMap::from([(ids[2], rows_before[&ids[2]])]),
        "before: {rows_before:?}"
    );
    // Each epoch says whether its observations went, when (the pass ran within the test), and
    // the detail lists no residuals for the pruned ones.
    let t0 = Utc::now() - chrono::Duration::minutes(10);
    for item in list["items"].as_array().unwrap() {
        let id = item["id"].as_i64().unwrap();
        let detail = &after[&format!("/api/v1/sites/{SITE}/epochs/{id}")];
        let residuals = detail["residuals"].as_array().unwrap();
        if id == ids[2] {
            assert!(item["observations_pruned_at"].is_null(), "{item}");
            assert_eq!(residuals.len() as i64, rows_before[&id], "{detail}");
        } else {
            let when = item["observations_pruned_at"].as_str().unwrap();
            let when = chrono::DateTime::parse_from_rfc3339(when).unwrap();
            assert!(when > t0 && when <= Utc::now(), "{item}");
            assert!(residuals.is_empty(), "{detail}");
            assert_eq!(
                detail["observations_pruned_at"],
                item["observations_pruned_at"]
            );
        }
    }
    // Everything else answers as before: the series (JSON and CSV), the site, the alerts, and
    // each epoch's detail but for the residuals and the new field.
    for (path, want) in &before {
        let mut have = after[path].clone();
        let mut want = want.clone();
        if path.contains("/epochs") {
            for v in [&mut have, &mut want] {
                strip_pruned(v);
            }
        }
        assert_eq!(have, want, "{path} changed");
    }
    // The pruned epoch's body is still known: the same again is the stored epoch, another body
    // for its time a conflict.
    let (st, b) = second.upload(SITE, &bodies[0]).await;
    assert_eq!((st, b["id"].as_i64()), (200, Some(ids[0])), "{b}");
    let other = synthetic_epoch(4, POINTS, "2024-06-01T09:00:00Z", 999, 0.0, 6);
    assert_eq!(second.upload(SITE, &other).await.0, 409);
    // A second pass finds nothing left to delete.
    let keep = Duration::from_secs(30 * 86_400);
    let again = cliffwatch::workers::retention::prune_observations(&second.store, keep, Utc::now())
        .await
        .unwrap();
    assert_eq!(again, 0);
    // The dashboard's epoch page says why the residual plots are missing.
    for (id, pruned) in [(ids[0], true), (ids[2], false)] {
        let r = second
            .client
            .get(second.url(&format!("/sites/{SITE}/epochs/{id}")))
            .send()
            .await
            .unwrap();
        assert_eq!(r.status(), 200);
        let html = r.text().await.unwrap();
        assert_eq!(
            html.contains("observations of this epoch were deleted"),
            pruned,
            "epoch {id}"
        );
        assert_eq!(html.contains("class=\"residual\""), !pruned, "epoch {id}");
    }
    second.stop().await;
}

/// Removes the retention's traces from an epoch list or detail: `observations_pruned_at`, and
/// the residuals.
fn strip_pruned(v: &mut Value) {
    match v {
        Value::Object(m) => {
            m.remove("observations_pruned_at");
            m.remove("residuals");
            for (_, x) in m.iter_mut() {
                strip_pruned(x);
            }
        }
        Value::Array(a) => a.iter_mut().for_each(strip_pruned),
        _ => {}
    }
}

/// Sets the modification time of `path` (file or folder) `days` days back.
fn age(path: &std::path::Path, days: u64) {
    let t = std::time::SystemTime::now() - Duration::from_secs(days * 86_400);
    std::fs::File::open(path).unwrap().set_modified(t).unwrap();
}

/// A folder holding one image, all of it last written `days` days ago.
fn old_folder(path: &std::path::Path, days: u64) {
    std::fs::create_dir_all(path).unwrap();
    std::fs::write(path.join("S1.jpg"), b"jpeg").unwrap();
    age(&path.join("S1.jpg"), days);
    age(path, days);
}

/// A daemon watching a directory with `watch_done_retention_days = 30` deletes, in its pass at
/// start, the taken folder last written 40 days ago, and keeps, through the whole pass, the one
/// of 10 days, the failed folder and the folder not yet taken.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn old_taken_folders_of_the_watched_directory_go() {
    let watch = tempfile::tempdir().unwrap();
    let site = watch.path().join(SITE);
    let (old, recent) = (site.join(".done/2024-06-01"), site.join(".done/2026-11-20"));
    let (failed, waiting) = (site.join(".failed/2024-06-02"), site.join("2024-06-03"));
    old_folder(&old, 40);
    old_folder(&recent, 10);
    old_folder(&failed, 40);
    old_folder(&waiting, 40);
    let dir = watch.path().to_path_buf();
    let server = TestServer::start(move |c| {
        c.watch_dir = Some(dir);
        c.watch_done_retention_days = 30;
    })
    .await;
    let start = Instant::now();
    while old.exists() {
        assert!(
            start.elapsed() < Duration::from_secs(30),
            "{} still there",
            old.display()
        );
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    // Stopping waits for the retention's pass to end, so a folder it would delete after the
    // old one is gone too before the folders are looked at.
    server.stop().await;
    for kept in [&recent, &failed, &waiting] {
        assert!(kept.join("S1.jpg").is_file(), "{} deleted", kept.display());
    }
}
