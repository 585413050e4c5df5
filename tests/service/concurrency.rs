//! 20 clients upload to different sites while 50 read histories: no "database is locked", no 5xx.

use crate::service_support;

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Arc;

use serde_json::json;
use service_support::{paper, TestServer, PAPER};

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
