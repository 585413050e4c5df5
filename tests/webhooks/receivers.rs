//! The other receivers' own checkers on what a node serves: `promtool check metrics` (Debian's
//! `prometheus`) on a fresh node's `/metrics`, where every series is already there at zero, and
//! on one that has served an upload; `openapi-spec-validator` (PyPI) on `/api/v1/openapi.json`,
//! whose operationIds are unique; `POST /api/v1/webhooks/{id}/test` against a receiver that
//! verifies the signature, and one that refuses; an unpadded `whsec_` secret accepted. Under
//! `CI=true` a missing checker fails the test.

use crate::support;

use std::collections::BTreeSet;
use std::io::Write;
use std::process::{Command, Stdio};

use reqwest::Method;
use serde_json::{json, Value};
use support::alerts::{create_site, day, upload_new, write_config, Daemon, Receiver, Scene};

/// Whether `program` runs; outside CI a missing one skips (printed), under `CI=true` it fails.
fn available(program: &str, args: &[&str], package: &str) -> bool {
    let ok = Command::new(program)
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    if !ok {
        if std::env::var("CI").is_ok_and(|v| v == "true") {
            panic!("CI=true: {program} missing ({package}; .ci/run installs it)");
        }
        eprintln!("skipped: {program} missing (install {package})");
    }
    ok
}

/// Runs `program args` with `input` on stdin; returns (success, stdout + stderr).
fn run_with_input(program: &str, args: &[&str], input: &[u8]) -> (bool, String) {
    let mut child = Command::new(program)
        .args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    child.stdin.take().unwrap().write_all(input).unwrap();
    let out = child.wait_with_output().unwrap();
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    (out.status.success(), text)
}

async fn metrics_text(d: &Daemon) -> String {
    let r = d.client.get(d.url("/metrics")).send().await.unwrap();
    assert_eq!(r.status(), 200);
    r.text().await.unwrap()
}

/// The value of the series whose line starts with `name{` and holds every `label`.
fn series(text: &str, name: &str, labels: &[&str]) -> Option<f64> {
    text.lines()
        .filter(|l| l.starts_with(&format!("{name}{{")) || l.starts_with(&format!("{name} ")))
        .find(|l| labels.iter().all(|x| l.contains(x)))
        .and_then(|l| l.rsplit(' ').next())
        .and_then(|v| v.parse().ok())
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn promtool_passes_the_metrics_of_a_fresh_node_and_after_an_upload() {
    if !available("promtool", &["--version"], "Debian's prometheus") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let config = write_config(dir.path(), "");
    let d = Daemon::start(&dir.path().join("data"), &config).await;
    let fresh = metrics_text(&d).await;
    let (ok, out) = run_with_input("promtool", &["check", "metrics"], fresh.as_bytes());
    assert!(ok, "promtool on a fresh node: {out}\n{fresh}");
    // Every series at zero from the start, for absent() and rate() rules.
    for (name, labels) in [
        ("cliffwatch_uploads_total", &["status=\"201\""][..]),
        ("cliffwatch_adjustments_total", &["outcome=\"ok\""][..]),
        ("cliffwatch_adjustments_total", &["outcome=\"failed\""][..]),
        ("cliffwatch_alerts_raised_total", &[][..]),
        (
            "cliffwatch_webhook_deliveries_total",
            &["outcome=\"ok\""][..],
        ),
        (
            "cliffwatch_webhook_deliveries_total",
            &["outcome=\"retry\""][..],
        ),
        (
            "cliffwatch_webhook_deliveries_total",
            &["outcome=\"failed\""][..],
        ),
        (
            "cliffwatch_alertmanager_posts_total",
            &["outcome=\"ok\""][..],
        ),
        (
            "cliffwatch_alertmanager_posts_total",
            &["outcome=\"failed\""][..],
        ),
        ("cliffwatch_webhook_queue_depth", &[][..]),
        ("cliffwatch_upload_slots_busy", &[][..]),
        ("cliffwatch_webhook_deliveries_pruned_total", &[][..]),
        ("cliffwatch_epoch_observations_pruned_total", &[][..]),
        ("cliffwatch_watch_folders_pruned_total", &[][..]),
    ] {
        assert_eq!(
            series(&fresh, name, labels),
            Some(0.0),
            "{name} {labels:?} on a fresh node:\n{fresh}"
        );
    }
    // After an upload: the counters moved, the histogram has its sample, promtool still passes.
    create_site(
        &d,
        "cliff",
        json!([{"level": "watch", "metric": "displacement_mm", "above": 5.0}]),
    )
    .await;
    let scene = Scene { n: 12, stable: 6 };
    upload_new(&d, "cliff", &scene.epoch(&day(0), 31, 0.0)).await;
    let after = metrics_text(&d).await;
    let (ok, out) = run_with_input("promtool", &["check", "metrics"], after.as_bytes());
    assert!(ok, "promtool after an upload: {out}\n{after}");
    assert_eq!(
        series(&after, "cliffwatch_uploads_total", &["status=\"201\""]),
        Some(1.0)
    );
    assert_eq!(
        series(&after, "cliffwatch_adjustments_total", &["outcome=\"ok\""]),
        Some(1.0)
    );
    assert_eq!(
        series(&after, "cliffwatch_adjustment_seconds_count", &[]),
        Some(1.0),
        "{after}"
    );
    // The adjustment time is a histogram (buckets Prometheus can aggregate), not a summary.
    assert_eq!(
        series(
            &after,
            "cliffwatch_adjustment_seconds_bucket",
            &["le=\"+Inf\""]
        ),
        Some(1.0),
        "{after}"
    );
    assert!(!after.contains("cliffwatch_adjustment_seconds{"), "{after}");
    // Per site: open alerts by level, the age of the last epoch, the watched folders at zero.
    for level in ["watch", "warning", "alarm"] {
        assert_eq!(
            series(
                &after,
                "cliffwatch_open_alerts",
                &["site=\"cliff\"", &format!("level=\"{level}\"")]
            ),
            Some(0.0),
            "{after}"
        );
    }
    let age = series(
        &after,
        "cliffwatch_last_epoch_age_seconds",
        &["site=\"cliff\""],
    )
    .unwrap_or_else(|| panic!("{after}"));
    let expected = (chrono::Utc::now().fixed_offset()
        - chrono::DateTime::parse_from_rfc3339(&day(0)).unwrap())
    .num_seconds() as f64;
    assert!(
        (age - expected).abs() < 120.0,
        "{age} s against {expected} s"
    );
    assert_eq!(
        series(
            &after,
            "cliffwatch_watch_folders_total",
            &["site=\"cliff\"", "outcome=\"failed\""]
        ),
        Some(0.0),
        "{after}"
    );
    // The block moves 10 mm against the stable points: the gauge counts the watch alerts the
    // API lists.
    support::alerts::mark_stable(&d, "cliff", &scene).await;
    upload_new(&d, "cliff", &scene.epoch(&day(1), 32, 10.0)).await;
    let moved = metrics_text(&d).await;
    let (_, open) = d.get("/api/v1/alerts?site=cliff&state=open").await;
    let watch = open["items"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|a| a["level"] == "watch")
        .count();
    assert!(watch > 0, "{open}");
    assert_eq!(
        series(
            &moved,
            "cliffwatch_open_alerts",
            &["site=\"cliff\"", "level=\"watch\""]
        ),
        Some(watch as f64),
        "{moved}"
    );
}

/// The shipped operations rules (`deploy/prometheus/cliffwatch.rules.yml`) pass `promtool check
/// rules`, and their unit tests (an unreachable daemon, an overdue campaign, a failed watched
/// folder, webhook deliveries that gave up, each with the times it must and must not fire)
/// pass `promtool test rules`.
#[test]
fn the_operations_rules_pass_promtool() {
    if !available("promtool", &["--version"], "Debian's prometheus") {
        return;
    }
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("deploy/prometheus");
    for args in [
        &["check", "rules", "cliffwatch.rules.yml"][..],
        &["test", "rules", "cliffwatch.rules.test.yml"][..],
    ] {
        let out = Command::new("promtool")
            .args(args)
            .current_dir(&dir)
            .output()
            .unwrap();
        let text = format!(
            "{}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
        assert!(out.status.success(), "promtool {args:?}: {text}");
        assert!(text.contains("SUCCESS"), "promtool {args:?}: {text}");
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_openapi_document_is_valid_with_unique_operation_ids() {
    let dir = tempfile::tempdir().unwrap();
    let config = write_config(dir.path(), "");
    let d = Daemon::start(&dir.path().join("data"), &config).await;
    let (s, doc) = d.get("/api/v1/openapi.json").await;
    assert_eq!(s, 200);
    let mut ids = vec![];
    for (path, item) in doc["paths"].as_object().unwrap() {
        for (method, op) in item.as_object().unwrap() {
            let id = op["operationId"]
                .as_str()
                .unwrap_or_else(|| panic!("{method} {path}: no operationId"));
            ids.push(id.to_string());
        }
    }
    let unique: BTreeSet<&String> = ids.iter().collect();
    assert_eq!(unique.len(), ids.len(), "operationIds repeat: {ids:?}");
    for id in [
        "list_sites",
        "get_site",
        "upload_epoch",
        "test_webhook",
        "list_alerts",
    ] {
        assert!(unique.contains(&id.to_string()), "{id} missing: {ids:?}");
    }
    if !available(
        "python3",
        &["-c", "import openapi_spec_validator"],
        "openapi-spec-validator from PyPI",
    ) {
        return;
    }
    let file = dir.path().join("openapi.json");
    std::fs::write(&file, serde_json::to_vec(&doc).unwrap()).unwrap();
    let out = Command::new("python3")
        .args(["-m", "openapi_spec_validator"])
        .arg(&file)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "openapi-spec-validator: {}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_test_notification_reports_the_receivers_answer() {
    let dir = tempfile::tempdir().unwrap();
    let config = write_config(dir.path(), "");
    let d = Daemon::start(&dir.path().join("data"), &config).await;
    // An unpadded secret, as the Standard Webhooks libraries accept: a 23-byte key, whose
    // padded base64 ends in one `=`.
    let unpadded = "whsec_Y2xpZmZ3YXRjaC11bnBhZGRlZC1rZXk";
    assert!(cliffwatch::webhooks::signing_key(unpadded).is_ok());
    assert_eq!(
        cliffwatch::webhooks::signing_key(unpadded).unwrap(),
        cliffwatch::webhooks::signing_key(&format!("{unpadded}=")).unwrap()
    );
    let good = Receiver::start_with_secret(0, unpadded).await;
    let refusing = Receiver::start_with_secret(1, support::alerts::SECRET).await;
    let am = Receiver::start_with_secret(0, support::alerts::SECRET).await;
    let mut ids = vec![];
    for (url, secret, format) in [
        (&good.url, unpadded, "standard"),
        (&refusing.url, support::alerts::SECRET, "standard"),
        (&am.url, support::alerts::SECRET, "alertmanager_api_v2"),
    ] {
        let (s, b) = d
            .send(
                Method::POST,
                "/api/v1/webhooks",
                Some(&json!({"url": url, "secret": secret, "format": format})),
            )
            .await;
        assert_eq!(s, 201, "{format}: {b}");
        ids.push(b["id"].as_str().unwrap().to_string());
    }
    let (s, r) = d
        .send(
            Method::POST,
            &format!("/api/v1/webhooks/{}/test", ids[0]),
            None,
        )
        .await;
    assert_eq!(s, 200, "{r}");
    assert_eq!(r["delivered"], true, "{r}");
    assert_eq!(r["status"], 200, "{r}");
    let log = good.log.lock().unwrap().clone();
    assert_eq!(log.len(), 1);
    assert_eq!(log[0].id, r["message_id"].as_str().unwrap());
    assert_eq!(log[0].body["type"], "test");
    assert_eq!(
        good.bad_signatures
            .load(std::sync::atomic::Ordering::SeqCst),
        0
    );
    // The refusing receiver answers 503: reported, not retried.
    let (s, r) = d
        .send(
            Method::POST,
            &format!("/api/v1/webhooks/{}/test", ids[1]),
            None,
        )
        .await;
    assert_eq!(s, 200, "{r}");
    assert_eq!(r["delivered"], false, "{r}");
    assert_eq!(r["status"], 503, "{r}");
    assert!(r["error"].as_str().unwrap().contains("503"), "{r}");
    assert_eq!(refusing.log.lock().unwrap().len(), 1, "sent once");
    // Alertmanager's format: one postable alert that names no site.
    let (s, r) = d
        .send(
            Method::POST,
            &format!("/api/v1/webhooks/{}/test", ids[2]),
            None,
        )
        .await;
    assert_eq!(s, 200, "{r}");
    assert_eq!(r["delivered"], true, "{r}");
    let tests: Vec<Value> = am
        .log
        .lock()
        .unwrap()
        .iter()
        .filter(|m| m.id.starts_with("msg_test_"))
        .map(|m| serde_json::from_slice(&m.raw).unwrap())
        .collect();
    assert_eq!(tests.len(), 1);
    assert_eq!(tests[0][0]["labels"]["alertname"], "cliffwatch_test");
    assert!(tests[0][0]["labels"].get("site").is_none());
    assert_eq!(
        am.bad_signatures.load(std::sync::atomic::Ordering::SeqCst),
        0
    );
    let (s, _) = d
        .send(Method::POST, "/api/v1/webhooks/nope/test", None)
        .await;
    assert_eq!(s, 404);
}
