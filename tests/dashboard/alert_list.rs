//! The site page's alert list as a person reads it in Chromium: one row per subject (a block
//! gathers its own alerts and its members'), with its worst level, the metrics behind it and the
//! epoch that raised it first; and on an alert's page, a de-escalation shows the test that
//! decided it with the numbers the API gives.

use crate::browser::Driver;
use crate::support;

use serde_json::{json, Value};
use support::dashboard::{create_site_with_stable, day, name, POINTS, STABLE};
use support::server::{synthetic_epoch, synthetic_epoch_moved, TestServer};

/// Creates site `id` with `rules` and marks the first [`STABLE`] points stable.
async fn site(s: &TestServer, id: &str, rules: Value) {
    create_site_with_stable(
        s,
        json!({"id": id, "name": id, "model": "orthogonal", "alert_rules": rules}),
    )
    .await;
}

/// Every alert of `site` the API lists.
async fn api_alerts(s: &TestServer, site: &str) -> Vec<Value> {
    let (_, a) = s
        .get(&format!("/api/v1/alerts?site={site}&limit=500"))
        .await;
    a["items"].as_array().unwrap().clone()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn one_row_per_subject_and_the_test_behind_a_deescalation() {
    let Some(driver) = Driver::start().await else {
        return;
    };
    let s = TestServer::start(|_| {}).await;

    // A block B1 (T010 to T014) among moving points T009 to T016, 2.5 mm a day, with a
    // displacement and a velocity rule: 5 points × 2 metrics + the block's own alerts.
    site(
        &s,
        "grp",
        json!([
            {"level": "watch", "metric": "displacement_mm", "above": 5.0, "clear_below": 4.0},
            {"level": "warning", "metric": "displacement_mm", "above": 10.0},
            {"level": "watch", "metric": "velocity_mm_per_day", "above": 1.0}]),
    )
    .await;
    let members: Vec<String> = (9..14).map(name).collect();
    for k in 0..7 {
        let body = synthetic_epoch(4, POINTS, &day(k), 700 + k as u64, 2.5 * k as f64, STABLE);
        let (st, answer) = s.upload("grp", &body).await;
        assert_eq!(st, 201, "epoch {k}: {answer}");
        if k == 0 {
            let r = s
                .client
                .put(s.url("/api/v1/sites/grp/groups/B1"))
                .json(&json!({"kind": "block", "points": members, "direction": [0.0, -1.0, 0.0]}))
                .send()
                .await
                .unwrap();
            assert_eq!(r.status(), 200, "{}", r.text().await.unwrap());
        }
    }
    let all = api_alerts(&s, "grp").await;
    let of_b1: Vec<&Value> = all
        .iter()
        .filter(|a| {
            a["state"] != "resolved"
                && (a["group"] == "B1"
                    || a["point"]
                        .as_str()
                        .is_some_and(|p| members.iter().any(|m| m == p)))
        })
        .collect();
    assert!(of_b1.len() >= 6, "several point × metric alerts: {of_b1:?}");
    let worst = of_b1
        .iter()
        .map(|a| match a["level"].as_str().unwrap() {
            "alarm" => 3,
            "warning" => 2,
            _ => 1,
        })
        .max()
        .unwrap();
    let worst = ["", "watch", "warning", "alarm"][worst];
    let first = of_b1
        .iter()
        .min_by_key(|a| {
            a["raised_observed_at"]
                .as_str()
                .expect("a raising epoch time")
                .to_string()
        })
        .unwrap();
    let raised_epoch = first["raised_epoch"].as_i64().unwrap();
    let latest_epoch = all
        .iter()
        .filter_map(|a| a["epoch"].as_i64())
        .max()
        .unwrap();
    assert!(raised_epoch < latest_epoch, "raised before the last epoch");
    let metric_names = {
        let mut m: Vec<&str> = of_b1
            .iter()
            .map(|a| match a["rule"].as_str().unwrap() {
                "displacement_mm" => "displacement",
                "velocity_mm_per_day" => "velocity",
                other => other,
            })
            .collect();
        m.sort_unstable();
        m.dedup();
        m
    };
    assert_eq!(metric_names, ["displacement", "velocity"]);

    driver.goto(&s.url("/sites/grp")).await;
    let rows = driver
        .script("return Array.from(document.querySelectorAll('#alerts tbody.subject')).map(function (b) { var r = b.querySelector('tr.subject'); return [b.getAttribute('data-subject'), r.querySelector('.badge').textContent, r.querySelector('td.who').textContent, r.querySelector('td.metrics').textContent, r.querySelector('td.raised').textContent, b.querySelectorAll('tr[id^=alert-]').length, b.querySelector('details').open]; })")
        .await;
    let rows = rows.as_array().unwrap();
    let b1: Vec<&Value> = rows.iter().filter(|r| r[0] == "block:B1").collect();
    assert_eq!(b1.len(), 1, "one row for block B1: {rows:?}");
    let b1 = b1[0];
    assert_eq!(b1[1], json!(worst), "{b1}");
    assert_eq!(b1[2], json!("block B1"));
    let metrics = b1[3].as_str().unwrap();
    for m in metric_names {
        assert!(metrics.contains(m), "{m}: {metrics}");
    }
    assert!(
        metrics.starts_with(&format!("displacement ({worst})")),
        "{metrics}"
    );
    let raised_text = b1[4].as_str().unwrap();
    let observed = first["raised_observed_at"].as_str().unwrap();
    let shown = format!("{} UTC", observed.replacen('T', " ", 1).get(..16).unwrap());
    assert!(
        raised_text.starts_with(&shown) && raised_text.ends_with(&format!("epoch {raised_epoch}")),
        "{shown}, epoch {raised_epoch}: {raised_text}"
    );
    assert_eq!(
        b1[5],
        json!(of_b1.len()),
        "every alert of B1 behind its row"
    );
    assert_eq!(b1[6], json!(false), "folded until opened");
    // No member point has a row of its own; the moving points outside B1 have theirs.
    for m in &members {
        assert!(
            !rows.iter().any(|r| r[0] == json!(format!("point:{m}"))),
            "{m}: {rows:?}"
        );
    }
    assert!(rows.iter().any(|r| r[0] == "point:T009"), "{rows:?}");
    driver
        .script(
            "document.querySelector('[data-subject=\"block:B1\"] summary').click(); return true",
        )
        .await;
    driver
        .wait_for("return document.querySelector('[data-subject=\"block:B1\"] details').open")
        .await;
    driver
        .script("document.getElementById('alerts').scrollIntoView(); return true")
        .await;
    driver.screenshot("alerts-grouped.png").await;

    // A point that went past 10 mm and came back to 7: its warning de-escalates to watch, and
    // the alert page says which test decided it, with the API's numbers.
    site(
        &s,
        "de",
        json!([
            {"level": "watch", "metric": "displacement_mm", "above": 5.0, "clear_below": 4.0},
            {"level": "warning", "metric": "displacement_mm", "above": 10.0}]),
    )
    .await;
    for (k, mm) in [0.0, 6.0, 12.0, 12.0, 7.0, 7.0].into_iter().enumerate() {
        let body =
            synthetic_epoch_moved(4, POINTS, &day(k), 800 + k as u64, [mm, 0.0, 0.0], STABLE);
        let (st, answer) = s.upload("de", &body).await;
        assert_eq!(st, 201, "epoch {k}: {answer}");
    }
    let moving = name(POINTS - 1);
    let alert = api_alerts(&s, "de")
        .await
        .into_iter()
        .find(|a| a["point"] == json!(moving))
        .unwrap_or_else(|| panic!("an alert of {moving}"));
    let id = alert["id"].as_str().unwrap().to_string();
    let (_, events) = s.get(&format!("/api/v1/alerts/{id}/events")).await;
    let items = events["items"].as_array().unwrap();
    let (k, deesc) = items
        .iter()
        .enumerate()
        .find(|(_, e)| e["type"] == "alert.deescalated")
        .unwrap_or_else(|| panic!("a de-escalation: {events}"));
    let test = &deesc["data"]["cleared_by"];
    assert_eq!(test["level"], "warning", "{test}");
    assert_eq!(test["threshold"], json!(10.0), "{test}");
    assert_eq!(test["how"], "not_exceeded", "{test}");
    let (v, sigma, z) = (
        test["value"].as_f64().unwrap(),
        test["sigma"].as_f64().unwrap(),
        test["z"].as_f64().unwrap(),
    );
    assert!((v - 7.0).abs() < 2.0, "the value read at 7 mm: {test}");
    assert!(v - z * sigma <= 10.0, "the test did not exceed: {test}");
    // Other events carry no test.
    assert!(items
        .iter()
        .filter(|e| e["type"] == "alert.raised" || e["type"] == "alert.escalated")
        .all(|e| e["data"].get("cleared_by").is_none()));

    driver.goto(&s.url(&format!("/sites/de/alerts/{id}"))).await;
    let seen = driver
        .script("var rows = Array.from(document.querySelectorAll('table.history tbody tr')); var i = rows.findIndex(function (r) { return r.querySelector('td.event') && r.querySelector('td.event').textContent == 'deescalated'; }); var t = rows[i + 1]; return [i, t.className, t.querySelector('.value').textContent, t.querySelector('.sigma').textContent, t.querySelector('.threshold').textContent, t.querySelector('.confidence').textContent, t.textContent, rows.filter(function (r) { return r.classList.contains('test'); }).length];")
        .await;
    assert_eq!(seen[1], "test", "the test's row follows the event: {seen}");
    assert_eq!(seen[2], json!(format!("{v:.2}")), "{seen}");
    assert_eq!(seen[3], json!(format!("{sigma:.2}")), "{seen}");
    assert_eq!(seen[4], json!("10"), "{seen}");
    let confidence = test["confidence"].as_f64().unwrap() * 100.0;
    assert_eq!(seen[5], json!(format!("{confidence}")), "{seen}");
    let words = seen[6].as_str().unwrap();
    assert!(
        words.contains(&format!(
            "{v:.2} − {z:.2} × {sigma:.2} = {:.2} is not above 10 mm at {confidence} % confidence",
            v - z * sigma
        )),
        "{words}"
    );
    // Rows before the de-escalation in the page are the API's events before it.
    let events_before = seen[0].as_u64().unwrap() as usize;
    assert_eq!(events_before, k, "{seen}");
    driver.screenshot("alert-deescalated.png").await;
    driver.quit().await;
    s.stop().await;
}

/// An alert that only a recompute raises names the epoch of the series at which the replayed
/// rules raised it, not the epoch whose upload caused the replay: days 3 and 4 come first (the
/// block moves 10 mm between them, below the 15 mm rule), then day 0, which becomes the
/// reference; replayed, the block is 30 mm out at day 3 and 40 mm at day 4.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_alert_a_replay_raises_names_the_epoch_that_raised_it() {
    let s = TestServer::start(|_| {}).await;
    site(
        &s,
        "late",
        json!([{"level": "warning", "metric": "displacement_mm", "above": 15.0, "source": "raw"}]),
    )
    .await;
    let mut ids = std::collections::HashMap::new();
    for k in [3usize, 4, 0] {
        let body = synthetic_epoch_moved(
            4,
            POINTS,
            &day(k),
            900 + k as u64,
            [10.0 * k as f64, 0.0, 0.0],
            STABLE,
        );
        let (st, answer) = s.upload("late", &body).await;
        assert_eq!(st, 201, "day {k}: {answer}");
        ids.insert(
            k,
            answer["epoch"]
                .as_i64()
                .or_else(|| answer["id"].as_i64())
                .unwrap(),
        );
        if k == 4 {
            assert!(
                api_alerts(&s, "late").await.is_empty(),
                "10 mm raised an alert"
            );
        }
    }
    let alerts = api_alerts(&s, "late").await;
    assert_eq!(alerts.len(), POINTS - STABLE, "{alerts:?}");
    for a in &alerts {
        assert_eq!(a["raised_epoch"], ids[&3], "{a}");
        assert!(
            a["raised_observed_at"]
                .as_str()
                .unwrap()
                .starts_with(&day(3)[..16]),
            "{a}"
        );
        assert_eq!(a["epoch"], ids[&4], "the latest evaluation is day 4: {a}");
    }
    s.stop().await;
}
