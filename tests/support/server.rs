//! Shared helpers of the service tests and the benchmark: paper data, a synthetic epoch, an
//! in-process server on an ephemeral port with a temporary data directory, table snapshots.
#![allow(dead_code)]

use std::path::PathBuf;

use cliffwatch::config::Config;
use cliffwatch::daemon::bind;
use cliffwatch::store::Store;
use serde_json::{json, Value};

/// `../shared/data` of the repository.
pub fn data_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data")
}

/// Names of the paper epochs, in observation order.
pub const PAPER: [&str; 9] = [
    "paper-case1-seed101",
    "paper-case1-seed102",
    "paper-case1-seed103",
    "paper-case2-seed101",
    "paper-case2-seed102",
    "paper-case2-seed103",
    "paper-case3-seed101",
    "paper-case3-seed102",
    "paper-case3-seed103",
];

/// One paper epoch (upload form) as JSON.
pub fn paper(name: &str) -> Value {
    let path = data_dir().join(format!("{name}.epoch.json"));
    serde_json::from_str(&std::fs::read_to_string(&path).expect("paper epoch")).expect("JSON")
}

/// A synthetic epoch: `images` stations 100 m in front of a 20 m × 20 m cliff with `points`
/// targets, c = 300 mm (calibrated), image noise ≈ 1 µm, approximations ± 10 mm. Points with an
/// index ≥ `moving_from` are shifted by `shift_mm` along −Y (towards the cameras).
pub fn synthetic_epoch(
    images: usize,
    points: usize,
    observed_at: &str,
    seed: u64,
    shift_mm: f64,
    moving_from: usize,
) -> Value {
    synthetic_epoch_moved(
        images,
        points,
        observed_at,
        seed,
        [0.0, -shift_mm, 0.0],
        moving_from,
    )
}

/// As [`synthetic_epoch`], with the points from `moving_from` on shifted by `shift_mm`
/// (X, Y, Z in mm): across the line of sight (X, Z) an epoch's σ is ≈ 0.25 mm, in depth
/// (Y) ≈ 1.5 mm.
pub fn synthetic_epoch_moved(
    images: usize,
    points: usize,
    observed_at: &str,
    seed: u64,
    shift_mm: [f64; 3],
    moving_from: usize,
) -> Value {
    let mut state = seed
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    let mut noise = move |scale: f64| {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 2.0 * scale
    };
    let side = (points as f64).sqrt().ceil() as usize;
    let xyz: Vec<[f64; 3]> = (0..points)
        .map(|i| {
            let (r, c) = (i / side, i % side);
            let x = -10.0 + 20.0 * c as f64 / (side - 1).max(1) as f64;
            let z = 20.0 * r as f64 / (side - 1).max(1) as f64;
            let y = 100.0 + 2.0 * ((i * 7919) % 13) as f64 / 13.0;
            let m = if i >= moving_from { 1e-3 } else { 0.0 };
            [
                x + m * shift_mm[0],
                y + m * shift_mm[1],
                z + m * shift_mm[2],
            ]
        })
        .collect();
    let c_mm = 300.0;
    let target = [0.0, 100.0, 10.0];
    let mut imgs = Vec::new();
    for k in 0..images {
        let t = if images > 1 {
            k as f64 / (images - 1) as f64
        } else {
            0.5
        };
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
                json!({"point": format!("T{:03}", i + 1), "x_mm": x, "y_mm": y})
            })
            .collect();
        imgs.push(json!({"id": format!("S{}", k + 1), "camera": "cam", "station": format!("S{}", k + 1), "observations": obs}));
    }
    let approx: Vec<Value> = xyz
        .iter()
        .enumerate()
        .map(|(i, p)| json!({"point": format!("T{:03}", i + 1), "X": p[0] + noise(0.01), "Y": p[1] + noise(0.01), "Z": p[2] + noise(0.01)}))
        .collect();
    json!({"observed_at": observed_at,
           "cameras": [{"id": "cam", "c_mm": c_mm, "calibrate_c": true}],
           "images": imgs, "approx": approx})
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

/// A server running in this process on an ephemeral loopback port with a temporary data dir.
pub struct TestServer {
    /// `http://127.0.0.1:PORT`.
    pub base: String,
    /// Its database (for snapshots).
    pub store: Store,
    /// HTTP client.
    pub client: reqwest::Client,
    stop: Option<tokio::sync::oneshot::Sender<()>>,
    task: Option<tokio::task::JoinHandle<()>>,
    /// Keeps the data directory alive.
    pub dir: tempfile::TempDir,
    /// The server's upload slots (a test may hold them to fill the node).
    pub uploads: cliffwatch::service::admission::UploadGate,
}

impl TestServer {
    /// Starts a server with the default configuration, changed by `adjust_config`.
    pub async fn start(adjust_config: impl FnOnce(&mut Config)) -> TestServer {
        let dir = tempfile::tempdir().expect("tempdir");
        let mut config = Config::with_data_dir(dir.path());
        config.listen = "127.0.0.1:0".into();
        adjust_config(&mut config);
        let bound = bind(config).await.expect("bind");
        let base = format!("http://{}", bound.local_addr());
        let store = bound.state().store.clone();
        let uploads = bound.state().uploads.clone();
        let (tx, rx) = tokio::sync::oneshot::channel::<()>();
        let task = tokio::spawn(async move {
            bound
                .run(async {
                    let _ = rx.await;
                })
                .await
                .expect("serve");
        });
        TestServer {
            base,
            store,
            client: reqwest::Client::new(),
            stop: Some(tx),
            task: Some(task),
            dir,
            uploads,
        }
    }

    /// Stops the server, waits for it, and hands back its data directory.
    pub async fn stop(mut self) -> tempfile::TempDir {
        if let Some(tx) = self.stop.take() {
            let _ = tx.send(());
        }
        if let Some(task) = self.task.take() {
            let _ = task.await;
        }
        self.dir
    }

    /// `url` for a path.
    pub fn url(&self, path: &str) -> String {
        format!("{}{}", self.base, path)
    }

    /// Creates a site (201 expected).
    pub async fn create_site(&self, id: &str) {
        let r = self
            .client
            .post(self.url("/api/v1/sites"))
            .json(&json!({"id": id, "name": id, "model": "orthogonal"}))
            .send()
            .await
            .unwrap();
        assert_eq!(r.status(), 201, "create site {id}");
    }

    /// POSTs an epoch; returns status and JSON answer.
    pub async fn upload(&self, site: &str, body: &Value) -> (u16, Value) {
        self.post(&format!("/api/v1/sites/{site}/epochs"), body)
            .await
    }

    /// POSTs an epoch already serialized (`body`, JSON) to `site` and reads the whole answer, as
    /// the benchmarks time it: the status and the answer's length in bytes.
    pub async fn upload_bytes(&self, site: &str, body: Vec<u8>) -> (u16, usize) {
        let r = self
            .client
            .post(self.url(&format!("/api/v1/sites/{site}/epochs")))
            .header("content-type", "application/json")
            .body(body)
            .send()
            .await
            .expect("sent");
        let status = r.status().as_u16();
        (status, r.bytes().await.expect("answer").len())
    }

    /// GETs JSON (each key once per object, [`json_answer`]).
    pub async fn get(&self, path: &str) -> (u16, Value) {
        let r = self.client.get(self.url(path)).send().await.unwrap();
        json_answer(r, &format!("GET {path}")).await
    }

    /// POSTs JSON; returns the status and the JSON answer (each key once per object).
    pub async fn post(&self, path: &str, body: &Value) -> (u16, Value) {
        let r = self
            .client
            .post(self.url(path))
            .json(body)
            .send()
            .await
            .unwrap();
        json_answer(r, &format!("POST {path}")).await
    }

    /// Sends a JSON request with any method; returns the status and the JSON answer (each key
    /// once per object).
    pub async fn send(
        &self,
        method: reqwest::Method,
        path: &str,
        body: Option<&Value>,
    ) -> (u16, Value) {
        let what = format!("{method} {path}");
        let mut rq = self.client.request(method, self.url(path));
        if let Some(b) = body {
            rq = rq.json(b);
        }
        json_answer(rq.send().await.unwrap(), &what).await
    }

    /// Free text with the NUL character, which PostgreSQL cannot store and SQLite would: refused
    /// with 422 naming the field on either backend, and nothing created.
    pub async fn assert_nul_text_refused(&self) {
        let area = serde_json::json!({"description": "below\u{0}the cliff",
            "circle": {"latitude": 35.0, "longitude": 135.0, "radius_km": 1.0}});
        for (body, field) in [
            (serde_json::json!({"id": "nul", "name": "a\u{0}b"}), "name"),
            (
                serde_json::json!({"id": "nul", "area": area}),
                "area.description",
            ),
        ] {
            let (st, answer) = self.post("/api/v1/sites", &body).await;
            assert_eq!(st, 422, "{answer}");
            assert!(answer.to_string().contains(field), "{answer}");
        }
        let (st, answer) = self.get("/api/v1/sites/nul").await;
        assert_eq!(st, 404, "the refused site was not created: {answer}");
        for body in [
            serde_json::json!({"by": "duty\u{0}officer"}),
            serde_json::json!({"by": "duty officer", "comment": "seen\u{0}"}),
        ] {
            let (st, answer) = self.post("/api/v1/alerts/x:T1:r:1/ack", &body).await;
            assert_eq!(st, 422, "{body}: {answer}");
            assert!(answer.to_string().contains("U+0000"), "{answer}");
        }
    }

    /// Row counts of every table: what "the database holds".
    pub async fn snapshot(&self) -> Vec<(String, i64)> {
        snapshot(&self.store).await
    }
}

/// The status and JSON body of an answer (`Null` when the body is not JSON), failing the test
/// when an object of it holds a key twice ([`super::unique_keys`]): every answer the helpers
/// read is checked.
pub async fn json_answer(r: reqwest::Response, what: &str) -> (u16, Value) {
    let status = r.status().as_u16();
    let text = r.text().await.unwrap_or_default();
    (status, super::unique_keys::answer_json(&text, what))
}

/// The JSON body of an answer read straight from the client, failing the test when it is not
/// JSON or an object of it holds a key twice.
pub async fn checked_json(r: reqwest::Response) -> Value {
    let url = r.url().path().to_string();
    let text = r.text().await.expect("an answer body");
    super::unique_keys::parse_unique_keys(&text)
        .unwrap_or_else(|e| panic!("{url}: malformed JSON answer: {e}\n{text}"))
}

/// Row counts of every table of a store.
pub async fn snapshot(store: &Store) -> Vec<(String, i64)> {
    let mut out = Vec::new();
    for t in [
        "sites",
        "cameras",
        "stations",
        "points",
        "epochs",
        "images",
        "observations",
        "coordinates",
        "joint_covariances",
        "displacements",
        "series_blocks",
        "series_seals",
        "alerts",
        "webhooks",
        "webhook_outbox",
        "webhook_deliveries",
    ] {
        let n: i64 = sqlx::query_scalar(&format!("SELECT COUNT(*) FROM {t}"))
            .fetch_one(store.reader())
            .await
            .unwrap();
        out.push((t.to_string(), n));
    }
    out
}

/// The daemon binary (`cliffwatch serve`) serving a data directory on an ephemeral loopback port:
/// a separate process, so tests can SIGKILL it and start another on the same data.
pub struct Daemon {
    child: std::process::Child,
    /// `http://127.0.0.1:PORT`.
    pub base: String,
    /// HTTP client.
    pub client: reqwest::Client,
}

pub use super::free_port;

impl Daemon {
    /// Starts `cliffwatch serve` on `data_dir` with `config`; waits for `/readyz`.
    pub async fn start(data_dir: &std::path::Path, config: &std::path::Path) -> Daemon {
        Self::start_with_env(data_dir, config, &[]).await
    }

    /// [`Daemon::start`] with extra environment variables for the process.
    pub async fn start_with_env(
        data_dir: &std::path::Path,
        config: &std::path::Path,
        env: &[(&str, &str)],
    ) -> Daemon {
        Self::start_on(free_port(), data_dir, config, env).await
    }

    /// [`Daemon::start_with_env`] on a given loopback port (known before the start, e.g. for a
    /// `public_url` in `config`).
    pub async fn start_on(
        port: u16,
        data_dir: &std::path::Path,
        config: &std::path::Path,
        env: &[(&str, &str)],
    ) -> Daemon {
        // Absent only in examples, which include this module but start no daemon.
        let Some(binary) = option_env!("CARGO_BIN_EXE_cliffwatch") else {
            panic!("Daemon::start needs the cliffwatch binary (tests and benchmarks only)");
        };
        let child = std::process::Command::new(binary)
            .args(["serve", "--listen"])
            .arg(format!("127.0.0.1:{port}"))
            .arg("--data-dir")
            .arg(data_dir)
            .arg("--config")
            .arg(config)
            .env("RUST_LOG", "warn")
            .envs(env.iter().copied())
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::inherit())
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
            tokio::time::sleep(std::time::Duration::from_millis(50)).await;
        }
        panic!("the daemon did not become ready");
    }

    /// `url` of a path.
    pub fn url(&self, path: &str) -> String {
        format!("{}{}", self.base, path)
    }

    /// The process id.
    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    /// Sends SIGTERM and waits up to `within` for the process to exit; returns how long it took,
    /// or `None` if it was still running then (it is killed on drop).
    pub fn terminate(&mut self, within: std::time::Duration) -> Option<std::time::Duration> {
        let started = std::time::Instant::now();
        let sent = std::process::Command::new("kill")
            .args(["-TERM", &self.child.id().to_string()])
            .status()
            .expect("run kill");
        assert!(sent.success(), "kill -TERM");
        while started.elapsed() < within {
            if let Ok(Some(_)) = self.child.try_wait() {
                return Some(started.elapsed());
            }
            std::thread::sleep(std::time::Duration::from_millis(20));
        }
        None
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
        let what = format!("{method} {path}");
        let mut rq = self.client.request(method, self.url(path));
        if let Some(b) = body {
            rq = rq.json(b);
        }
        json_answer(rq.send().await.unwrap(), &what).await
    }

    /// GET JSON.
    pub async fn get(&self, path: &str) -> (u16, Value) {
        self.send(reqwest::Method::GET, path, None).await
    }

    /// GET a page: the status and the body as text.
    pub async fn get_text(&self, path: &str) -> (u16, String) {
        let r = self.client.get(self.url(path)).send().await.unwrap();
        let status = r.status().as_u16();
        (status, r.text().await.unwrap_or_default())
    }
}

impl Drop for Daemon {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}
