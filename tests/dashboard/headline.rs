//! The headline of a site's pages in Chromium, as the person on call reads it: a point
//! accelerating to failure raises a time-to-failure alarm, and the headline says so in words,
//! with the date before which failure is likely (the one-sided bound the rule reads) and the
//! forecast failure time as dates in UTC and in the site's zone (the same instants the API's
//! series gives: the last epoch plus the filtered time to failure and its bound), says that it counts
//! from the last epoch, how old that epoch is, what to do and whom to call. At 390 and 360 px it
//! fits.

use crate::browser::Driver;
use crate::support;

use serde_json::{json, Value};
use support::dashboard::{day, name};
use support::server::TestServer;

/// `2026-11-17 09:00 UTC · 18:00 JST` (the local date added when it differs), computed here
/// with chrono-tz rather than through the crate's formatter.
fn utc_and_tokyo(unix: f64) -> String {
    let utc = chrono::DateTime::from_timestamp(unix.round() as i64, 0).unwrap();
    let local = utc.with_timezone(&chrono_tz::Asia::Tokyo);
    let l = if local.date_naive() == utc.date_naive() {
        local.format("%H:%M JST")
    } else {
        local.format("%Y-%m-%d %H:%M JST")
    };
    format!("{} · {l}", utc.format("%Y-%m-%d %H:%M UTC"))
}

/// `2026-11-17 18:00 JST (09:00 UTC)`: the headline's local time first, then UTC (its date
/// added when it differs), computed here with chrono-tz.
fn tokyo_then_utc(unix: f64) -> String {
    let utc = chrono::DateTime::from_timestamp(unix.round() as i64, 0).unwrap();
    let local = utc.with_timezone(&chrono_tz::Asia::Tokyo);
    let u = if local.date_naive() == utc.date_naive() {
        utc.format("%H:%M UTC")
    } else {
        utc.format("%Y-%m-%d %H:%M UTC")
    };
    format!("{} ({u})", local.format("%Y-%m-%d %H:%M JST"))
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_headline_says_the_worst_alert_its_failure_date_and_what_to_do() {
    let Some(driver) = Driver::start().await else {
        return;
    };
    let s = TestServer::start(|_| {}).await;
    let response = "Close the road below the face.\nSend the on-call geologist.";
    let contacts = [
        "Geologist on call: +81 90 1234 5678",
        "Road office: +81 3 0000 0000",
    ];
    let (st, e) = s
        .post(
            "/api/v1/sites",
            &json!({"id": "tf", "name": "Tanba face", "time_zone": "Asia/Tokyo", "model": "orthogonal",
                "response_text": response, "contacts": contacts, "schedule_hours": 24.0,
                "alert_rules": [
                    {"level": "watch", "metric": "displacement_mm", "above": 5.0, "clear_below": 4.0},
                    {"level": "alarm", "metric": "time_to_failure_hours", "below": 200.0}]}),
        )
        .await;
    assert_eq!(st, 201, "{e}");
    support::dashboard::fill_accelerating(&s, "tf").await;
    let (_, open) = s.get("/api/v1/alerts?site=tf&state=open").await;
    let alarmed: Vec<String> = open["items"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|a| a["level"] == "alarm" && a["rule"] == "time_to_failure_hours")
        .map(|a| a["point"].as_str().unwrap().to_string())
        .collect();
    assert!(!alarmed.is_empty(), "a time-to-failure alarm: {open}");

    driver.goto(&s.url("/sites/tf")).await;
    let what = driver
        .script("return document.querySelector('section.headline .what').textContent")
        .await;
    let what = what.as_str().unwrap().to_string();
    eprintln!("headline: {what}");
    // The words: level, subject, metric.
    let subject = what
        .strip_prefix("ALARM · point ")
        .and_then(|r| r.split(' ').next())
        .unwrap_or_else(|| panic!("{what}"));
    assert!(
        alarmed.iter().any(|p| p == subject),
        "{subject} of {alarmed:?}"
    );
    assert!(what.contains("; time to failure "), "{what}");
    // The failure date: the subject's last epoch plus its filtered time to failure, as the
    // API gives them, local time first then UTC, with its interval; counted from that epoch.
    let (_, series) = s
        .get(&format!(
            "/api/v1/sites/tf/points/{subject}/displacements?limit=1000"
        ))
        .await;
    let last: &Value = series["items"].as_array().unwrap().last().unwrap();
    let t0 = chrono::DateTime::parse_from_rfc3339(last["observed_at"].as_str().unwrap())
        .unwrap()
        .timestamp() as f64;
    let hours = last["f_time_to_failure_hours"]
        .as_f64()
        .expect("a forecast");
    let sigma = last["sigma_f_time_to_failure_hours"].as_f64().unwrap();
    assert!(
        what.contains(&format!("{hours:.0} ± {sigma:.0} h (1σ)")),
        "{hours} ± {sigma}: {what}"
    );
    // Its velocity ± 1σ, as the API gives it.
    let v = last["f_velocity_mm_per_day"].as_f64().unwrap();
    let sv = last["sigma_f_velocity_mm_per_day"].as_f64().unwrap();
    assert!(
        what.contains(&format!(" · velocity {v:.2} ± {sv:.2} mm/day (1σ) · ")),
        "{v} ± {sv}: {what}"
    );
    let expected = tokyo_then_utc(t0 + hours * 3600.0);
    assert!(
        what.contains(&format!(", expected {expected} (±2σ: ")),
        "{expected}: {what}"
    );
    // The one-sided bound the alarm rule reads, first: failure likely before it, and how far
    // that is from now (the fixture's epochs lie weeks in the past: passed).
    let bound_at = t0 + (hours + 1.6449 * sigma) * 3600.0;
    let bound = tokyo_then_utc(bound_at);
    assert!(
        what.contains(&format!(" · failure likely before {bound}, passed ")),
        "{bound}: {what}"
    );
    assert!(what.contains(" ago (95 %, one-sided); "), "{what}");
    let upper = tokyo_then_utc(t0 + (hours + 2.0 * sigma) * 3600.0);
    assert!(what.contains(&format!(" to {upper})")), "{upper}: {what}");
    assert!(
        what.contains(&format!(
            "the forecast of point {subject} counted from its last epoch ({})",
            tokyo_then_utc(t0)
        )),
        "{what}"
    );
    // The truth (day 16) is inside the interval the reader is given.
    let truth = chrono::DateTime::parse_from_rfc3339(&day(16))
        .unwrap()
        .timestamp() as f64;
    assert!(
        (t0 + (hours - 2.0 * sigma) * 3600.0) <= truth
            && truth <= t0 + (hours + 2.0 * sigma) * 3600.0,
        "truth {truth} outside {hours} ± 2·{sigma} h from {t0}"
    );
    // The last epoch's age, the response text (its line break kept) and the contacts.
    let rest = driver
        .script("var h = document.querySelector('section.headline'); return [h.querySelector('.last-epoch').textContent, h.querySelector('.response p').innerText, Array.from(h.querySelectorAll('.contacts li')).map(function (l) { return l.textContent; })]")
        .await;
    let epoch_line = rest[0].as_str().unwrap();
    assert!(
        epoch_line.starts_with(&format!("Last epoch {}, ", utc_and_tokyo(t0)))
            && epoch_line.contains(" d ")
            && epoch_line.contains(" ago")
            && epoch_line.contains("overdue"),
        "{epoch_line}"
    );
    assert_eq!(rest[1], json!(response));
    assert_eq!(rest[2], json!(contacts));
    // The point's page carries the same headline; its link leads to the subject.
    driver.screenshot("headline-desk.png").await;
    driver
        .goto(&s.url(&format!("/sites/tf/points/{}", name(0))))
        .await;
    let again = driver
        .script("return document.querySelector('section.headline .what').textContent")
        .await;
    assert_eq!(
        again.as_str().unwrap(),
        what,
        "same headline on a point page"
    );
    // Phones 390 and 360 px wide: the headline and the site page fit without scrolling sideways.
    for phone in [390u32, 360] {
        driver.emulate_phone_width(phone).await;
        driver.goto(&s.url("/sites/tf")).await;
        let width = driver
            .script("return [window.innerWidth, document.documentElement.scrollWidth, document.querySelector('section.headline').getBoundingClientRect().right]")
            .await;
        assert_eq!(width[0], json!(phone), "{width}");
        assert!(
            width[1].as_f64().unwrap() <= phone as f64,
            "{phone}: {width}"
        );
        assert!(
            width[2].as_f64().unwrap() <= phone as f64,
            "{phone}: {width}"
        );
        driver
            .screenshot(format!("headline-phone-{phone}.png"))
            .await;
    }
    // The accelerating points declared a block: the headline names the block, not a point,
    // and states the incident's forecast, the same instant the API's incident gives.
    driver.emulate_phone_width(1280).await;
    let members: Vec<String> = (support::dashboard::STABLE..support::dashboard::POINTS)
        .map(name)
        .collect();
    let r = s
        .client
        .put(s.url("/api/v1/sites/tf/groups/B1"))
        .json(&json!({"kind": "block", "points": members}))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200, "{}", r.text().await.unwrap());
    let (_, incidents) = s.get("/api/v1/sites/tf/incidents").await;
    let first = &incidents["items"][0];
    assert_eq!(first["id"], "block:B1", "{incidents}");
    let likely = chrono::DateTime::parse_from_rfc3339(
        first["forecast"]["likely_before"]
            .as_str()
            .unwrap_or_else(|| panic!("a forecast: {first}")),
    )
    .unwrap()
    .timestamp() as f64;
    for page in [
        "/sites/tf",
        "/sites/tf/groups/B1",
        &format!("/sites/tf/points/{}", members[0]),
    ] {
        driver.goto(&s.url(page)).await;
        let block_what = driver
            .script("return document.querySelector('section.headline .what').textContent")
            .await;
        let block_what = block_what.as_str().unwrap();
        eprintln!("{page}: {block_what}");
        assert!(
            block_what.starts_with("ALARM · block B1 · velocity "),
            "{page}: {block_what}"
        );
        assert!(
            block_what.contains(&format!(
                " · failure likely before {}, ",
                tokyo_then_utc(likely)
            )),
            "{page}: {block_what}"
        );
        assert!(
            block_what.contains(&format!(
                "the forecast of {} counted from its last epoch",
                first["forecast"]["from"].as_str().unwrap()
            )),
            "{page}: {block_what}"
        );
    }
    driver.screenshot("headline-block.png").await;
    driver.quit().await;
    s.stop().await;
}
