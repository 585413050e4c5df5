//! SQLite's WAL is checkpointed by the daemon, not inside an upload's commit
//! (`store::wal_checkpoint`).

use crate::support::server::{synthetic_epoch, TestServer};

/// Uploads land in the WAL; the daemon's checkpointer (every second) then copies them into the
/// database file without being asked, and a checkpoint with no reader in the way copies every
/// page.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_daemon_checkpoints_the_wal_into_the_database_file() {
    let s = TestServer::start(|_| {}).await;
    s.create_site("wal").await;
    let db = s.dir.path().join("cliffwatch.db");
    let size = || std::fs::metadata(&db).expect("database file").len();
    // Let the checkpoint of the site's creation pass, then write more than it held.
    tokio::time::sleep(std::time::Duration::from_millis(1500)).await;
    let before = size();
    for k in 0..3 {
        let t = format!("2026-01-0{}T00:00:00Z", k + 1);
        let (st, body) = s
            .upload("wal", &synthetic_epoch(4, 12, &t, k as u64, 0.0, 12))
            .await;
        assert_eq!(st, 201, "{body}");
    }
    let mut grown = false;
    for _ in 0..50 {
        if size() > before {
            grown = true;
            break;
        }
        tokio::time::sleep(std::time::Duration::from_millis(100)).await;
    }
    assert!(
        grown,
        "the database file stayed at {before} bytes for 5 s after 3 uploads"
    );
    let c = s
        .store
        .checkpoint_wal()
        .await
        .expect("checkpoint")
        .expect("SQLite");
    assert!(c.wal_pages > 0, "{c:?}");
    assert_eq!(c.copied_pages, c.wal_pages, "{c:?}");
    s.stop().await;
}
