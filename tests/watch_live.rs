//! The watcher inside the running server: a server started with `watch_dir` takes a folder that
//! appears with `READY` on its own (file-system events, rescan as fallback), the epoch shows in the
//! API and the folder moves to `.done/`.

mod service_support;
mod watch_support;

use std::time::{Duration, Instant};

use cliffwatch::simulate::scenes::{long_range, LongRangeParams};
use service_support::TestServer;
use watch_support::write_epoch;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn running_server_takes_a_ready_folder() {
    let watch = tempfile::tempdir().unwrap();
    let site = watch.path().join("kamo");
    std::fs::create_dir_all(&site).unwrap();
    let dir = watch.path().to_path_buf();
    let server = TestServer::start(move |c| c.watch_dir = Some(dir)).await;
    server.create_site("kamo").await;
    let (epoch, _) = long_range(&LongRangeParams {
        width_px: 1080,
        height_px: 720,
        pixel_size_mm: 0.021,
        noise_px: 0.0,
        approx_sigma_m: 0.01,
        ..LongRangeParams::default()
    })
    .unwrap();
    // written while the server runs; READY last
    write_epoch(&site, &epoch, "e1", "2026-11-20T09:00:00Z", true, 1);

    let start = Instant::now();
    let limit = Duration::from_secs(180);
    let done = site.join(".done").join("e1");
    loop {
        let (status, body) = server.get("/api/v1/sites/kamo/epochs").await;
        assert_eq!(status, 200, "{body}");
        let epochs = body.to_string().matches("observed_at").count();
        if epochs == 1 && done.is_dir() {
            break;
        }
        let failed = site.join(".failed").join("e1").join("error.txt");
        assert!(
            !failed.exists(),
            "{}",
            std::fs::read_to_string(&failed).unwrap_or_default()
        );
        assert!(
            start.elapsed() < limit,
            "no epoch after {limit:?}: {body}; folder still at {:?}",
            site.join("e1").is_dir()
        );
        tokio::time::sleep(Duration::from_millis(250)).await;
    }
    eprintln!("epoch from the watched folder after {:?}", start.elapsed());
    assert!(
        !site.join("e1").exists(),
        "the folder left the site's top level"
    );
    server.stop().await;
}
