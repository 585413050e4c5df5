//! A server killed with SIGKILL in the middle of uploads restarts cleanly: every epoch is either
//! fully there or absent, and re-uploading the absent ones works. Uses the real binary.

use crate::support;

use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use serde_json::{json, Value};
use support::server::{paper, PAPER};

use crate::support::free_port;

struct Binary {
    child: Child,
    base: String,
}

async fn start(dir: &std::path::Path) -> Binary {
    let port = free_port();
    let mut child = Command::new(env!("CARGO_BIN_EXE_cliffwatch"))
        .args([
            "serve",
            "--listen",
            &format!("127.0.0.1:{port}"),
            "--data-dir",
        ])
        .arg(dir)
        .env("RUST_LOG", "warn")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("start cliffwatch");
    let base = format!("http://127.0.0.1:{port}");
    let client = reqwest::Client::new();
    let t0 = Instant::now();
    let mut healthy = false;
    while !healthy && t0.elapsed() < Duration::from_secs(30) {
        healthy = matches!(client.get(format!("{base}/healthz")).send().await, Ok(r) if r.status() == 200);
        if !healthy {
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
    }
    if !healthy {
        let _ = child.kill();
        let _ = child.wait();
        panic!("server did not become healthy");
    }
    Binary { child, base }
}

fn epoch(k: usize) -> Value {
    let mut e = paper(PAPER[6 + k % 3]);
    e["observed_at"] = json!(format!("2001-01-01T{:02}:{:02}:00Z", k / 60, k % 60));
    e
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn sigkill_during_uploads_leaves_whole_epochs() {
    const N: usize = 60;
    let dir = tempfile::tempdir().unwrap();
    let mut server = start(dir.path()).await;
    let client = reqwest::Client::new();
    let r = client
        .post(format!("{}/api/v1/sites", server.base))
        .json(&json!({"id": "crash"}))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 201);

    let url = format!("{}/api/v1/sites/crash/epochs", server.base);
    let done = std::sync::Arc::new(std::sync::atomic::AtomicUsize::new(0));
    let mut tasks = Vec::new();
    for w in 0..6 {
        let (client, url, done) = (client.clone(), url.clone(), done.clone());
        tasks.push(tokio::spawn(async move {
            for k in (w..N).step_by(6) {
                match client.post(&url).json(&epoch(k)).send().await {
                    Ok(r) if r.status() == 201 => {
                        done.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
                    }
                    Ok(r) => panic!("upload {k} -> {}", r.status()),
                    Err(_) => return, // the server is gone
                }
            }
        }));
    }
    let t0 = Instant::now();
    while done.load(std::sync::atomic::Ordering::SeqCst) < N / 3
        && t0.elapsed() < Duration::from_secs(120)
    {
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
    server.child.kill().expect("SIGKILL");
    server.child.wait().unwrap();
    for t in tasks {
        t.await.unwrap();
    }
    let acknowledged = done.load(std::sync::atomic::Ordering::SeqCst);
    assert!(
        acknowledged < N,
        "the kill came after every upload: nothing tested"
    );

    let mut server = start(dir.path()).await;
    let (status, list): (u16, Value) = {
        let r = client
            .get(format!(
                "{}/api/v1/sites/crash/epochs?limit=1000",
                server.base
            ))
            .send()
            .await
            .unwrap();
        (
            r.status().as_u16(),
            crate::support::server::checked_json(r).await,
        )
    };
    assert_eq!(status, 200);
    let stored = list["items"].as_array().unwrap().clone();
    assert!(
        stored.len() >= acknowledged,
        "every acknowledged upload survives"
    );
    for e in &stored {
        let id = e["id"].as_i64().unwrap();
        let full: Value = client
            .get(format!("{}/api/v1/sites/crash/epochs/{id}", server.base))
            .send()
            .await
            .unwrap()
            .json()
            .await
            .unwrap();
        assert_eq!(
            full["points"].as_array().unwrap().len(),
            12,
            "epoch {id} complete"
        );
        let observations: usize = full["images"]
            .as_array()
            .unwrap()
            .iter()
            .map(|i| i["observations"].as_u64().unwrap() as usize)
            .sum::<usize>()
            + full["dropped"].as_array().unwrap().len();
        assert_eq!(
            full["residuals"].as_array().unwrap().len(),
            observations,
            "epoch {id} observations"
        );
        assert_eq!(
            full["displacements"].as_array().unwrap().len(),
            12,
            "epoch {id} displacements"
        );
    }
    let url = format!("{}/api/v1/sites/crash/epochs", server.base);
    let mut created = 0;
    for k in 0..N {
        let r = client.post(&url).json(&epoch(k)).send().await.unwrap();
        let status = r.status().as_u16();
        assert!(status == 200 || status == 201, "re-upload {k} -> {status}");
        created += usize::from(status == 201);
    }
    assert_eq!(created, N - stored.len());
    let list: Value = client
        .get(format!(
            "{}/api/v1/sites/crash/epochs?limit=1000",
            server.base
        ))
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    assert_eq!(list["items"].as_array().unwrap().len(), N);
    let _ = Command::new("kill")
        .arg("-TERM")
        .arg(server.child.id().to_string())
        .status();
    let status = server.child.wait().unwrap();
    assert!(status.success(), "SIGTERM exits with 0: {status:?}");
}
