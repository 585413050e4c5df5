//! cliffwatch against a real Alertmanager (Debian's `prometheus-alertmanager`, started here on
//! a loopback port with its own configuration and storage): every open alert is re-posted each
//! period (1 s here), so the alarms are back within one period after Alertmanager restarts; a
//! resolution leaves Alertmanager within one period; an escalation keeps the lower level firing
//! (muted by the documented inhibit rule), so Alertmanager's own webhook notifications show no
//! resolution when things got worse; `generatorURL` opens the page of the alert's incident and the
//! fingerprint is Alertmanager's. Under `CI=true` a missing Alertmanager fails the test.

use crate::support;

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use reqwest::Method;
use serde_json::{json, Value};
use support::alerts::{create_site, day, mark_stable, upload_new, write_config, Daemon, Scene};
use support::server::free_port;

const SITE: &str = "cliff";
/// The re-post period of the test (`alertmanager_resend_secs`).
const PERIOD: Duration = Duration::from_secs(1);
/// What "within one period" allows besides the period: the loop's poll, the POST, and
/// Alertmanager's own processing, measured well under this.
const SLACK: Duration = Duration::from_millis(1500);

/// The Alertmanager binary, or `None` (with the reason printed) outside CI when it is missing.
fn alertmanager_binary() -> Option<PathBuf> {
    let path = PathBuf::from("/usr/bin/prometheus-alertmanager");
    if path.exists() {
        return Some(path);
    }
    if std::env::var("CI").is_ok_and(|v| v == "true") {
        panic!(
            "CI=true: {} missing (Debian's prometheus-alertmanager; .ci/run installs it)",
            path.display()
        );
    }
    eprintln!(
        "skipped: {} missing (install Debian's prometheus-alertmanager)",
        path.display()
    );
    None
}

/// The inhibit rules the README documents: a higher level of one subject and rule mutes the lower.
const INHIBIT: &str = "inhibit_rules:
  - source_matchers: ['severity=\"alarm\"']
    target_matchers: ['severity=~\"watch|warning\"']
    equal: [alertname, site, point, group, rule]
  - source_matchers: ['severity=\"warning\"']
    target_matchers: ['severity=\"watch\"']
    equal: [alertname, site, point, group, rule]
";

/// A running Alertmanager; killed on drop.
struct Alertmanager {
    binary: PathBuf,
    dir: PathBuf,
    port: u16,
    child: Option<std::process::Child>,
}

impl Alertmanager {
    /// Starts Alertmanager in `dir` on a free port, its webhook receiver pointing at `tap`.
    async fn start(binary: PathBuf, dir: &Path, tap: &str) -> Alertmanager {
        std::fs::write(
            dir.join("alertmanager.yml"),
            format!(
                "route:\n  receiver: tap\n  group_by: [alertname, site]\n  group_wait: 200ms\n  \
                 group_interval: 1s\n  repeat_interval: 1h\nreceivers:\n  - name: tap\n    \
                 webhook_configs:\n      - url: {tap}\n        send_resolved: true\n{INHIBIT}"
            ),
        )
        .unwrap();
        let mut am = Alertmanager {
            binary,
            dir: dir.to_path_buf(),
            port: free_port(),
            child: None,
        };
        am.spawn().await;
        am
    }

    async fn spawn(&mut self) {
        let child = std::process::Command::new(&self.binary)
            .arg(format!(
                "--config.file={}",
                self.dir.join("alertmanager.yml").display()
            ))
            .arg(format!(
                "--storage.path={}",
                self.dir.join("data").display()
            ))
            .arg(format!("--web.listen-address=127.0.0.1:{}", self.port))
            .arg("--cluster.listen-address=")
            .arg("--log.level=warn")
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::inherit())
            .spawn()
            .expect("start Alertmanager");
        self.child = Some(child);
        let ready = format!("http://127.0.0.1:{}/-/ready", self.port);
        for _ in 0..200 {
            if let Ok(r) = reqwest::get(&ready).await {
                if r.status().is_success() {
                    return;
                }
            }
            tokio::time::sleep(Duration::from_millis(25)).await;
        }
        panic!("Alertmanager did not become ready");
    }

    fn stop(&mut self) {
        if let Some(mut c) = self.child.take() {
            let _ = c.kill();
            let _ = c.wait();
        }
    }

    fn alerts_url(&self) -> String {
        format!("http://127.0.0.1:{}/api/v2/alerts", self.port)
    }

    /// The alerts Alertmanager holds as active or muted (not resolved).
    async fn alerts(&self) -> Vec<Value> {
        match reqwest::get(self.alerts_url()).await {
            Ok(r) => r.json::<Vec<Value>>().await.unwrap_or_default(),
            Err(_) => vec![],
        }
    }

    /// Waits until `ok` holds of the alerts; returns them and how long it took.
    async fn wait_for(
        &self,
        what: &str,
        within: Duration,
        ok: impl Fn(&[Value]) -> bool,
    ) -> (Vec<Value>, Duration) {
        let start = Instant::now();
        loop {
            let got = self.alerts().await;
            if ok(&got) {
                return (got, start.elapsed());
            }
            assert!(
                start.elapsed() < within,
                "{what}: not within {within:?}; Alertmanager holds {got:#?}"
            );
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
    }
}

impl Drop for Alertmanager {
    fn drop(&mut self) {
        self.stop();
    }
}

/// Alertmanager's webhook notifications, as received.
#[derive(Clone, Default)]
struct Tap {
    bodies: Arc<Mutex<Vec<Value>>>,
}

impl Tap {
    async fn start() -> (Tap, String) {
        let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
        let url = format!("http://{}/am", listener.local_addr().unwrap());
        let tap = Tap::default();
        let bodies = tap.bodies.clone();
        let app = axum::Router::new().route(
            "/am",
            axum::routing::post(move |axum::Json(v): axum::Json<Value>| {
                let bodies = bodies.clone();
                async move {
                    bodies.lock().unwrap().push(v);
                    "ok"
                }
            }),
        );
        tokio::spawn(async move {
            let _ = axum::serve(listener, app).await;
        });
        (tap, url)
    }

    /// `(status, severity, point)` of every alert of every notification so far.
    fn notified(&self) -> Vec<(String, String, String)> {
        let mut out = vec![];
        for b in self.bodies.lock().unwrap().iter() {
            for a in b["alerts"].as_array().into_iter().flatten() {
                out.push((
                    a["status"].as_str().unwrap_or("").to_string(),
                    a["labels"]["severity"].as_str().unwrap_or("").to_string(),
                    a["labels"]["point"].as_str().unwrap_or("").to_string(),
                ));
            }
        }
        out
    }

    async fn wait_for(&self, what: &str, ok: impl Fn(&[(String, String, String)]) -> bool) {
        let start = Instant::now();
        loop {
            let n = self.notified();
            if ok(&n) {
                return;
            }
            assert!(
                start.elapsed() < Duration::from_secs(15),
                "{what}: Alertmanager notified {n:?}"
            );
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
    }
}

fn severities(alerts: &[Value], state: &str) -> BTreeSet<(String, String)> {
    alerts
        .iter()
        .filter(|a| a["status"]["state"] == state)
        .map(|a| {
            (
                a["labels"]["point"].as_str().unwrap_or("").to_string(),
                a["labels"]["severity"].as_str().unwrap_or("").to_string(),
            )
        })
        .collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn alertmanager_holds_every_open_alert_across_restarts_and_escalations() {
    let Some(binary) = alertmanager_binary() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let (tap, tap_url) = Tap::start().await;
    let am_dir = dir.path().join("am");
    std::fs::create_dir(&am_dir).unwrap();
    let mut am = Alertmanager::start(binary, &am_dir, &tap_url).await;

    let port = free_port();
    let public_url = format!("http://127.0.0.1:{port}");
    let config = write_config(
        dir.path(),
        &format!(
            "alertmanager_resend_secs = {}\npublic_url = \"{public_url}\"\n\
             [[webhooks]]\nurl = \"{}\"\nsecret = \"{}\"\nmin_level = \"watch\"\n\
             format = \"alertmanager_api_v2\"\n",
            PERIOD.as_secs_f64(),
            am.alerts_url(),
            support::alerts::SECRET
        ),
    );
    let data = dir.path().join("data");
    let daemon = Daemon::start_on(port, &data, &config, &[]).await;

    // A block of 8 points moving 10 mm (watch above 5 mm), then 20 mm (warning above 15 mm).
    let scene = Scene { n: 16, stable: 8 };
    let block: BTreeSet<String> = (scene.stable..scene.n).map(Scene::name).collect();
    create_site(
        &daemon,
        SITE,
        json!([{"level": "watch", "metric": "displacement_mm", "above": 5.0},
               {"level": "warning", "metric": "displacement_mm", "above": 15.0}]),
    )
    .await;
    mark_stable(&daemon, SITE, &scene).await;
    for k in 0..2 {
        let body = scene.epoch(&day(k), 900 + k as u64, 10.0 * k as f64);
        upload_new(&daemon, SITE, &body).await;
    }
    let watch: BTreeSet<(String, String)> = block
        .iter()
        .map(|p| (p.clone(), "watch".to_string()))
        .collect();
    let (held, took) = am
        .wait_for("8 watch alerts", PERIOD + SLACK, |a| {
            severities(a, "active") == watch
        })
        .await;
    eprintln!("8 watch alerts in Alertmanager {took:?} after the upload's answer");

    // Each alert: Alertmanager's fingerprint of its labels, and a generatorURL that opens the
    // page of its incident (the point's: no block is declared), which lists the alert.
    for a in &held {
        let labels: std::collections::BTreeMap<String, String> =
            serde_json::from_value(a["labels"].clone()).unwrap();
        assert_eq!(
            a["fingerprint"],
            cliffwatch::webhooks::fingerprint(&labels),
            "{a}"
        );
        let id = a["annotations"]["alert_id"].as_str().unwrap();
        let point = a["labels"]["point"].as_str().unwrap();
        assert_eq!(
            a["annotations"]["incident"],
            format!("point:{point}"),
            "{a}"
        );
        let page = a["generatorURL"].as_str().unwrap();
        assert_eq!(page, format!("{public_url}/sites/{SITE}/points/{point}"));
        let r = daemon.client.get(page).send().await.unwrap();
        assert_eq!(r.status(), 200, "{page}");
        let html = r.text().await.unwrap();
        let encoded: String = id
            .bytes()
            .map(|b| match b {
                b'A'..=b'Z' | b'a'..=b'z' | b'0'..=b'9' | b'-' | b'.' | b'_' | b'~' => {
                    (b as char).to_string()
                }
                _ => format!("%{b:02X}"),
            })
            .collect();
        let listed_on_page = format!("/alerts/{encoded}\"");
        assert!(
            html.contains(&format!("data-subject=\"point:{point}\""))
                && html.contains(&listed_on_page),
            "{page} lists its incident and the alert {id}: {html}"
        );
        let (s, listed) = daemon
            .get(&format!("/api/v1/alerts?site={SITE}&state=open"))
            .await;
        assert_eq!(s, 200);
        assert!(
            listed["items"]
                .as_array()
                .unwrap()
                .iter()
                .any(|x| x["id"] == id),
            "{id}"
        );
    }
    tap.wait_for("watch notifications", |n| {
        n.iter()
            .filter(|(s, sev, _)| s == "firing" && sev == "watch")
            .count()
            >= 8
    })
    .await;

    // Escalation: 20 mm. Watch stays firing (inhibited), warning fires; Alertmanager never
    // notifies a resolution.
    let body = scene.epoch(&day(2), 902, 20.0);
    let escalating = upload_new(&daemon, SITE, &body).await;
    let warning: BTreeSet<(String, String)> = block
        .iter()
        .map(|p| (p.clone(), "warning".to_string()))
        .collect();
    let (_, took) = am
        .wait_for("8 warning alerts, watch muted", PERIOD + SLACK, |a| {
            severities(a, "active") == warning && severities(a, "suppressed") == watch
        })
        .await;
    eprintln!("escalation in Alertmanager {took:?} after the upload's answer");
    tap.wait_for("warning notifications", |n| {
        n.iter()
            .filter(|(s, sev, _)| s == "firing" && sev == "warning")
            .count()
            >= 8
    })
    .await;
    // Several group intervals: a resolution of the watch alerts would have been sent by now.
    tokio::time::sleep(Duration::from_secs(3)).await;
    let resolved: Vec<_> = tap
        .notified()
        .into_iter()
        .filter(|(s, _, _)| s == "resolved")
        .collect();
    assert!(
        resolved.is_empty(),
        "escalation notified as a resolution: {resolved:?}"
    );

    // Alertmanager restarts (alerts are in its memory only): every open alert is back within
    // one period.
    am.stop();
    am.spawn().await;
    let restarted = Instant::now();
    let (_, took) = am
        .wait_for("alerts back after the restart", PERIOD + SLACK, |a| {
            severities(a, "active") == warning && severities(a, "suppressed") == watch
        })
        .await;
    eprintln!("16 alerts back {took:?} after Alertmanager was ready again (period {PERIOD:?})");
    assert!(restarted.elapsed() <= PERIOD + SLACK);

    // Resolution: the reference moves to the last epoch; Alertmanager holds none within one
    // period, and its receiver is told (so the tap would have seen a resolution above).
    let (s, b) = daemon
        .send(
            Method::PUT,
            &format!("/api/v1/sites/{SITE}/reference"),
            Some(&json!({"epoch": escalating["id"]})),
        )
        .await;
    assert_eq!(s, 200, "{b}");
    assert_eq!(b["reference_epoch"], escalating["id"], "{b}");
    let (_, took) = am
        .wait_for("every alert inactive", PERIOD + SLACK, |a| a.is_empty())
        .await;
    eprintln!("resolution in Alertmanager {took:?} after the reference moved");
    tap.wait_for("resolved notifications", |n| {
        n.iter()
            .filter(|(s, sev, _)| s == "resolved" && sev == "warning")
            .count()
            >= 8
    })
    .await;
    // Resolved alerts stay resolved while cliffwatch keeps posting them (one hold = 4 periods).
    tokio::time::sleep(PERIOD * 2).await;
    assert!(am.alerts().await.is_empty());
}

/// `(alert id, level)` of the open velocity and time-to-failure alerts of `site`.
async fn open_rate_alerts(d: &Daemon, site: &str) -> BTreeSet<(String, String)> {
    let (s, a) = d
        .get(&format!("/api/v1/alerts?site={site}&limit=1000"))
        .await;
    assert_eq!(s, 200, "{a}");
    a["items"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|a| {
            a["state"] != "resolved"
                && (a["rule"] == "velocity_mm_per_day" || a["rule"] == "time_to_failure_hours")
        })
        .map(|a| {
            (
                a["id"].as_str().unwrap().to_string(),
                a["level"].as_str().unwrap().to_string(),
            )
        })
        .collect()
}

/// The `alert_id`s Alertmanager holds active.
fn active_ids(alerts: &[Value]) -> BTreeSet<String> {
    alerts
        .iter()
        .filter(|a| a["status"]["state"] == "active")
        .filter_map(|a| a["annotations"]["alert_id"].as_str().map(str::to_string))
        .collect()
}

/// Velocity and time to failure do not depend on the reference epoch. The monitoring series of
/// `cliffwatch simulate` (seed 1: 40 epochs 12 h apart, a declared 5-target block accelerating
/// to failure 12 h after the last) with the README's rules: moving the reference to epochs 21,
/// 31 and 39 keeps every velocity and time-to-failure alert open at its level in cliffwatch
/// (before the fix the move to epoch 39 resolved T119's alarm) and firing in Alertmanager, with
/// no resolution notified.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn moving_the_reference_keeps_velocity_and_time_to_failure_alarms_firing() {
    let Some(binary) = alertmanager_binary() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let (tap, tap_url) = Tap::start().await;
    let am_dir = dir.path().join("am");
    std::fs::create_dir(&am_dir).unwrap();
    let am = Alertmanager::start(binary, &am_dir, &tap_url).await;
    let config = write_config(
        dir.path(),
        &format!(
            "alertmanager_resend_secs = {}\n\
             [[webhooks]]\nurl = \"{}\"\nsecret = \"{}\"\nmin_level = \"watch\"\n\
             format = \"alertmanager_api_v2\"\n",
            PERIOD.as_secs_f64(),
            am.alerts_url(),
            support::alerts::SECRET
        ),
    );
    let d = Daemon::start(&dir.path().join("data"), &config).await;
    let series =
        cliffwatch_sim::series::image_series(&cliffwatch_sim::series::ImageSeriesScenario {
            seed: 1,
            epochs: 40,
            ..Default::default()
        })
        .expect("the monitoring series");
    let (s, b) = d
        .send(
            Method::POST,
            "/api/v1/sites",
            Some(
                &json!({"id": SITE, "frame": {"up": [0, 1, 0]}, "alert_rules": [
                {"level": "watch",   "metric": "displacement_mm", "above": 5, "clear_below": 4},
                {"level": "warning", "metric": "velocity_mm_per_day", "above": 1},
                {"level": "alarm",   "metric": "time_to_failure_hours", "below": 96}]}),
            ),
        )
        .await;
    assert_eq!(s, 201, "{b}");
    let mut ids = vec![];
    for (k, e) in series.epochs.iter().enumerate() {
        let body = serde_json::to_value(e).unwrap();
        ids.push(upload_new(&d, SITE, &body).await["id"].clone());
        if k > 0 {
            continue;
        }
        for p in series.truth.points.iter().filter(|p| p.role == "stable") {
            let (s, b) = d
                .send(
                    Method::PUT,
                    &format!("/api/v1/sites/{SITE}/points/{}", p.name),
                    Some(&json!({"role": "stable"})),
                )
                .await;
            assert_eq!(s, 200, "{b}");
        }
        let block: Vec<&str> = series
            .truth
            .points
            .iter()
            .filter(|p| p.group.is_some())
            .map(|p| p.name.as_str())
            .collect();
        let (s, b) = d
            .send(
                Method::PUT,
                &format!("/api/v1/sites/{SITE}/groups/B1"),
                Some(&json!({"kind": "block", "points": block,
                             "direction": series.truth.direction})),
            )
            .await;
        assert_eq!(s, 200, "{b}");
    }
    let before = open_rate_alerts(&d, SITE).await;
    let levels: BTreeSet<&str> = before.iter().map(|(_, l)| l.as_str()).collect();
    assert!(
        levels.contains("alarm") && levels.contains("warning"),
        "the accelerating block has its velocity warning and time-to-failure alarm: {before:?}"
    );
    let before_ids: BTreeSet<String> = before.iter().map(|(id, _)| id.clone()).collect();
    // One incident for the block holds every one of them, with the block's own forecast.
    let (s, b) = d.get(&format!("/api/v1/sites/{SITE}/incidents")).await;
    assert_eq!(s, 200, "{b}");
    let listed = b["items"].as_array().unwrap().clone();
    let first = &listed[0];
    assert_eq!(
        first["id"], "block:B1",
        "the most urgent incident: {listed:#?}"
    );
    assert_eq!(first["level"], "alarm", "{first}");
    let held: BTreeSet<String> = first["alert_ids"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap().to_string())
        .collect();
    assert!(before_ids.is_subset(&held), "{before_ids:?} ⊄ {held:?}");
    let forecast = &first["forecast"];
    assert_eq!(forecast["from"], "block B1", "{first}");
    let likely = forecast["likely_before"].as_str().unwrap();
    let truth = series.truth.failure_at.expect("the series fails");
    let likely = chrono::DateTime::parse_from_rfc3339(likely).unwrap();
    let last = series.truth.epochs.last().unwrap().observed_at;
    assert!(
        likely > last && likely < truth + chrono::Duration::hours(96),
        "failure likely before {likely}, last epoch {last}, true failure {truth}"
    );
    am.wait_for("every rate alert firing", PERIOD + SLACK * 4, |a| {
        before_ids.is_subset(&active_ids(a))
    })
    .await;
    // What the receiver was told while the series came in (the data resolved some alerts on the
    // way), once Alertmanager has sent it.
    tokio::time::sleep(PERIOD * 3).await;
    let resolutions = |tap: &Tap| -> Vec<(String, String, String)> {
        tap.notified()
            .into_iter()
            .filter(|(s, sev, _)| s == "resolved" && (sev == "alarm" || sev == "warning"))
            .collect()
    };
    let resolved_before = resolutions(&tap).len();

    for k in [20, 30, 38] {
        let (s, b) = d
            .send(
                Method::PUT,
                &format!("/api/v1/sites/{SITE}/reference"),
                Some(&json!({"epoch": ids[k]})),
            )
            .await;
        assert_eq!(s, 200, "{b}");
        let after = open_rate_alerts(&d, SITE).await;
        assert!(
            before.is_subset(&after),
            "reference at epoch {}: {before:?} → {after:?}",
            ids[k]
        );
    }
    // Several re-post periods and group intervals: a resolution would have reached Alertmanager
    // and its receiver by now.
    tokio::time::sleep(PERIOD * 3).await;
    let held = am.alerts().await;
    assert!(
        before_ids.is_subset(&active_ids(&held)),
        "{before_ids:?} not all active in {held:#?}"
    );
    let resolved = resolutions(&tap);
    assert_eq!(
        resolved.len(),
        resolved_before,
        "resolutions after the moves: {:?}",
        &resolved[resolved_before..]
    );
}
