//! Shared by the dashboard tests: a site with a moving block, filled through the API.
#![allow(dead_code)]

use crate::support::server::{synthetic_epoch, TestServer};
use serde_json::{json, Value};

pub const SITE: &str = "kamo";
pub const NAME: &str = "Kamo <script>alert(1)</script> & cliff";
pub const STABLE: usize = 8;
pub const POINTS: usize = 16;

pub use super::{day, hour};

pub fn name(i: usize) -> String {
    format!("T{:03}", i + 1)
}

/// Creates the site with watch and warning rules, marks the stable points, uploads `epochs`
/// daily epochs with the block moving 2.5 mm a day.
pub async fn fill(s: &TestServer, epochs: usize, auth: Option<&str>) {
    let with = |r: reqwest::RequestBuilder| match auth {
        Some(t) => r.bearer_auth(t),
        None => r,
    };
    let r = with(s.client.post(s.url("/api/v1/sites")))
        .json(
            &json!({"id": SITE, "name": NAME, "model": "orthogonal", "alert_rules": [
            {"level": "watch", "metric": "displacement_mm", "above": 5.0, "clear_below": 4.0},
            {"level": "warning", "metric": "displacement_mm", "above": 10.0}]}),
        )
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 201);
    for i in 0..STABLE {
        let r = with(
            s.client
                .put(s.url(&format!("/api/v1/sites/{SITE}/points/{}", name(i)))),
        )
        .json(&json!({"role": "stable"}))
        .send()
        .await
        .unwrap();
        assert_eq!(r.status(), 200);
    }
    for k in 0..epochs {
        let body = synthetic_epoch(4, POINTS, &day(k), 500 + k as u64, 2.5 * k as f64, STABLE);
        let r = with(
            s.client
                .post(s.url(&format!("/api/v1/sites/{SITE}/epochs"))),
        )
        .json(&body)
        .send()
        .await
        .unwrap();
        assert_eq!(r.status(), 201, "epoch {k}");
    }
}

/// GETs `path`: its status and body (an HTML page when 200).
pub async fn html(s: &TestServer, path: &str) -> (u16, String) {
    let r = s.client.get(s.url(path)).send().await.unwrap();
    let status = r.status().as_u16();
    if status == 200 {
        let ct = r.headers()[reqwest::header::CONTENT_TYPE]
            .to_str()
            .unwrap()
            .to_string();
        assert!(ct.starts_with("text/html"), "{path}: {ct}");
    }
    (status, r.text().await.unwrap())
}

/// The `href="…"` targets of a page.
pub fn links(page: &str) -> Vec<String> {
    page.split("href=\"")
        .skip(1)
        .filter_map(|s| s.split('"').next())
        .map(str::to_string)
        .collect()
}

/// Marks the first [`STABLE`] points of `site` stable and uploads a block accelerating to
/// failure: the points from [`STABLE`] on follow d(t) = −v0·t_f·ln(1 − t/t_f), 1 mm/day at first,
/// failure at t_f = 16 days (day 16 = 2026-11-17 09:00 UTC), across the line of sight (σ ≈
/// 0.25 mm an epoch), with epochs every 6 h (as a site is observed once it accelerates) up to
/// 54 h before the failure.
pub async fn fill_accelerating(s: &TestServer, site: &str) {
    for i in 0..STABLE {
        let r = s
            .client
            .put(s.url(&format!("/api/v1/sites/{site}/points/{}", name(i))))
            .json(&json!({"role": "stable"}))
            .send()
            .await
            .unwrap();
        assert_eq!(r.status(), 200);
    }
    for k in 0..56 {
        let mm = -16.0 * (1.0 - k as f64 / 64.0).ln();
        let body = super::server::synthetic_epoch_moved(
            4,
            POINTS,
            &hour(6 * k),
            300 + k as u64,
            [mm, 0.0, 0.0],
            STABLE,
        );
        let (st, answer) = s.upload(site, &body).await;
        assert_eq!(st, 201, "epoch {k}: {answer}");
    }
}

/// Creates a site from `body` (the API's site form; 201 asserted) and marks the first
/// [`STABLE`] points stable.
pub async fn create_site_with_stable(s: &TestServer, body: Value) {
    let id = body["id"]
        .as_str()
        .expect("the site form names its id")
        .to_string();
    let r = s
        .client
        .post(s.url("/api/v1/sites"))
        .json(&body)
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 201, "{}", r.text().await.unwrap());
    for i in 0..STABLE {
        let r = s
            .client
            .put(s.url(&format!("/api/v1/sites/{id}/points/{}", name(i))))
            .json(&json!({"role": "stable"}))
            .send()
            .await
            .unwrap();
        assert_eq!(r.status(), 200);
    }
}

/// A page's text as a reader sees it: the tags removed, entities `&amp;`, `&lt;`, `&gt;`,
/// `&quot;` and `&#39;` decoded, runs of white space made one space.
pub fn text_of(page: &str) -> String {
    let no_tags = regex::Regex::new(r"(?s)<(script|style)\b.*?</(script|style)>|<[^>]*>")
        .unwrap()
        .replace_all(page, " ");
    let decoded = no_tags
        .replace("&lt;", "<")
        .replace("&gt;", ">")
        .replace("&quot;", "\"")
        .replace("&#39;", "'")
        .replace("&amp;", "&");
    decoded.split_whitespace().collect::<Vec<_>>().join(" ")
}
