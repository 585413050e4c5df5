//! Implausible input caught at the door (issue 77): a first epoch with its approximations in
//! millimetres, c in metres, pixels given as mm; an unknown metric, level or rule member; settings
//! for a point the site never measured. Each is refused with 422 naming the field, and nothing
//! is stored.

use crate::support;

use serde_json::{json, Value};
use support::server::{paper, synthetic_epoch, TestServer};

/// The error message of a refusal.
fn message(e: &Value) -> &str {
    e["error"]["message"].as_str().unwrap_or_default()
}

#[tokio::test]
async fn a_first_epoch_in_wrong_units_is_refused_naming_the_field() {
    let s = TestServer::start(|_| {}).await;
    s.create_site("units").await;
    let good = paper("paper-case1-seed101");
    let synthetic = synthetic_epoch(4, 16, "2026-11-01T09:00:00Z", 1, 0.0, 16);
    let before = s.snapshot().await;

    let mut cases: Vec<(&str, Value, &str, &str)> = Vec::new();
    for (name, epoch) in [("paper", &good), ("synthetic", &synthetic)] {
        let mut mm = epoch.clone();
        for a in mm["approx"].as_array_mut().unwrap() {
            for k in ["X", "Y", "Z"] {
                a[k] = json!(a[k].as_f64().unwrap() * 1000.0);
            }
        }
        cases.push((name, mm, "approx: ", "look like millimetres"));
        let mut metres = epoch.clone();
        metres["cameras"][0]["c_mm"] = json!(0.3);
        cases.push((
            name,
            metres,
            "cameras[0].c_mm (camera 'cam'): ",
            "looks like metres",
        ));
        let mut pixels = epoch.clone();
        for image in pixels["images"].as_array_mut().unwrap() {
            for o in image["observations"].as_array_mut().unwrap() {
                for k in ["x_mm", "y_mm"] {
                    o[k] = json!(o[k].as_f64().unwrap() / 0.005);
                }
            }
        }
        cases.push((name, pixels, ".x_mm, y_mm: ", "look like pixels"));
    }
    for (name, body, field, what) in &cases {
        let (status, e) = s.upload("units", body).await;
        assert_eq!(status, 422, "{name} {field}: {e}");
        assert_eq!(e["error"]["code"], "invalid_epoch", "{e}");
        let m = message(&e);
        assert!(m.contains(field), "{name}: {m}");
        assert!(m.contains(what), "{name}: {m}");
        assert!(m.contains("; expected "), "{name}: {m}");
    }
    // Nothing stored: no epoch listed, no row anywhere.
    let (_, list) = s.get("/api/v1/sites/units/epochs").await;
    assert_eq!(list["items"], json!([]), "{list}");
    let (_, points) = s.get("/api/v1/sites/units/points").await;
    assert_eq!(points["items"], json!([]), "{points}");
    assert_eq!(s.snapshot().await, before);
    // The same epochs in the right units are taken.
    assert_eq!(s.upload("units", &good).await.0, 201);
    s.stop().await;
}

#[tokio::test]
async fn an_unknown_metric_level_or_member_is_named() {
    let s = TestServer::start(|_| {}).await;
    let before = s.snapshot().await;
    for (rule, want) in [
        (
            json!({"level": "watch", "metric": "displacement_m", "above": 5}),
            "alert_rules[0].metric: unknown metric 'displacement_m' (one of displacement_mm, \
             displacement_along_mm, velocity_mm_per_day, time_to_failure_hours)",
        ),
        (
            json!({"level": "red", "metric": "displacement_mm", "above": 5}),
            "alert_rules[0].level: unknown alert level 'red' (one of watch, warning, alarm)",
        ),
        (
            json!({"level": "watch", "metric": "displacement_mm", "abov": 5}),
            "alert_rules[0].abov: unknown member; a rule has level, metric, above",
        ),
    ] {
        let body = json!({"id": "rules", "name": "Rules", "alert_rules": [rule]});
        let (status, e) = s.post("/api/v1/sites", &body).await;
        assert_eq!(status, 422, "{e}");
        assert_eq!(e["error"]["code"], "invalid_site", "{e}");
        assert!(message(&e).starts_with(want), "{e}");
    }
    let (status, _) = s.get("/api/v1/sites/rules").await;
    assert_eq!(status, 404, "nothing created");
    assert_eq!(s.snapshot().await, before);
    s.stop().await;
}

#[tokio::test]
async fn settings_for_a_point_never_measured_are_refused_unless_planned() {
    let s = TestServer::start(|_| {}).await;
    s.create_site("pts").await;
    // Before the first epoch every point is planned: roles are set up front.
    let (status, p) = s
        .send(
            reqwest::Method::PUT,
            "/api/v1/sites/pts/points/1",
            Some(&json!({"role": "stable"})),
        )
        .await;
    assert_eq!(status, 200, "{p}");
    assert_eq!(s.upload("pts", &paper("paper-case1-seed101")).await.0, 201);
    let (_, points) = s.get("/api/v1/sites/pts/points?limit=1000").await;
    let before = s.snapshot().await;
    // A name no epoch observed: refused, naming it.
    let (status, e) = s
        .send(
            reqwest::Method::PUT,
            "/api/v1/sites/pts/points/T999",
            Some(&json!({"role": "stable"})),
        )
        .await;
    assert_eq!(status, 422, "{e}");
    assert_eq!(e["error"]["code"], "invalid_point", "{e}");
    let m = message(&e);
    assert!(
        m.starts_with("point 'T999': site 'pts' has never measured it"),
        "{m}"
    );
    assert!(m.contains("\"planned\": true"), "{m}");
    assert_eq!(s.snapshot().await, before, "nothing stored");
    assert_eq!(s.get("/api/v1/sites/pts/points?limit=1000").await.1, points);
    // A measured point is set as before.
    let (status, p) = s
        .send(
            reqwest::Method::PUT,
            "/api/v1/sites/pts/points/2",
            Some(&json!({"role": "stable"})),
        )
        .await;
    assert_eq!((status, &p["role"]), (200, &json!("stable")), "{p}");
    // Declared planned: set up, and listed.
    let (status, p) = s
        .send(
            reqwest::Method::PUT,
            "/api/v1/sites/pts/points/T999",
            Some(&json!({"role": "stable", "planned": true})),
        )
        .await;
    assert_eq!((status, &p["role"]), (200, &json!("stable")), "{p}");
    let (_, after) = s.get("/api/v1/sites/pts/points?limit=1000").await;
    assert!(
        after["items"]
            .as_array()
            .unwrap()
            .iter()
            .any(|i| i["point"] == "T999"),
        "{after}"
    );
    s.stop().await;
}

/// A warning that does not block: the synthetic epoch's image noise (about 0.0006 mm) is a third
/// of the default a-priori σ (0.002 mm). The upload is stored, and the answer and the epoch page
/// say so in words.
#[tokio::test]
async fn an_apriori_sigma_far_from_the_scatter_is_said_in_the_answer_and_on_the_page() {
    let s = TestServer::start(|_| {}).await;
    s.create_site("sigma").await;
    let epoch = synthetic_epoch(4, 16, "2026-11-01T09:00:00Z", 1, 0.0, 16);
    let (status, answer) = s.upload("sigma", &epoch).await;
    assert_eq!(status, 201, "{answer}");
    let warning = answer["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(Value::as_str)
        .find(|w| w.starts_with("the image measurements agree"))
        .unwrap_or_else(|| panic!("no a-priori σ warning in {}", answer["warnings"]))
        .to_string();
    assert!(warning.contains("set sigma_mm nearer"), "{warning}");
    let (status, page) =
        support::dashboard::html(&s, &format!("/sites/sigma/epochs/{}", answer["id"])).await;
    assert_eq!(status, 200);
    assert!(page.contains("than their stated precision"), "{page}");
    s.stop().await;
}
