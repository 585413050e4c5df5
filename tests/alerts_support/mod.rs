//! Helpers of the alerting tests: a monitoring series in the upload form with known truth, the
//! daemon binary on an ephemeral port (killable with SIGKILL), and a loopback webhook receiver that
//! verifies every Standard Webhooks signature and can answer 503 for a while.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use serde_json::{json, Value};

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

    fn base(&self, i: usize) -> [f64; 3] {
        let side = (self.n as f64).sqrt().ceil() as usize;
        let (r, c) = (i / side, i % side);
        let x = -10.0 + 20.0 * c as f64 / (side - 1).max(1) as f64;
        let z = 20.0 * r as f64 / (side - 1).max(1) as f64;
        let y = 100.0 + 2.0 * ((i * 7919) % 13) as f64 / 13.0;
        [x, y, z]
    }

    /// True displacement (mm, site frame) of target `i` when the block has moved `block_mm`.
    pub fn truth_mm(&self, i: usize, block_mm: f64) -> [f64; 3] {
        if i < self.stable {
            [0.0; 3]
        } else {
            [0.0, -block_mm, 0.0]
        }
    }

    /// One epoch in the upload form, the block moved `block_mm` from the reference.
    pub fn epoch(&self, observed_at: &str, seed: u64, block_mm: f64) -> Value {
        let mut state = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let mut noise = move |scale: f64| {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 2.0 * scale
        };
        let xyz: Vec<[f64; 3]> = (0..self.n)
            .map(|i| {
                let b = self.base(i);
                let d = self.truth_mm(i, block_mm);
                [
                    b[0] + d[0] / 1000.0,
                    b[1] + d[1] / 1000.0,
                    b[2] + d[2] / 1000.0,
                ]
            })
            .collect();
        let c_mm = 300.0;
        let target = [0.0, 100.0, 10.0];
        let images = 4;
        let mut imgs = Vec::new();
        for k in 0..images {
            let t = k as f64 / (images - 1) as f64;
            let xo = [-25.0 + 50.0 * t, 0.0, 5.0 + 4.0 * (k % 2) as f64];
            let f = normalize([target[0] - xo[0], target[1] - xo[1], target[2] - xo[2]]);
            let r1 = normalize(cross(f, [0.0, 0.0, 1.0]));
            let r2 = cross(r1, f);
            let r3 = [-f[0], -f[1], -f[2]];
            let obs: Vec<Value> = xyz
                .iter()
                .enumerate()
                .map(|(i, p)| {
                    let d = [p[0] - xo[0], p[1] - xo[1], p[2] - xo[2]];
                    let u = [dot(r1, d), dot(r2, d), dot(r3, d)];
                    let x = -c_mm * u[0] / u[2] + noise(0.001);
                    let y = -c_mm * u[1] / u[2] + noise(0.001);
                    json!({"point": Scene::name(i), "x_mm": x, "y_mm": y})
                })
                .collect();
            imgs.push(json!({"id": format!("S{}", k + 1), "camera": "cam",
                             "station": format!("S{}", k + 1), "observations": obs}));
        }
        let approx: Vec<Value> = xyz
            .iter()
            .enumerate()
            .map(|(i, p)| {
                json!({"point": Scene::name(i), "X": p[0] + noise(0.01),
                                 "Y": p[1] + noise(0.01), "Z": p[2] + noise(0.01)})
            })
            .collect();
        json!({"observed_at": observed_at,
               "cameras": [{"id": "cam", "c_mm": c_mm, "calibrate_c": true}],
               "images": imgs, "approx": approx})
    }
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
fn normalize(a: [f64; 3]) -> [f64; 3] {
    let n = dot(a, a).sqrt();
    [a[0] / n, a[1] / n, a[2] / n]
}

/// `observed_at` of epoch `k`: one a day from 2026-11-01.
pub fn day(k: usize) -> String {
    let t = chrono::DateTime::parse_from_rfc3339("2026-11-01T09:00:00Z").unwrap()
        + chrono::Duration::days(k as i64);
    t.with_timezone(&chrono::Utc)
        .to_rfc3339_opts(chrono::SecondsFormat::Secs, true)
}

/// The daemon binary serving a data directory on an ephemeral loopback port.
pub struct Daemon {
    child: Child,
    /// `http://127.0.0.1:PORT`.
    pub base: String,
    /// HTTP client.
    pub client: reqwest::Client,
}

fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

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

impl Daemon {
    /// Starts `cliffwatch serve` on `data_dir` with `config`; waits for `/readyz`.
    pub async fn start(data_dir: &Path, config: &Path) -> Daemon {
        let port = free_port();
        let child = Command::new(env!("CARGO_BIN_EXE_cliffwatch"))
            .args(["serve", "--listen"])
            .arg(format!("127.0.0.1:{port}"))
            .arg("--data-dir")
            .arg(data_dir)
            .arg("--config")
            .arg(config)
            .env("RUST_LOG", "warn")
            .stdout(Stdio::null())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("start the daemon");
        let d = Daemon {
            child,
            base: format!("http://127.0.0.1:{port}"),
            client: reqwest::Client::new(),
        };
        for _ in 0..400 {
            if let Ok(r) = d.client.get(d.url("/readyz")).send().await {
                if r.status().is_success() {
                    return d;
                }
            }
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
        panic!("the daemon did not become ready");
    }

    /// `url` of a path.
    pub fn url(&self, path: &str) -> String {
        format!("{}{}", self.base, path)
    }

    /// SIGKILL, no shutdown of any kind.
    pub fn kill9(mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }

    /// JSON request; returns status and body.
    pub async fn send(
        &self,
        method: reqwest::Method,
        path: &str,
        body: Option<&Value>,
    ) -> (u16, Value) {
        let mut rq = self.client.request(method, self.url(path));
        if let Some(b) = body {
            rq = rq.json(b);
        }
        let r = rq.send().await.unwrap();
        let s = r.status().as_u16();
        (s, r.json().await.unwrap_or(Value::Null))
    }

    /// GET JSON.
    pub async fn get(&self, path: &str) -> (u16, Value) {
        self.send(reqwest::Method::GET, path, None).await
    }
}

impl Drop for Daemon {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// One message the receiver accepted (answered 2xx) or refused.
#[derive(Debug, Clone)]
pub struct Received {
    /// `webhook-id`.
    pub id: String,
    /// The body as JSON.
    pub body: Value,
    /// Whether it was answered 200.
    pub accepted: bool,
}

/// A loopback webhook receiver: verifies every signature (counting failures), answers 503 to the
/// first `fail_first` requests, 200 afterwards.
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
}

impl Receiver {
    /// Starts the receiver on an ephemeral port.
    pub async fn start(fail_first: usize) -> Receiver {
        use axum::http::{HeaderMap, StatusCode};
        let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
        let addr = listener.local_addr().unwrap();
        let rx = Receiver {
            url: format!("http://{addr}/hook"),
            log: Arc::default(),
            bad_signatures: Arc::default(),
            fail_remaining: Arc::new(AtomicUsize::new(fail_first)),
            gone: Arc::default(),
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
                        SECRET,
                        &id,
                        ts,
                        &body,
                        &h("webhook-signature"),
                    );
                    if !ok {
                        st.bad_signatures.fetch_add(1, Ordering::SeqCst);
                        return StatusCode::UNAUTHORIZED;
                    }
                    if st.gone.load(Ordering::SeqCst) {
                        st.log.lock().unwrap().push(Received {
                            id,
                            body: Value::Null,
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

/// `enabled` of every webhook endpoint in a data directory's database (read-only).
pub async fn endpoints_enabled(data_dir: &Path) -> Vec<bool> {
    use sqlx::ConnectOptions;
    let mut conn = sqlx::sqlite::SqliteConnectOptions::new()
        .filename(data_dir.join("cliffwatch.db"))
        .read_only(true)
        .connect()
        .await
        .unwrap();
    sqlx::query_scalar("SELECT enabled FROM webhooks ORDER BY id")
        .fetch_all(&mut conn)
        .await
        .unwrap()
}

/// Every outbox id and its event type in a data directory's database (read-only).
pub async fn outbox_ids(data_dir: &Path) -> Vec<(String, String)> {
    use sqlx::ConnectOptions;
    let mut conn = sqlx::sqlite::SqliteConnectOptions::new()
        .filename(data_dir.join("cliffwatch.db"))
        .read_only(true)
        .connect()
        .await
        .unwrap();
    sqlx::query_as("SELECT id, event_type FROM webhook_outbox ORDER BY id")
        .fetch_all(&mut conn)
        .await
        .unwrap()
}
