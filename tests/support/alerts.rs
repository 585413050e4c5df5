//! Helpers of the alerting tests: a monitoring series in the upload form with known truth (the
//! synthetic epoch of `support::server`), the daemon binary on an ephemeral port (killable with
//! SIGKILL; `support::server::Daemon`), a configuration with fast retries, and a loopback webhook
//! receiver that verifies every Standard Webhooks signature and can answer 503 for a while.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

use reqwest::Method;
use serde_json::{json, Value};

pub use crate::support::server::Daemon;

/// Creates site `id` (orthogonal model) with the given alert rules through the API.
pub async fn create_site(d: &Daemon, id: &str, rules: Value) {
    let (s, b) = d
        .send(
            Method::POST,
            "/api/v1/sites",
            Some(&json!({"id": id, "model": "orthogonal", "alert_rules": rules})),
        )
        .await;
    assert_eq!(s, 201, "{b}");
}

/// Uploads an epoch to site `site` and asserts that it was created (201); returns the summary.
pub async fn upload_new(d: &Daemon, site: &str, body: &Value) -> Value {
    let (s, b) = d
        .send(
            Method::POST,
            &format!("/api/v1/sites/{site}/epochs"),
            Some(body),
        )
        .await;
    assert_eq!(s, 201, "{b}");
    b
}

/// Marks the scene's fixed points (index < `stable`) of site `site` as stable points.
pub async fn mark_stable(d: &Daemon, site: &str, scene: &Scene) {
    for i in 0..scene.stable {
        let (s, b) = d
            .send(
                Method::PUT,
                &format!("/api/v1/sites/{site}/points/{}", Scene::name(i)),
                Some(&json!({"role": "stable"})),
            )
            .await;
        assert_eq!(s, 200, "{b}");
    }
}

/// Site `site` with a watch rule above 5 mm of displacement, the scene's fixed points marked
/// stable, and two epochs (seeds `seed`, `seed + 1`) between which the scene's block moves 10 mm:
/// one watch alert per moving point.
pub async fn watch_block_moving(d: &Daemon, site: &str, scene: &Scene, seed: u64) {
    create_site(
        d,
        site,
        json!([{"level": "watch", "metric": "displacement_mm", "above": 5.0}]),
    )
    .await;
    mark_stable(d, site, scene).await;
    for k in 0..2 {
        let body = scene.epoch(&day(k), seed + k as u64, 10.0 * k as f64);
        upload_new(d, site, &body).await;
    }
}

/// Webhook secret of the tests (`whsec_` + base64 of 24 bytes).
pub const SECRET: &str = "whsec_MfKQ9r8GKYqrTwjUPD8ILPZIo2LaLaSw";

/// A monitoring scene: `n` targets T001… on a 20 m × 20 m face 100 m in front of 4 stations
/// (c = 300 mm, image noise uniform ±1 µm). Points with index < `stable` are fixed; the others form a
/// block moving along −Y (towards the cameras).
#[derive(Debug, Clone)]
pub struct Scene {
    /// Number of targets.
    pub n: usize,
    /// Targets T001…T{stable} never move.
    pub stable: usize,
}

impl Scene {
    /// Name of target `i` (0-based).
    pub fn name(i: usize) -> String {
        format!("T{:03}", i + 1)
    }

    /// True displacement (mm, site frame) of target `i` when the block has moved `block_mm`.
    pub fn truth_mm(&self, i: usize, block_mm: f64) -> [f64; 3] {
        if i < self.stable {
            [0.0; 3]
        } else {
            [0.0, -block_mm, 0.0]
        }
    }

    /// One epoch in the upload form, the block moved `block_mm` from the reference
    /// ([`super::server::synthetic_epoch`] with 4 stations).
    pub fn epoch(&self, observed_at: &str, seed: u64, block_mm: f64) -> Value {
        super::server::synthetic_epoch(4, self.n, observed_at, seed, block_mm, self.stable)
    }
}

/// `observed_at` of epoch `k`: one a day from 2026-11-01.
pub use super::day;

/// A configuration file with fast webhook retries (poll 50 ms, backoff from 0.2 s, at most 1 s).
pub fn write_config(dir: &Path, extra: &str) -> PathBuf {
    let path = dir.join("cliffwatch.toml");
    std::fs::write(
        &path,
        format!(
            "webhook_poll_ms = 50\nwebhook_timeout_secs = 5\n{extra}\n\
             [webhook_retry]\nbase_seconds = 0.2\nmax_delay_seconds = 1.0\nmax_attempts = 50\n"
        ),
    )
    .unwrap();
    path
}

/// [`write_config`] with one webhook to `url`, signed with [`SECRET`], from the watch level up.
pub fn write_webhook_config(dir: &Path, url: &str) -> PathBuf {
    write_config(
        dir,
        &format!("[[webhooks]]\nurl = \"{url}\"\nsecret = \"{SECRET}\"\nmin_level = \"watch\"\n"),
    )
}

/// One message the receiver accepted (answered 2xx) or refused.
#[derive(Debug, Clone)]
pub struct Received {
    /// `webhook-id`.
    pub id: String,
    /// The body as JSON.
    pub body: Value,
    /// The body as received (the bytes that were signed).
    pub raw: Vec<u8>,
    /// Whether it was answered 200.
    pub accepted: bool,
}

/// A loopback webhook receiver: verifies every signature (counting failures) with its secret,
/// answers 503 to the first `fail_first` requests, 200 afterwards.
#[derive(Clone)]
pub struct Receiver {
    /// `http://127.0.0.1:PORT/hook`.
    pub url: String,
    /// Everything received, in order.
    pub log: Arc<Mutex<Vec<Received>>>,
    /// Requests whose signature did not verify.
    pub bad_signatures: Arc<AtomicUsize>,
    /// Requests still to refuse with 503.
    pub fail_remaining: Arc<AtomicUsize>,
    /// When set, every request is answered 410 Gone.
    pub gone: Arc<std::sync::atomic::AtomicBool>,
    /// When set, every request is answered only after a minute (longer than any POST timeout
    /// of the tests).
    pub hang: Arc<std::sync::atomic::AtomicBool>,
    /// The secret signatures are verified with.
    pub secret: String,
}

impl Receiver {
    /// Starts the receiver on an ephemeral port, verifying with [`SECRET`].
    pub async fn start(fail_first: usize) -> Receiver {
        Self::start_with_secret(fail_first, SECRET).await
    }

    /// Starts the receiver on an ephemeral port, verifying with `secret`.
    pub async fn start_with_secret(fail_first: usize, secret: &str) -> Receiver {
        use axum::http::{HeaderMap, StatusCode};
        let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
        let addr = listener.local_addr().unwrap();
        let rx = Receiver {
            url: format!("http://{addr}/hook"),
            log: Arc::default(),
            bad_signatures: Arc::default(),
            fail_remaining: Arc::new(AtomicUsize::new(fail_first)),
            gone: Arc::default(),
            hang: Arc::default(),
            secret: secret.to_string(),
        };
        let state = rx.clone();
        let app = axum::Router::new().route(
            "/hook",
            axum::routing::post(move |headers: HeaderMap, body: axum::body::Bytes| {
                let st = state.clone();
                async move {
                    let h = |k: &str| {
                        headers
                            .get(k)
                            .and_then(|v| v.to_str().ok())
                            .unwrap_or("")
                            .to_string()
                    };
                    let id = h("webhook-id");
                    let ts: i64 = h("webhook-timestamp").parse().unwrap_or(0);
                    let ok = cliffwatch::webhooks::verify(
                        &st.secret,
                        &id,
                        ts,
                        &body,
                        &h("webhook-signature"),
                    );
                    if !ok {
                        st.bad_signatures.fetch_add(1, Ordering::SeqCst);
                        return StatusCode::UNAUTHORIZED;
                    }
                    if st.hang.load(Ordering::SeqCst) {
                        tokio::time::sleep(std::time::Duration::from_secs(60)).await;
                        return StatusCode::OK;
                    }
                    if st.gone.load(Ordering::SeqCst) {
                        st.log.lock().unwrap().push(Received {
                            id,
                            body: Value::Null,
                            raw: body.to_vec(),
                            accepted: false,
                        });
                        return StatusCode::GONE;
                    }
                    let refuse = st
                        .fail_remaining
                        .fetch_update(Ordering::SeqCst, Ordering::SeqCst, |n| n.checked_sub(1))
                        .is_ok();
                    st.log.lock().unwrap().push(Received {
                        id,
                        body: serde_json::from_slice(&body).unwrap_or(Value::Null),
                        raw: body.to_vec(),
                        accepted: !refuse,
                    });
                    if refuse {
                        StatusCode::SERVICE_UNAVAILABLE
                    } else {
                        StatusCode::OK
                    }
                }
            }),
        );
        tokio::spawn(async move {
            let _ = axum::serve(listener, app).await;
        });
        rx
    }

    /// Distinct `webhook-id`s answered 200, with the body of each.
    pub fn accepted(&self) -> std::collections::BTreeMap<String, Value> {
        self.log
            .lock()
            .unwrap()
            .iter()
            .filter(|r| r.accepted)
            .map(|r| (r.id.clone(), r.body.clone()))
            .collect()
    }
}

/// A read-only connection to a data directory's database.
async fn read_only_database(data_dir: &Path) -> sqlx::SqliteConnection {
    use sqlx::ConnectOptions;
    sqlx::sqlite::SqliteConnectOptions::new()
        .filename(data_dir.join("cliffwatch.db"))
        .read_only(true)
        .connect()
        .await
        .unwrap()
}

/// `enabled` of every webhook endpoint in a data directory's database (read-only).
pub async fn endpoints_enabled(data_dir: &Path) -> Vec<bool> {
    let mut conn = read_only_database(data_dir).await;
    sqlx::query_scalar("SELECT enabled FROM webhooks ORDER BY id")
        .fetch_all(&mut conn)
        .await
        .unwrap()
}

/// Every outbox id and its event type in a data directory's database (read-only).
pub async fn outbox_ids(data_dir: &Path) -> Vec<(String, String)> {
    let mut conn = read_only_database(data_dir).await;
    sqlx::query_as("SELECT id, event_type FROM webhook_outbox ORDER BY id")
        .fetch_all(&mut conn)
        .await
        .unwrap()
}

/// Every outbox message of a data directory's database (read-only): `(alert_id, payload)`, the
/// payload parsed from the stored contract body.
pub async fn outbox_payloads(data_dir: &Path) -> Vec<(String, Value)> {
    let mut conn = read_only_database(data_dir).await;
    let rows: Vec<(String, String)> =
        sqlx::query_as("SELECT alert_id, payload FROM webhook_outbox ORDER BY id")
            .fetch_all(&mut conn)
            .await
            .unwrap();
    rows.into_iter()
        .map(|(a, p)| (a, serde_json::from_str(&p).expect("a JSON payload")))
        .collect()
}

/// Every outbox event of a data directory's database (read-only): `(id, event_type, alert_id)`.
pub async fn outbox_events(data_dir: &Path) -> Vec<(String, String, String)> {
    let mut conn = read_only_database(data_dir).await;
    sqlx::query_as("SELECT id, event_type, alert_id FROM webhook_outbox ORDER BY id")
        .fetch_all(&mut conn)
        .await
        .unwrap()
}
