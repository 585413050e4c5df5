//! The on-call pages on a phone, as a reader holds it (Chromium at 390 and 360 px): the site,
//! block, point and alert pages of a block accelerating to failure show every value without
//! sideways scrolling (no element reaches past the viewport's right edge), the plots fit the
//! width and keep the latest epoch in view, and their tick labels stay at least 11 px.

use crate::browser::Driver;
use crate::support;

use serde_json::{json, Value};
use support::dashboard::{name, POINTS, STABLE};
use support::server::TestServer;

/// The elements of the page that reach past the viewport (tag, class, right edge), the page's
/// scroll width, and the smallest font size (px) of the plots' tick labels.
const MEASURE: &str = "var w = window.innerWidth; var out = []; \
    document.querySelectorAll('body *').forEach(function (e) { \
      var r = e.getBoundingClientRect(); \
      if (r.width > 0 && r.right > w + 0.5 && !e.closest('details:not([open])')) { \
        out.push(e.tagName.toLowerCase() + '.' + (e.getAttribute('class') || '') + ' ' + Math.round(r.right)); } }); \
    var ticks = Array.from(document.querySelectorAll('svg text')).filter(function (t) { \
      return t.getClientRects().length > 0 && t.textContent.trim() !== ''; }).map(function (t) { \
      return [parseFloat(getComputedStyle(t).fontSize) * t.getScreenCTM().a, \
        t.closest('svg').getAttribute('class') + ' ' + (t.getAttribute('class') || '') + ' ' + t.textContent]; }) \
      .sort(function (a, b) { return a[0] - b[0]; }); \
    return [w, document.documentElement.scrollWidth, out.slice(0, 12), ticks.length ? ticks[0][0] : null, ticks.length ? ticks[0][1] : null];";

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_on_call_pages_fit_a_phone() {
    let Some(driver) = Driver::start().await else {
        return;
    };
    let s = TestServer::start(|_| {}).await;
    let (st, e) = s
        .post(
            "/api/v1/sites",
            &json!({"id": "tf", "name": "Tanba face", "time_zone": "Asia/Tokyo",
                "response_text": "Close the road below the face.",
                "alert_rules": [
                    {"level": "watch", "metric": "displacement_mm", "above": 5.0, "clear_below": 4.0},
                    {"level": "warning", "metric": "velocity_mm_per_day", "above": 1.0},
                    {"level": "alarm", "metric": "time_to_failure_hours", "below": 200.0}]}),
        )
        .await;
    assert_eq!(st, 201, "{e}");
    support::dashboard::fill_accelerating(&s, "tf").await;
    let members: Vec<String> = (STABLE..POINTS).map(name).collect();
    let r = s
        .client
        .put(s.url("/api/v1/sites/tf/groups/B1"))
        .json(&json!({"kind": "block", "points": members}))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200);
    let (_, open) = s.get("/api/v1/alerts?site=tf&state=open").await;
    let alert = open["items"][0]["id"].as_str().unwrap().to_string();
    let pages = [
        "/sites/tf".to_string(),
        "/sites/tf/groups/B1".to_string(),
        format!("/sites/tf/points/{}", members[0]),
        format!("/sites/tf/alerts/{}", urlencoding(&alert)),
    ];
    let mut failures = vec![];
    for width in [390u32, 360] {
        driver.emulate_phone_width(width).await;
        for page in &pages {
            driver.goto(&s.url(page)).await;
            let seen: Value = driver.script(MEASURE).await;
            eprintln!("{width} {page}: {seen}");
            assert_eq!(seen[0], json!(width), "{seen}");
            if seen[1].as_f64().unwrap() > width as f64 || !seen[2].as_array().unwrap().is_empty() {
                failures.push(format!(
                    "{width} px {page}: scroll width {} and {}",
                    seen[1], seen[2]
                ));
            }
            if let Some(tick) = seen[3].as_f64() {
                if tick < 11.0 {
                    failures.push(format!(
                        "{width} px {page}: labels of {tick:.1} px ({})",
                        seen[4]
                    ));
                }
            }
            let file = page.trim_start_matches('/').replace(['/', '%', ':'], "-");
            driver.screenshot(format!("phone-{width}-{file}.png")).await;
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
    driver.quit().await;
    s.stop().await;
}

/// `:` as `%3A`, as the pages link an alert.
fn urlencoding(s: &str) -> String {
    s.replace(':', "%3A")
}
