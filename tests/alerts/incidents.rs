//! Incidents: one per declared block with every alert of its points and its own, listed through
//! the API, acknowledged in one action (API and dashboard form), each alert recorded with who and
//! the comment; acknowledging again is 409, an unknown incident 404.

use crate::support;

use std::collections::BTreeSet;

use reqwest::Method;
use serde_json::{json, Value};
use support::alerts::{
    day, mark_stable, outbox_events, outbox_payloads, upload_new, write_config, Daemon, Scene,
};

/// Site `id`: displacement watch and warning rules for every point and the block, the scene's
/// fixed points stable, its moving points block B1, and `extra` (a point outside the block
/// moving with it: index 15 of 16 is left out of B1).
async fn site_with_block(d: &Daemon, id: &str, scene: &Scene) -> Vec<String> {
    let (s, b) = d
        .send(
            Method::POST,
            "/api/v1/sites",
            Some(&json!({"id": id, "alert_rules": [
                {"level": "watch", "metric": "displacement_mm", "above": 5.0, "clear_below": 4.0},
                {"level": "warning", "metric": "displacement_mm", "above": 10.0, "clear_below": 8.0}]})),
        )
        .await;
    assert_eq!(s, 201, "{b}");
    mark_stable(d, id, scene).await;
    let block: Vec<String> = (scene.stable..scene.n - 1).map(Scene::name).collect();
    let (s, g) = d
        .send(
            Method::PUT,
            &format!("/api/v1/sites/{id}/groups/B1"),
            Some(&json!({"kind": "block", "direction": [0.0, -1.0, 0.0], "points": block})),
        )
        .await;
    assert_eq!(s, 200, "{g}");
    block
}

async fn incidents(d: &Daemon, site: &str) -> Vec<Value> {
    let (s, b) = d.get(&format!("/api/v1/sites/{site}/incidents")).await;
    assert_eq!(s, 200, "{b}");
    b["items"].as_array().unwrap().clone()
}

async fn open_alerts(d: &Daemon, site: &str) -> Vec<Value> {
    let (s, a) = d
        .get(&format!("/api/v1/alerts?site={site}&limit=1000"))
        .await;
    assert_eq!(s, 200, "{a}");
    a["items"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|a| a["state"] != "resolved")
        .cloned()
        .collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_block_is_one_incident_acknowledged_in_one_action() {
    let dir = tempfile::tempdir().unwrap();
    let public = "https://cw.example.org";
    let config = write_config(dir.path(), &format!("public_url = \"{public}/\""));
    let data = dir.path().join("data");
    let d = Daemon::start(&data, &config).await;
    let scene = Scene { n: 16, stable: 8 };
    let block = site_with_block(&d, "cliff", &scene).await;
    for k in 0..3 {
        upload_new(
            &d,
            "cliff",
            &scene.epoch(&day(k), 700 + k as u64, 8.0 * k as f64),
        )
        .await;
    }
    let alerts = open_alerts(&d, "cliff").await;
    let outside = Scene::name(scene.n - 1);
    let of_block: BTreeSet<String> = alerts
        .iter()
        .filter(|a| {
            a["group"] == "B1"
                || a["point"]
                    .as_str()
                    .is_some_and(|p| block.iter().any(|b| b == p))
        })
        .map(|a| a["id"].as_str().unwrap().to_string())
        .collect();
    // Every point of the block alerts, and the block itself: many alerts, one incident.
    assert!(of_block.len() > block.len(), "{alerts:#?}");
    let list = incidents(&d, "cliff").await;
    let b1: Vec<&Value> = list.iter().filter(|i| i["id"] == "block:B1").collect();
    assert_eq!(b1.len(), 1, "{list:#?}");
    let b1 = b1[0];
    assert_eq!(b1["kind"], "block");
    assert_eq!(b1["subject"], "B1");
    assert_eq!(b1["level"], "warning");
    assert_eq!(b1["state"], "open");
    assert_eq!(b1["page"], "/sites/cliff/groups/B1");
    let ids: BTreeSet<String> = b1["alert_ids"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap().to_string())
        .collect();
    assert_eq!(ids, of_block);
    let points: Vec<&str> = b1["points"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap())
        .collect();
    assert_eq!(points, block.iter().map(String::as_str).collect::<Vec<_>>());
    // The point outside the block is an incident of its own; no alert is in two incidents.
    assert!(
        list.iter().any(|i| i["id"] == format!("point:{outside}")),
        "{list:#?}"
    );
    let all: usize = list
        .iter()
        .map(|i| i["alert_ids"].as_array().unwrap().len())
        .sum();
    assert_eq!(all, alerts.len());

    // Every webhook body names its alert's incident and links the incident's page: the block's
    // for the block and its points, the point's own for the point outside it.
    let payloads = outbox_payloads(&data).await;
    assert!(!payloads.is_empty());
    for (alert, p) in &payloads {
        let (key, page) = if of_block.contains(alert) {
            ("block:B1".to_string(), "/sites/cliff/groups/B1".to_string())
        } else {
            let point = p["data"]["point"].as_str().expect("a point alert");
            assert_eq!(point, outside, "{p}");
            (
                format!("point:{point}"),
                format!("/sites/cliff/points/{point}"),
            )
        };
        assert_eq!(p["data"]["incident"], key, "{p}");
        assert_eq!(p["data"]["incident_url"], format!("{public}{page}"), "{p}");
    }
    // That page (the block's) lists the incident's alerts and acknowledges them in one form; a
    // member point's page sends the reader to it.
    let (s, html) = d.get_text("/sites/cliff/groups/B1").await;
    assert_eq!(s, 200);
    assert!(html.contains("data-subject=\"block:B1\""), "{html}");
    assert!(
        html.contains(&format!("acknowledge all {} open alerts", of_block.len())),
        "{html}"
    );
    let (s, html) = d
        .get_text(&format!("/sites/cliff/points/{}", block[0]))
        .await;
    assert_eq!(s, 200);
    assert!(
        html.contains("incident of block B1") && html.contains("href=\"/sites/cliff/groups/B1\""),
        "{html}"
    );

    // One acknowledgement acknowledges every alert of the block, each with who and the comment,
    // and queues one alert.acknowledged per alert.
    let acked_before = outbox_events(&data)
        .await
        .iter()
        .filter(|(_, t, _)| t == "alert.acknowledged")
        .count();
    let (s, after) = d
        .send(
            Method::POST,
            "/api/v1/sites/cliff/incidents/block:B1/ack",
            Some(&json!({"by": "geologist", "comment": "road closed"})),
        )
        .await;
    assert_eq!(s, 200, "{after}");
    assert_eq!(after["state"], "acknowledged", "{after}");
    assert_eq!(after["acknowledged_by"], json!(["geologist"]));
    for a in open_alerts(&d, "cliff").await {
        let id = a["id"].as_str().unwrap();
        if of_block.contains(id) {
            assert_eq!(a["state"], "acknowledged", "{a}");
            assert_eq!(a["acknowledged_by"], "geologist", "{a}");
            assert_eq!(a["ack_comment"], "road closed", "{a}");
        } else {
            assert_eq!(a["state"], "open", "the point outside the block: {a}");
        }
    }
    let acked_after = outbox_events(&data)
        .await
        .iter()
        .filter(|(_, t, _)| t == "alert.acknowledged")
        .count();
    assert_eq!(acked_after - acked_before, of_block.len());

    // Again: 409 naming who; an unknown incident: 404; a blank name: 422, nothing changed.
    let (s, b) = d
        .send(
            Method::POST,
            "/api/v1/sites/cliff/incidents/block:B1/ack",
            Some(&json!({"by": "someone else"})),
        )
        .await;
    assert_eq!(s, 409, "{b}");
    assert!(
        b["error"]["message"]
            .as_str()
            .unwrap()
            .contains("geologist"),
        "{b}"
    );
    let (s, b) = d
        .send(
            Method::POST,
            "/api/v1/sites/cliff/incidents/block:B9/ack",
            Some(&json!({"by": "geologist"})),
        )
        .await;
    assert_eq!(s, 404, "{b}");
    assert!(
        b["error"]["message"].as_str().unwrap().contains("block:B9"),
        "{b}"
    );
    let point = format!("/api/v1/sites/cliff/incidents/point:{outside}/ack");
    let (s, b) = d
        .send(Method::POST, &point, Some(&json!({"by": "  "})))
        .await;
    assert_eq!(s, 422, "{b}");
    assert!(open_alerts(&d, "cliff")
        .await
        .iter()
        .any(|a| a["point"] == outside.as_str() && a["state"] == "open"));

    // The site page: one row for the block, its form acknowledges the point outside's incident.
    let page = d
        .client
        .get(format!("{}/sites/cliff", d.base))
        .send()
        .await
        .unwrap()
        .text()
        .await
        .unwrap();
    assert_eq!(page.matches("data-subject=\"block:B1\"").count(), 1);
    let form_action = format!("/dashboard/sites/cliff/incidents/point%3A{outside}/ack");
    assert!(page.contains(&form_action), "{page}");
    assert!(
        !page.contains("/dashboard/sites/cliff/incidents/block%3AB1/ack"),
        "an acknowledged incident has no form"
    );
    let r = d
        .client
        .post(format!("{}{}", d.base, form_action))
        .form(&[("by", "night shift"), ("comment", "")])
        .send()
        .await
        .unwrap();
    assert!(
        r.status().is_success() || r.status().is_redirection(),
        "{}",
        r.status()
    );
    assert!(open_alerts(&d, "cliff")
        .await
        .iter()
        .filter(|a| a["point"] == outside.as_str())
        .all(|a| a["state"] == "acknowledged" && a["acknowledged_by"] == "night shift"));
}
