//! Changes of history recompute the derived series in one transaction and re-evaluate the alerts
//! without re-sending what staff already received: a new reference resolves alerts the new
//! displacements no longer support (one `alert.resolved`, no new `alert.raised`); an epoch that
//! arrives out of order gives exactly the series and alert state of an in-order upload.

use crate::support;

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

use reqwest::Method;
use serde_json::{json, Value};
use support::alerts::{
    create_site, day, mark_stable, outbox_events, write_config, write_webhook_config, Daemon,
    Receiver, Scene,
};

const STEP_MM: f64 = 3.5;

async fn site(d: &Daemon, id: &str, scene: &Scene) {
    let rules = json!([
        {"level": "watch", "metric": "displacement_mm", "above": 5.0, "clear_below": 4.0},
        {"level": "warning", "metric": "displacement_mm", "above": 10.0, "clear_below": 8.0}]);
    create_site(d, id, rules).await;
    mark_stable(d, id, scene).await;
}

async fn upload(d: &Daemon, site: &str, scene: &Scene, k: usize) {
    let body = scene.epoch(&day(k), 100 + k as u64, STEP_MM * k as f64);
    let (s, b) = d
        .send(
            Method::POST,
            &format!("/api/v1/sites/{site}/epochs"),
            Some(&body),
        )
        .await;
    assert_eq!(s, 201, "{site} day {k}: {b}");
}

async fn alerts(d: &Daemon, site: &str) -> Vec<Value> {
    let (_, a) = d
        .get(&format!("/api/v1/alerts?site={site}&limit=1000"))
        .await;
    a["items"].as_array().unwrap().clone()
}

/// The displacement alerts of a site (a `reference_unstable` alert may come and go with the
/// reference: the congruence test excludes a still point by chance now and then).
async fn displacement_alerts(d: &Daemon, site: &str) -> Vec<Value> {
    alerts(d, site)
        .await
        .into_iter()
        .filter(|a| a["rule"] == "displacement_mm")
        .collect()
}

/// Outbox events of displacement alerts: `(message id, event type)`.
async fn displacement_events(data: &std::path::Path) -> Vec<(String, String)> {
    outbox_events(data)
        .await
        .into_iter()
        .filter(|(_, _, a)| a.contains(":displacement_mm:"))
        .map(|(id, t, _)| (id, t))
        .collect()
}

/// point → rows (observed_at, dx, dy, dz, velocity, significant) of a site.
async fn series(d: &Daemon, site: &str, scene: &Scene) -> BTreeMap<String, Vec<Value>> {
    let mut out = BTreeMap::new();
    for i in 0..scene.n {
        let (s, b) = d
            .get(&format!(
                "/api/v1/sites/{site}/points/{}/displacements?limit=1000",
                Scene::name(i)
            ))
            .await;
        assert_eq!(s, 200, "{b}");
        out.insert(Scene::name(i), b["items"].as_array().unwrap().clone());
    }
    out
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn reference_change_reevaluates_alerts_without_resending_history() {
    let dir = tempfile::tempdir().unwrap();
    let receiver = Receiver::start(0).await;
    let config = write_webhook_config(dir.path(), &receiver.url);
    let data = dir.path().join("data");
    let d = Daemon::start(&data, &config).await;
    let scene = Scene { n: 16, stable: 8 };
    site(&d, "cliff", &scene).await;
    for k in 0..6 {
        upload(&d, "cliff", &scene, k).await;
    }
    // 17.5 mm after 5 days: the block's points exceed the warning threshold at 99 %.
    let before = displacement_alerts(&d, "cliff").await;
    assert_eq!(before.len(), scene.n - scene.stable, "{before:?}");
    assert!(
        before
            .iter()
            .all(|a| a["level"] == "warning" && a["state"] == "open"),
        "{before:?}"
    );
    // Staff acknowledge one of them.
    let acked = before[0]["id"].as_str().unwrap().to_string();
    let (s, b) = d
        .send(
            Method::POST,
            &format!("/api/v1/alerts/{acked}/ack"),
            Some(&json!({"by": "geologist", "comment": "on it"})),
        )
        .await;
    assert_eq!(s, 200, "{b}");
    let outbox_before = displacement_events(&data).await;

    // Against day 4 the block moved only 3.5 mm: no rule holds, every alert resolves, once.
    let (s, b) = d
        .send(
            Method::PUT,
            "/api/v1/sites/cliff/reference",
            Some(&json!({"epoch": 5})),
        )
        .await;
    assert_eq!(s, 200, "{b}");
    let after = displacement_alerts(&d, "cliff").await;
    assert_eq!(after.len(), before.len());
    assert!(after.iter().all(|a| a["state"] == "resolved"), "{after:?}");
    assert!(
        after.iter().all(|a| a["message"]
            .as_str()
            .unwrap()
            .ends_with("resolved: the reference was set to epoch 5 by anonymous")),
        "{after:?}"
    );
    // a resolved alert still says how high it went
    assert!(
        after.iter().all(|a| a["peak_level"] == "warning"),
        "{after:?}"
    );
    let outbox_after = displacement_events(&data).await;
    let new: Vec<&(String, String)> = outbox_after
        .iter()
        .filter(|e| !outbox_before.contains(e))
        .collect();
    assert_eq!(new.len(), before.len(), "{new:?}");
    assert!(new.iter().all(|(_, t)| t == "alert.resolved"), "{new:?}");

    // Back to the first epoch as the reference: the warnings hold again and are raised anew (the
    // earlier ones were resolved), stamped now; the history is not replayed to the receiver.
    let (s, b) = d
        .send(
            Method::PUT,
            "/api/v1/sites/cliff/reference",
            Some(&json!({"epoch": null})),
        )
        .await;
    assert_eq!(s, 200, "{b}");
    let open: Vec<Value> = displacement_alerts(&d, "cliff")
        .await
        .into_iter()
        .filter(|a| a["state"] == "open")
        .collect();
    assert_eq!(open.len(), before.len(), "{open:?}");
    assert!(open.iter().all(|a| a["level"] == "warning"));
    let outbox_final = displacement_events(&data).await;
    let newer: Vec<&(String, String)> = outbox_final
        .iter()
        .filter(|e| !outbox_after.contains(e))
        .collect();
    assert_eq!(newer.len(), before.len(), "one event per alert: {newer:?}");
    assert!(newer.iter().all(|(_, t)| t == "alert.raised"), "{newer:?}");

    // Everything in the outbox reaches the receiver, each id once.
    let all = outbox_events(&data).await.len();
    let deadline = Instant::now() + Duration::from_secs(20);
    while receiver.accepted().len() < all {
        assert!(Instant::now() < deadline, "deliveries missing");
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    let log = receiver.log.lock().unwrap().clone();
    assert_eq!(log.len(), all, "no retries, no duplicates");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_out_of_order_epoch_gives_the_in_order_series_and_alerts() {
    let dir = tempfile::tempdir().unwrap();
    let config = write_config(dir.path(), "");
    let d = Daemon::start(&dir.path().join("data"), &config).await;
    let scene = Scene { n: 16, stable: 8 };
    site(&d, "ordered", &scene).await;
    site(&d, "late", &scene).await;
    for k in 0..6 {
        upload(&d, "ordered", &scene, k).await;
    }
    // Day 3 arrives last (a delayed campaign).
    for k in [0, 1, 2, 4, 5, 3] {
        upload(&d, "late", &scene, k).await;
    }
    assert_same_series_and_alerts(&d, "ordered", "late", &scene, 6).await;
}

/// A site measured hourly: each upload's analysis reads the last 40 days of its history (the
/// forecast's 40 daily bins), not its last 40 records, so the filter of an epoch uploaded in
/// order runs over every hour since the reference, as a recompute's does. 60 hourly epochs,
/// then a change of the rules recomputes the site from the same coordinates: every row's
/// filtered values stay as the uploads stored them (to 1e-9). Had an upload read 40 records,
/// the filters of hours 41–59 would start later than the recompute's and differ.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_hourly_site_reads_its_days_of_history_as_a_recompute_does() {
    const HOURS: usize = 60;
    let dir = tempfile::tempdir().unwrap();
    let config = write_config(dir.path(), "");
    let d = Daemon::start(&dir.path().join("data"), &config).await;
    let scene = Scene { n: 16, stable: 8 };
    site(&d, "hourly", &scene).await;
    for k in 0..HOURS {
        let body = scene.epoch(&support::hour(k), 100 + k as u64, 0.25 * k as f64);
        let (s, b) = d
            .send(Method::POST, "/api/v1/sites/hourly/epochs", Some(&body))
            .await;
        assert_eq!(s, 201, "hour {k}: {b}");
    }
    let uploaded = series(&d, "hourly", &scene).await;
    let rules = json!({"alert_rules": [
        {"level": "watch", "metric": "displacement_mm", "above": 6.0}]});
    let (s, b) = d
        .send(Method::PATCH, "/api/v1/sites/hourly", Some(&rules))
        .await;
    assert_eq!(s, 200, "{b}");
    let recomputed = series(&d, "hourly", &scene).await;
    // The largest difference of the filtered values in the first 40 hours (any reach reads
    // their whole history) and in the last 20 (only a reach in days does).
    let (mut early, mut late) = (0.0_f64, 0.0_f64);
    let mut moving = 0;
    for (p, rows) in &uploaded {
        assert_eq!(rows.len(), HOURS, "{p}");
        assert_eq!(recomputed[p].len(), HOURS, "{p}");
        for (k, (x, y)) in rows.iter().zip(&recomputed[p]).enumerate() {
            assert_eq!(x["observed_at"], y["observed_at"], "{p}");
            for c in [
                "f_d_mm",
                "f_velocity_mm_per_day",
                "sigma_f_velocity_mm_per_day",
            ] {
                let (u, v) = (x[c].as_f64(), y[c].as_f64());
                assert_eq!(u.is_some(), v.is_some(), "{p} hour {k} {c}: {x} vs {y}");
                let diff = (u.unwrap_or(0.0) - v.unwrap_or(0.0)).abs();
                if k < 40 {
                    early = early.max(diff);
                } else {
                    late = late.max(diff);
                }
            }
        }
        let last = rows.last().unwrap()["f_velocity_mm_per_day"].as_f64();
        moving += usize::from(last.is_some_and(|v| v > 3.0));
    }
    println!("largest difference: {early:e} in hours 0–39, {late:e} in hours 40–59");
    assert!(early < 1e-4, "{early}");
    assert!(
        late <= 10.0 * early + 1e-9,
        "hours 40–59 differ by {late}, 0–39 by {early}"
    );
    // The moving points' filtered velocity is the motion's, 6 mm/day.
    assert_eq!(moving, scene.n - scene.stable, "{uploaded:?}");
}

/// The displacement series (each of `epochs` rows) and the open alerts of sites `one` and
/// `other` agree.
async fn assert_same_series_and_alerts(
    d: &Daemon,
    one: &str,
    other: &str,
    scene: &Scene,
    epochs: usize,
) {
    let a = series(d, one, scene).await;
    let b = series(d, other, scene).await;
    for (p, rows) in &a {
        let other = &b[p];
        assert_eq!(rows.len(), epochs, "{p}");
        assert_eq!(other.len(), epochs, "{p}");
        for (r, o) in rows.iter().zip(other) {
            assert_eq!(r["observed_at"], o["observed_at"]);
            assert_eq!(r["significant"], o["significant"], "{p}: {r} vs {o}");
            for k in ["dx_mm", "dy_mm", "dz_mm", "sigma_mm"] {
                let (x, y) = (r[k].as_f64().unwrap(), o[k].as_f64().unwrap());
                assert!((x - y).abs() < 1e-3, "{p} {k}: {x} vs {y}");
            }
            match (
                r["velocity_mm_per_day"].as_f64(),
                o["velocity_mm_per_day"].as_f64(),
            ) {
                (Some(x), Some(y)) => assert!((x - y).abs() < 1e-3, "{p} velocity {x} vs {y}"),
                (x, y) => assert_eq!(x, y, "{p} velocity"),
            }
        }
    }
    let level = |v: Vec<Value>| -> BTreeMap<String, (String, String)> {
        v.into_iter()
            .map(|a| {
                (
                    a["point"].as_str().unwrap_or("-").to_string(),
                    (
                        a["level"].as_str().unwrap().to_string(),
                        a["state"].as_str().unwrap().to_string(),
                    ),
                )
            })
            .filter(|(_, (_, s))| s != "resolved")
            .collect()
    };
    let (x, y) = (level(alerts(d, one).await), level(alerts(d, other).await));
    assert!(!x.is_empty());
    assert_eq!(x, y);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn stable_points_marked_after_the_epochs_give_the_series_of_marking_them_first() {
    let dir = tempfile::tempdir().unwrap();
    let config = write_config(dir.path(), "");
    let d = Daemon::start(&dir.path().join("data"), &config).await;
    let scene = Scene { n: 16, stable: 8 };
    site(&d, "first", &scene).await;
    let rules = json!([
        {"level": "watch", "metric": "displacement_mm", "above": 5.0, "clear_below": 4.0},
        {"level": "warning", "metric": "displacement_mm", "above": 10.0, "clear_below": 8.0}]);
    create_site(&d, "after", rules).await;
    for k in 0..6 {
        upload(&d, "first", &scene, k).await;
        upload(&d, "after", &scene, k).await;
    }
    // Without stable points the datum is held by every point, the moving block included: the
    // series differ until the roles are set.
    let (a, b) = (
        series(&d, "first", &scene).await,
        series(&d, "after", &scene).await,
    );
    let p = Scene::name(0);
    let gap = (a[&p][5]["dx_mm"].as_f64().unwrap() - b[&p][5]["dx_mm"].as_f64().unwrap()).abs()
        + (a[&p][5]["dy_mm"].as_f64().unwrap() - b[&p][5]["dy_mm"].as_f64().unwrap()).abs()
        + (a[&p][5]["dz_mm"].as_f64().unwrap() - b[&p][5]["dz_mm"].as_f64().unwrap()).abs();
    assert!(gap > 0.5, "the datum should matter: {gap} mm");
    mark_stable(&d, "after", &scene).await;
    assert_same_series_and_alerts(&d, "first", "after", &scene, 6).await;
    // Setting a role a point already has leaves the series as they are.
    let (s, b) = d
        .send(
            Method::PUT,
            &format!("/api/v1/sites/after/points/{p}"),
            Some(&json!({"role": "stable"})),
        )
        .await;
    assert_eq!(s, 200, "{b}");
    assert_eq!(b["role"], "stable");
    assert_same_series_and_alerts(&d, "first", "after", &scene, 6).await;
}

/// A recompute that raises again, at the same epoch, an alert that was resolved before gives it a
/// new id: the resolved alert stays resolved with its history, and `alert.raised` goes out for an
/// id staff have not seen resolved.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_replayed_raise_never_reopens_a_resolved_alert() {
    let dir = tempfile::tempdir().unwrap();
    let config = write_config(dir.path(), "");
    let data = dir.path().join("data");
    let scene = Scene { n: 16, stable: 8 };
    let d = Daemon::start(&data, &config).await;
    let rules = json!([{"level": "watch", "metric": "displacement_mm", "above": 20.0}]);
    create_site(&d, "replay", rules).await;
    mark_stable(&d, "replay", &scene).await;
    let send = |k: usize, block_mm: f64| {
        let body = scene.epoch(&day(k), 300 + k as u64, block_mm);
        let d = &d;
        async move {
            let (s, b) = d
                .send(Method::POST, "/api/v1/sites/replay/epochs", Some(&body))
                .await;
            assert_eq!(s, 201, "day {k}: {b}");
        }
    };
    // The block 0, 40 and 13 mm from day 1: raised on day 2, resolved on day 3 (σ of a
    // displacement ≈ 1.5 mm here: every margin is 4σ or more).
    for (k, block_mm) in [(1, 0.0), (2, 40.0), (3, 13.0)] {
        send(k, block_mm).await;
    }
    let before = alerts(&d, "replay").await;
    assert_eq!(before.len(), scene.n - scene.stable, "{before:?}");
    assert!(
        before.iter().all(|a| a["state"] == "resolved"),
        "{before:?}"
    );
    let resolved: BTreeMap<String, String> = before
        .iter()
        .map(|a| {
            (
                a["id"].as_str().unwrap().into(),
                a["point"].as_str().unwrap().into(),
            )
        })
        .collect();

    // Day 0 arrives late with the block at −13 mm and becomes the reference: day 1 is 13 mm, day
    // 2 53 mm and day 3 26 mm from it, so the replay raises on day 2 again and the alert stays
    // open.
    send(0, -13.0).await;
    let after = alerts(&d, "replay").await;
    for (id, point) in &resolved {
        let old = after.iter().find(|a| a["id"] == id.as_str()).unwrap();
        assert_eq!(old["state"], "resolved", "{point}: {old}");
        let open: Vec<&Value> = after
            .iter()
            .filter(|a| a["point"] == point.as_str() && a["state"] == "open")
            .collect();
        assert_eq!(open.len(), 1, "{point}: {after:?}");
        let new_id = open[0]["id"].as_str().unwrap();
        assert!(new_id.starts_with(&format!("{id}:")), "{new_id} after {id}");
        assert!(
            open[0]["raised_at"].as_str().unwrap() > old["updated_at"].as_str().unwrap(),
            "{point}: raised {} before the old alert's resolution {}",
            open[0]["raised_at"],
            old["updated_at"]
        );
    }
}
