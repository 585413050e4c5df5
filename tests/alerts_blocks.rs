//! Blocks and the site settings of the filtered analysis, through the daemon's HTTP API: a declared
//! block group raises one group alert (`point` null, `group`, its points) from the block's motion;
//! `reference_epochs` averages the first epochs into the reference and recomputes; bad settings
//! answer 422 naming the field and store nothing.

mod alerts_support;

use alerts_support::{day, mark_stable, upload_new, write_config, Daemon, Scene};
use reqwest::Method;
use serde_json::{json, Value};

async fn alerts(d: &Daemon, site: &str) -> Vec<Value> {
    let (s, a) = d
        .get(&format!("/api/v1/alerts?site={site}&limit=1000"))
        .await;
    assert_eq!(s, 200, "{a}");
    a["items"].as_array().unwrap().clone()
}

async fn create(d: &Daemon, body: Value) -> (u16, Value) {
    d.send(Method::POST, "/api/v1/sites", Some(&body)).await
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_declared_block_raises_one_group_alert() {
    let dir = tempfile::tempdir().unwrap();
    let config = write_config(dir.path(), "");
    let d = Daemon::start(&dir.path().join("data"), &config).await;
    let scene = Scene { n: 16, stable: 8 };
    // A warning rule for the block only; no point rule.
    let (s, b) = create(
        &d,
        json!({"id": "cliff", "alert_rules": [
            {"level": "warning", "metric": "displacement_mm", "above": 10.0, "group": "B1"}]}),
    )
    .await;
    assert_eq!(s, 201, "{b}");
    mark_stable(&d, "cliff", &scene).await;
    let block: Vec<String> = (scene.stable..scene.n).map(Scene::name).collect();
    let (s, g) = d
        .send(
            Method::PUT,
            "/api/v1/sites/cliff/groups/B1",
            Some(&json!({"kind": "block", "direction": [0.0, -1.0, 0.0], "points": block})),
        )
        .await;
    assert_eq!(s, 200, "{g}");
    assert_eq!(g["name"], "B1");
    assert_eq!(g["points"].as_array().unwrap().len(), block.len());
    let (s, all) = d.get("/api/v1/sites/cliff/groups").await;
    assert_eq!(s, 200, "{all}");
    assert_eq!(all.as_array().unwrap().len(), 1);
    for k in 0..3 {
        upload_new(
            &d,
            "cliff",
            &scene.epoch(&day(k), 300 + k as u64, 8.0 * k as f64),
        )
        .await;
    }
    // 16 mm: the block's translation (8 points averaged) exceeds 10 mm at 99 %.
    let open = alerts(&d, "cliff").await;
    assert_eq!(open.len(), 1, "{open:?}");
    let a = &open[0];
    assert_eq!(a["rule"], "displacement_mm");
    assert_eq!(a["level"], "warning");
    assert!(a["point"].is_null(), "{a}");
    assert_eq!(a["group"], "B1");
    let points: Vec<&str> = a["points"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p.as_str().unwrap())
        .collect();
    assert_eq!(points.len(), block.len(), "{a}");
    let v = a["value"].as_f64().unwrap();
    assert!(
        (v - 16.0).abs() < 3.0,
        "block translation {v} mm against 16 mm"
    );
    // The series carries the filtered state of every point after the first epochs.
    let (s, series) = d
        .get(&format!(
            "/api/v1/sites/cliff/points/{}/displacements",
            block[0]
        ))
        .await;
    assert_eq!(s, 200, "{series}");
    assert_eq!(series["items"].as_array().unwrap().len(), 3);
    // Unknown site and bad bodies.
    let (s, _) = d
        .send(
            Method::PUT,
            "/api/v1/sites/nowhere/groups/B1",
            Some(&json!({"kind": "block"})),
        )
        .await;
    assert_eq!(s, 404);
    for (body, field) in [
        (json!({"kind": "slab"}), "kind"),
        (
            json!({"kind": "block", "direction": [0.0, 0.0, 0.0]}),
            "direction",
        ),
        (
            json!({"kind": "block", "process_noise": -1.0}),
            "process_noise",
        ),
        (json!({"kind": "block", "points": ["a b"]}), "points"),
    ] {
        let (s, b) = d
            .send(Method::PUT, "/api/v1/sites/cliff/groups/B2", Some(&body))
            .await;
        assert_eq!(s, 422, "{body}: {b}");
        assert!(
            b["error"]["message"].as_str().unwrap().contains(field),
            "{body}: {b}"
        );
    }
    let (s, _) = d.get("/api/v1/sites/cliff/groups/B2").await;
    assert_eq!(s, 404, "nothing stored");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn site_settings_are_validated_and_a_reference_of_several_epochs_is_averaged() {
    let dir = tempfile::tempdir().unwrap();
    let config = write_config(dir.path(), "");
    let d = Daemon::start(&dir.path().join("data"), &config).await;
    for (body, field) in [
        (
            json!({"id": "a", "reference_epochs": 0}),
            "reference_epochs",
        ),
        (json!({"id": "a", "process_noise": 0.0}), "process_noise"),
        (json!({"id": "a", "confidence": 0.4}), "confidence"),
        (
            json!({"id": "a", "alert_rules": [{"level": "watch", "metric": "displacement_mm", "above": 5, "for_epochs": 0}]}),
            "for_epochs",
        ),
        (
            json!({"id": "a", "alert_rules": [{"level": "watch", "metric": "displacement_mm", "above": 5, "source": "smoothed"}]}),
            "alert_rules[0]",
        ),
    ] {
        let (s, b) = create(&d, body.clone()).await;
        assert_eq!(s, 422, "{body}: {b}");
        assert!(
            b["error"]["message"].as_str().unwrap().contains(field),
            "{body}: {b}"
        );
        let (s, _) = d.get("/api/v1/sites/a").await;
        assert_eq!(s, 404, "nothing stored for {body}");
    }
    // Two sites fed the same still epochs: one against epoch 1, one against the mean of 3.
    let scene = Scene { n: 12, stable: 6 };
    for (id, k) in [("one", 1), ("three", 3)] {
        let (s, b) = create(&d, json!({"id": id, "reference_epochs": k})).await;
        assert_eq!(s, 201, "{b}");
        assert_eq!(b["reference_epochs"], k);
        mark_stable(&d, id, &scene).await;
        for e in 0..5 {
            upload_new(&d, id, &scene.epoch(&day(e), 500 + e as u64, 0.0)).await;
        }
    }
    let point = Scene::name(9);
    let mut sigma = vec![];
    for id in ["one", "three"] {
        let (s, b) = d
            .get(&format!("/api/v1/sites/{id}/points/{point}/displacements"))
            .await;
        assert_eq!(s, 200, "{b}");
        let items = b["items"].as_array().unwrap().clone();
        assert_eq!(items.len(), 5);
        sigma.push(items[4]["sigma_dz_mm"].as_f64().unwrap());
        if id == "three" {
            // The first epoch is part of the mean: its displacement is no longer exactly zero.
            assert!(items[0]["d_mm"].as_f64().unwrap() > 0.0, "{:?}", items[0]);
        }
    }
    // σ of a displacement against the mean of 3 epochs: √(1 + 1/3) instead of √2 times one
    // epoch's (the stable-point datum adds a little to both).
    let ratio = sigma[1] / sigma[0];
    assert!(
        (0.7..0.95).contains(&ratio),
        "σ against the mean of 3 / against one epoch = {ratio} ({sigma:?})"
    );
}
