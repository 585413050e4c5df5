//! 20 clients upload to different sites while 50 read histories: no "database is locked", no 5xx.
//! A node whose upload slots are full turns uploads away with 503 and `Retry-After`, storing
//! nothing, and every upload retried after it is stored once.

use crate::support;

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Arc;

use serde_json::json;
use support::server::{paper, TestServer, PAPER};

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn uploads_and_reads_in_parallel() {
    const UPLOADERS: usize = 20;
    const READERS: usize = 50;
    const EPOCHS: usize = 3;
    let s = Arc::new(TestServer::start(|c| c.read_connections = 8).await);
    for i in 0..UPLOADERS {
        let site = format!("site{i}");
        s.create_site(&site).await;
        assert_eq!(s.upload(&site, &paper(PAPER[6])).await.0, 201);
    }
    let stop = Arc::new(AtomicBool::new(false));
    let reads = Arc::new(AtomicUsize::new(0));
    let mut readers = Vec::new();
    for r in 0..READERS {
        let (s, stop, reads) = (s.clone(), stop.clone(), reads.clone());
        readers.push(tokio::spawn(async move {
            let mut k = r;
            while !stop.load(Ordering::SeqCst) {
                let site = format!("site{}", k % UPLOADERS);
                let path = match k % 3 {
                    0 => format!("/api/v1/sites/{site}/points/5/displacements"),
                    1 => format!("/api/v1/sites/{site}/epochs"),
                    _ => format!("/api/v1/sites/{site}/points"),
                };
                let r = s.client.get(s.url(&path)).send().await.unwrap();
                let status = r.status().as_u16();
                let body = r.text().await.unwrap();
                assert_eq!(status, 200, "{path}: {body}");
                reads.fetch_add(1, Ordering::SeqCst);
                k += 1;
            }
        }));
    }
    let mut uploaders = Vec::new();
    for i in 0..UPLOADERS {
        let s = s.clone();
        uploaders.push(tokio::spawn(async move {
            for e in 0..EPOCHS {
                let mut body = paper(PAPER[7 + e % 2]);
                body["observed_at"] = json!(format!("2001-0{}-01T00:00:00Z", e + 1));
                let (status, answer) = s.upload(&format!("site{i}"), &body).await;
                assert_eq!(status, 201, "site{i} epoch {e}: {answer}");
            }
        }));
    }
    for u in uploaders {
        u.await.unwrap();
    }
    stop.store(true, Ordering::SeqCst);
    for r in readers {
        r.await.unwrap();
    }
    assert!(reads.load(Ordering::SeqCst) >= READERS);
    for i in 0..UPLOADERS {
        let (_, list) = s.get(&format!("/api/v1/sites/site{i}/epochs")).await;
        assert_eq!(list["items"].as_array().unwrap().len(), 1 + EPOCHS);
    }
}

/// With the node's one upload slot held, an upload waits `upload_queue_secs` and is answered 503
/// with `Retry-After` and code `overloaded`, and nothing is stored; once the slot is free the same
/// body is stored. Then a burst of uploads to 12 sites through that one slot, held until each has
/// been turned away once: every answer is 201 or such a 503, and each upload retried after its
/// `Retry-After` ends stored, once.
#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn a_full_node_turns_uploads_away_and_they_are_stored_when_retried() {
    const SITES: usize = 12;
    let s = Arc::new(
        TestServer::start(|c| {
            c.max_concurrent_uploads = 1;
            c.upload_queue_secs = 0.2;
        })
        .await,
    );
    assert_eq!(s.uploads.size(), 1);
    s.create_site("busy").await;
    let held = s.uploads.enter().await.expect("the free slot");
    let started = std::time::Instant::now();
    let r = s
        .client
        .post(s.url("/api/v1/sites/busy/epochs"))
        .json(&paper(PAPER[6]))
        .send()
        .await
        .unwrap();
    assert!(started.elapsed() >= std::time::Duration::from_millis(200));
    assert_eq!(r.status(), 503);
    assert_eq!(r.headers()["retry-after"], "1");
    let answer: serde_json::Value = crate::support::server::checked_json(r).await;
    assert_eq!(answer["error"]["code"], "overloaded", "{answer}");
    assert_eq!(answer["error"]["details"]["retry_after_secs"], 1);
    let (_, list) = s.get("/api/v1/sites/busy/epochs").await;
    assert_eq!(list["items"].as_array().unwrap().len(), 0, "nothing stored");
    drop(held);
    assert_eq!(s.upload("busy", &paper(PAPER[6])).await.0, 201);

    for i in 0..SITES {
        s.create_site(&format!("burst{i}")).await;
    }
    let turned_away = Arc::new(AtomicUsize::new(0));
    let refused_first = Arc::new(AtomicUsize::new(0));
    let held = s.uploads.enter().await.expect("the free slot");
    let mut uploaders = Vec::new();
    for i in 0..SITES {
        let (s, turned_away, refused_first) =
            (s.clone(), turned_away.clone(), refused_first.clone());
        uploaders.push(tokio::spawn(async move {
            let path = format!("/api/v1/sites/burst{i}/epochs");
            for attempt in 0..50 {
                let r = s
                    .client
                    .post(s.url(&path))
                    .json(&paper(PAPER[6 + i % 3]))
                    .send()
                    .await
                    .unwrap();
                match r.status().as_u16() {
                    201 => return,
                    503 => {
                        let wait: u64 = r.headers()["retry-after"]
                            .to_str()
                            .unwrap()
                            .parse()
                            .unwrap();
                        assert!((1..=60).contains(&wait));
                        turned_away.fetch_add(1, Ordering::SeqCst);
                        if attempt == 0 {
                            refused_first.fetch_add(1, Ordering::SeqCst);
                        }
                        // Retry-After is in seconds; a test waits a tenth of it.
                        tokio::time::sleep(std::time::Duration::from_millis(100 * wait)).await;
                    }
                    other => panic!("burst{i}: {other} {}", r.text().await.unwrap()),
                }
            }
            panic!("burst{i}: never stored");
        }));
    }
    // Every uploader is turned away while the slot is held; then they share it.
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(60);
    while refused_first.load(Ordering::SeqCst) < SITES {
        assert!(
            std::time::Instant::now() < deadline,
            "uploads not turned away"
        );
        tokio::time::sleep(std::time::Duration::from_millis(20)).await;
    }
    drop(held);
    for u in uploaders {
        u.await.unwrap();
    }
    for i in 0..SITES {
        let (_, list) = s.get(&format!("/api/v1/sites/burst{i}/epochs")).await;
        assert_eq!(list["items"].as_array().unwrap().len(), 1, "burst{i}");
    }
    println!(
        "{} of the burst's attempts were turned away",
        turned_away.load(Ordering::SeqCst)
    );
}
