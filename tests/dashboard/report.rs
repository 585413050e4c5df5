//! The campaign report as a reader meets it (issue 61, item 10): a site of 28 points with a
//! 6-point block accelerating towards failure, printed to A4 in Chromium, fits on at most three
//! pages; and the page says what the site page says: the headline, the plan in alert colours,
//! the block's motion with its forecast failure date, every epoch with its adjustment's health,
//! and the alert history with the epoch that first raised each subject's alerts.

use std::collections::HashMap;

use serde_json::{json, Value};

use crate::browser::Driver;
use crate::support;
use support::dashboard::{create_site_with_stable, hour, name, STABLE};
use support::server::{synthetic_epoch_moved, TestServer};

const SITE: &str = "report-site";
const POINTS: usize = 28;
/// The block: T009–T014.
const BLOCK: std::ops::Range<usize> = STABLE..STABLE + 6;
const EPOCHS: usize = 44;

/// An epoch whose block points have moved `mm` along X and whose other points are still (the
/// same noise as the still body: one seed for both).
fn epoch(k: usize, mm: f64) -> Value {
    let seed = 900 + k as u64;
    let moved = synthetic_epoch_moved(4, POINTS, &hour(6 * k), seed, [mm, 0.0, 0.0], 0);
    let mut still = synthetic_epoch_moved(4, POINTS, &hour(6 * k), seed, [0.0; 3], 0);
    let block: Vec<String> = BLOCK.map(name).collect();
    for (img, m) in still["images"]
        .as_array_mut()
        .unwrap()
        .iter_mut()
        .zip(moved["images"].as_array().unwrap())
    {
        for (o, mo) in img["observations"]
            .as_array_mut()
            .unwrap()
            .iter_mut()
            .zip(m["observations"].as_array().unwrap())
        {
            if block.contains(&o["point"].as_str().unwrap().to_string()) {
                *o = mo.clone();
            }
        }
    }
    still
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_report_fits_three_a4_pages_and_says_what_the_site_says() {
    let Some(driver) = Driver::start().await else {
        return;
    };
    let s = TestServer::start(|_| {}).await;
    create_site_with_stable(
        &s,
        json!({"id": SITE, "name": "Report cliff", "model": "orthogonal", "time_zone": "Asia/Tokyo",
               "response_text": "Close route 12 below the face.",
               "alert_rules": [
            {"level": "watch", "metric": "displacement_mm", "above": 5.0, "clear_below": 4.0},
            {"level": "warning", "metric": "displacement_mm", "above": 10.0},
            {"level": "warning", "metric": "velocity_mm_per_day", "above": 1.0},
            {"level": "alarm", "metric": "time_to_failure_hours", "below": 96.0}]}),
    )
    .await;
    let r = s
        .client
        .put(s.url(&format!("/api/v1/sites/{SITE}/groups/B1")))
        .json(&json!({"kind": "block", "direction": [1, 0, 0], "points": BLOCK.map(name).collect::<Vec<_>>()}))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200, "{}", r.text().await.unwrap());
    for k in 0..EPOCHS {
        // d(t) = −v0·t_f·ln(1 − t/t_f): 1 mm/day at first, failure 16 days after the first epoch.
        let mm = -16.0 * (1.0 - k as f64 / 64.0).ln();
        let (st, answer) = s.upload(SITE, &epoch(k, mm)).await;
        assert_eq!(st, 201, "epoch {k}: {answer}");
    }
    let (_, alerts) = s
        .get(&format!("/api/v1/alerts?site={SITE}&limit=1000"))
        .await;
    let alerts = alerts["items"].as_array().unwrap().clone();
    assert!(!alerts.is_empty(), "the block raised alerts");

    driver.goto(&s.url(&format!("/sites/{SITE}/report"))).await;
    // What a reader takes from it.
    let seen = driver
        .script(
            "return {
              headline: document.querySelector('article.report section.headline').textContent,
              block: Array.from(document.querySelectorAll('table.blocks tbody tr')).map(function (r) { return r.textContent; }),
              coloured: document.querySelectorAll('svg.plan .pt.watch, svg.plan .pt.warning, svg.plan .pt.alarm').length,
              epochs: document.querySelectorAll('ol.epoch-health li').length,
              health: document.querySelector('p.health').textContent,
              history: Array.from(document.querySelectorAll('table.history tr.subject')).map(function (r) { return [r.children[1].textContent, r.querySelector('td.raised').textContent]; }),
              plots: document.querySelectorAll('.report-plots figure').length
            }",
        )
        .await;
    let headline = seen["headline"].as_str().unwrap();
    assert!(headline.contains("Close route 12"), "headline: {headline}");
    assert!(
        headline.contains("block B1") || headline.contains("T0"),
        "headline names the worst subject: {headline}"
    );
    let block = seen["block"][0].as_str().expect("a row for block B1");
    assert!(block.starts_with("B1"), "{block}");
    assert!(
        block.contains("UTC") || block.contains("no forecast yet"),
        "the block's forecast failure time or why there is none: {block}"
    );
    assert_eq!(
        seen["coloured"].as_u64(),
        Some(BLOCK.len() as u64),
        "the plan colours the block's points by their open alerts"
    );
    assert_eq!(seen["epochs"].as_u64(), Some(EPOCHS as u64), "every epoch");
    let health = seen["health"].as_str().unwrap();
    assert!(
        health.starts_with(&format!("{EPOCHS} epochs tested")),
        "{health}"
    );
    // Each subject's first raising epoch is the API's earliest for that subject.
    let mut earliest: HashMap<String, (String, i64)> = HashMap::new();
    for a in &alerts {
        let subject = match (a["point"].as_str(), a["group"].as_str()) {
            (Some(p), _) => p.to_string(),
            (None, Some(g)) => format!("block {g}"),
            _ => "site".to_string(),
        };
        let t = a["raised_observed_at"].as_str().unwrap().to_string();
        let e = a["raised_epoch"].as_i64().unwrap();
        let entry = earliest.entry(subject).or_insert((t.clone(), e));
        if t < entry.0 {
            *entry = (t, e);
        }
    }
    let history = seen["history"].as_array().unwrap();
    assert_eq!(history.len(), earliest.len(), "one row per subject");
    for row in history {
        let (subject, raised) = (row[0].as_str().unwrap(), row[1].as_str().unwrap());
        let (t, e) = &earliest[subject];
        assert!(
            raised.contains(&format!("(epoch {e})")) && raised.contains(&t[..16].replace('T', " ")),
            "{subject}: '{raised}' against {t} epoch {e}"
        );
    }
    assert!(seen["plots"].as_u64().unwrap() >= 1, "the block's plot");
    let (pdf, pages) = driver.print_a4().await;
    println!("report: {pages} A4 pages, {} bytes", pdf.len());
    if let Some(dir) = std::env::var_os("CLIFFWATCH_SCREENSHOTS") {
        std::fs::write(std::path::Path::new(&dir).join("report-28.pdf"), &pdf).unwrap();
    }
    assert!(
        (1..=3).contains(&pages),
        "a site of {POINTS} points on at most 3 A4 pages: {pages}"
    );
    driver.quit().await;
    s.stop().await;
}
