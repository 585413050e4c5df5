//! Issue 77: a retired site's watched folder is refused as its HTTP upload is: it goes to
//! `.failed/` with an `error.txt` saying since when and why the site is retired, and nothing is
//! stored.

use crate::support;

use cliffwatch::watch::{scan_once, WatchOptions};
use serde_json::json;
use support::server::TestServer;
use support::watch::{small_scene, write_epoch};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_retired_sites_folder_fails_saying_why() {
    let server = TestServer::start(|_| {}).await;
    server.create_site("closed").await;
    let (st, b) = server
        .post(
            "/api/v1/sites/closed/retire",
            &json!({"reason": "the road below was closed for good"}),
        )
        .await;
    assert_eq!(st, 200, "{b}");
    let watch = tempfile::tempdir().unwrap();
    let site_dir = watch.path().join("closed");
    write_epoch(
        &site_dir,
        &small_scene(),
        "e1",
        "2026-11-20T09:00:00Z",
        true,
        1,
    );
    let before = server.snapshot().await;
    let taken = scan_once(
        &server.store,
        &WatchOptions::new(watch.path().to_path_buf()),
    )
    .await;
    assert_eq!(taken.len(), 1);
    let err = std::fs::read_to_string(site_dir.join(".failed/e1/error.txt"))
        .unwrap_or_else(|e| panic!("no error.txt in .failed ({e})"));
    assert!(err.contains("site 'closed' was retired on"), "{err}");
    assert!(err.contains("the road below was closed for good"), "{err}");
    assert_eq!(server.snapshot().await, before, "nothing stored");
    server.stop().await;
}
