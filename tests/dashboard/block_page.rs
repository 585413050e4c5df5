//! A block's page in Chromium: reached from the site page's link, it names the block, shows its
//! latest motion, and links each member point (and only those), whose page links back to it.

use crate::browser::Driver;
use crate::support;

use serde_json::{json, Value};
use support::dashboard::{fill, name, SITE};
use support::server::TestServer;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_block_page_links_its_members_and_they_link_back() {
    let Some(driver) = Driver::start().await else {
        return;
    };
    let s = TestServer::start(|_| {}).await;
    fill(&s, 6, None).await;
    // The moving points T010 to T014 declared as block B1 (T009 and T015, T016 moving too, left out).
    let members: Vec<String> = (9..14).map(name).collect();
    let r = s
        .client
        .put(s.url(&format!("/api/v1/sites/{SITE}/groups/B1")))
        .json(&json!({"kind": "block", "points": members, "direction": [0.0, -1.0, 0.0]}))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200, "{}", r.text().await.unwrap());
    let (_, motion) = s
        .get(&format!("/api/v1/sites/{SITE}/groups/B1/motion"))
        .await;
    let last: &Value = motion["items"]
        .as_array()
        .unwrap()
        .last()
        .expect("a motion");

    driver.goto(&s.url(&format!("/sites/{SITE}"))).await;
    driver
        .script("document.querySelector('p.blocks a').click(); return true")
        .await;
    driver
        .wait_for("return location.pathname.endsWith('/groups/B1')")
        .await;
    let seen = driver
        .script("return [document.querySelector('h1').textContent, Array.from(document.querySelectorAll('#members a')).map(function (a) { return [a.textContent, a.getAttribute('href')]; }), document.querySelector('table.latest').innerText]")
        .await;
    assert!(seen[0].as_str().unwrap().starts_with("Block B1"), "{seen}");
    let want: Vec<Value> = members
        .iter()
        .map(|m| json!([m, format!("/sites/{SITE}/points/{m}")]))
        .collect();
    assert_eq!(seen[1], json!(want), "the member links");
    // The latest motion as the API gives it (d ± σ, 2 decimals).
    let d = format!(
        "{:.2} ± {:.2}",
        last["d_mm"].as_f64().unwrap(),
        last["sigma_mm"].as_f64().unwrap()
    );
    assert!(seen[2].as_str().unwrap().contains(&d), "{d}: {seen}");
    driver.screenshot("block-desk.png").await;
    // A member's page links back to its block.
    driver
        .script("document.querySelector('#members a').click(); return true")
        .await;
    driver
        .wait_for(&format!(
            "return location.pathname.endsWith('/points/{}')",
            members[0]
        ))
        .await;
    let back = driver
        .script("return Array.from(document.querySelectorAll('main a')).filter(function (a) { return a.getAttribute('href').endsWith('/groups/B1'); }).length")
        .await;
    assert!(back.as_u64().unwrap() >= 1, "a link back to B1");
    driver.emulate_phone_width(360).await;
    driver
        .goto(&s.url(&format!("/sites/{SITE}/groups/B1")))
        .await;
    let width = driver
        .script("return [window.innerWidth, document.documentElement.scrollWidth]")
        .await;
    assert!(
        width[1].as_f64().unwrap() <= width[0].as_f64().unwrap(),
        "{width}"
    );
    driver.screenshot("block-phone-360.png").await;
    // An unknown block is a 404 page.
    let r = s
        .client
        .get(s.url(&format!("/sites/{SITE}/groups/nope")))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 404);
    driver.quit().await;
    s.stop().await;
}

/// A block accelerating to failure (the points T009–T016 of the headline's fixture, declared as
/// block B2): its page draws the latest forecast's inverse-velocity line, and the line reaches
/// zero at the forecast failure time the API gives (the last epoch plus the filtered time to
/// failure), at the plot's right edge, whose date label is that day; its forecast history gives
/// the date before which failure is likely, and "no forecast yet", without a date, for epochs
/// whose bound lies beyond a week.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_block_page_draws_the_forecast_line_down_to_the_failure_time() {
    use support::dashboard::{POINTS, STABLE};
    let Some(driver) = Driver::start().await else {
        return;
    };
    let s = TestServer::start(|_| {}).await;
    s.create_site("tf").await;
    support::dashboard::fill_accelerating(&s, "tf").await;
    let members: Vec<String> = (STABLE..POINTS).map(name).collect();
    let r = s
        .client
        .put(s.url("/api/v1/sites/tf/groups/B2"))
        .json(&json!({"kind": "block", "points": members}))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200, "{}", r.text().await.unwrap());
    let (_, motion) = s.get("/api/v1/sites/tf/groups/B2/motion").await;
    let last: &Value = motion["items"].as_array().unwrap().last().unwrap();
    let t0 = chrono::DateTime::parse_from_rfc3339(last["observed_at"].as_str().unwrap())
        .unwrap()
        .timestamp() as f64;
    let hours = last["f_time_to_failure_hours"]
        .as_f64()
        .unwrap_or_else(|| panic!("a block forecast: {last}"));
    let t_f = t0 + hours * 3600.0;

    driver.goto(&s.url("/sites/tf/groups/B2")).await;
    let seen = driver
        .script("var f = document.querySelector('figure.inverse'); var l = f.querySelector('line.fit'); var t = f.querySelectorAll('svg text'); return [f.querySelector('figcaption').textContent, l && l.getAttribute('data-zero'), l && l.getAttribute('x2'), l && l.getAttribute('y2'), t[t.length - 1].textContent, f.querySelector('line.axis').getAttribute('y2')]")
        .await;
    eprintln!("{seen}");
    assert!(
        seen[0]
            .as_str()
            .unwrap()
            .contains("dashed: the latest forecast's law"),
        "{seen}"
    );
    let zero: f64 = seen[1].as_str().expect("a line").parse().unwrap();
    assert!(
        (zero - t_f).abs() <= 6.0 * 3600.0,
        "line's zero {zero} vs forecast {t_f}"
    );
    // The line ends at the plot's right edge, on the time axis (1/v = 0) ...
    assert_eq!(seen[2], json!("632.0"), "{seen}");
    let axis: f64 = seen[5].as_str().unwrap().parse().unwrap();
    let end: f64 = seen[3].as_str().unwrap().parse().unwrap();
    assert!((end - axis).abs() < 1.0, "{seen}");
    // ... under the date label of the forecast failure day.
    let day = chrono::DateTime::from_timestamp(t_f as i64, 0)
        .unwrap()
        .format("%Y-%m-%d")
        .to_string();
    assert_eq!(seen[4], json!(day), "{seen}");
    // The forecast history: the latest row gives the date before which failure is likely (the
    // one-sided 95 % bound, the last epoch plus hours + 1.645 σ); rows whose bound lies beyond a
    // week say "no forecast yet" and give no date.
    let history = driver
        .script("return Array.from(document.querySelectorAll('table.forecasts tbody tr')).map(function (r) { return r.innerText; })")
        .await;
    let rows: Vec<&str> = history
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r.as_str().unwrap())
        .collect();
    assert!(rows[0].contains(&format!("{hours:.0} ± ")), "{rows:?}");
    let sigma = last["sigma_f_time_to_failure_hours"].as_f64().unwrap();
    let bound = chrono::DateTime::from_timestamp(
        (t0 + (hours + 1.6449 * sigma) * 3600.0).round() as i64,
        0,
    )
    .unwrap()
    .format("%Y-%m-%d %H:%M UTC")
    .to_string();
    assert!(rows[0].contains(&bound), "{bound}: {rows:?}");
    let not_yet: Vec<&&str> = rows
        .iter()
        .filter(|r| r.contains("no forecast yet"))
        .collect();
    assert!(
        not_yet
            .iter()
            .all(|r| !r.contains("2026-11-1") || r.matches("UTC").count() == 1),
        "a row without a forecast yet gives no failure date: {not_yet:?}"
    );
    // The line runs through the points it is drawn over: at each epoch of its window where 1/v
    // is plotted (v > 2σ), the line against 1/v ± 2σ(1/v) (σ_v / v²).
    let fit = driver
        .script("var l = document.querySelector('figure.inverse line.fit'); return [l.getAttribute('data-t0'), l.getAttribute('data-y0'), l.getAttribute('data-zero')]")
        .await;
    let num = |v: &Value| v.as_str().unwrap().parse::<f64>().unwrap();
    let (t0, y0, zero) = (num(&fit[0]), num(&fit[1]), num(&fit[2]));
    let mut normalised = vec![];
    for r in motion["items"].as_array().unwrap() {
        let t = chrono::DateTime::parse_from_rfc3339(r["observed_at"].as_str().unwrap())
            .unwrap()
            .timestamp() as f64;
        let (Some(v), Some(sv)) = (
            r["f_velocity_mm_per_day"].as_f64(),
            r["sigma_f_velocity_mm_per_day"].as_f64(),
        ) else {
            continue;
        };
        if t + 1.0 < t0 || v <= 2.0 * sv {
            continue;
        }
        let line = y0 * (zero - t) / (zero - t0);
        normalised.push((line - 1.0 / v) / (sv / (v * v)));
    }
    eprintln!("line against the plotted 1/v, in σ: {normalised:?}");
    assert!(normalised.len() >= 3, "{normalised:?}");
    let last = *normalised.last().unwrap();
    assert!(last.abs() <= 2.0, "the last epoch: {last} σ from the line");
    let rms = (normalised.iter().map(|x| x * x).sum::<f64>() / normalised.len() as f64).sqrt();
    assert!(rms <= 2.0, "rms {rms} σ: {normalised:?}");
    driver
        .script("document.querySelector('figure.inverse').scrollIntoView(); return true")
        .await;
    driver.screenshot("block-forecast.png").await;
    driver.quit().await;
    s.stop().await;
}
