//! The watcher inside the running server: a server started with `watch_dir` takes a folder that
//! appears with `READY` on its own (file-system events, rescan as fallback), the epoch shows in the
//! API and the folder moves to `.done/`. The epoch's page shows each station's image with the
//! detected targets drawn over it and named as the truth names them; the preview is a JPEG of the
//! image made on request; an image that has left the watched directory is reported, not served.

use crate::support;

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

use support::server::TestServer;
use support::watch::write_epoch;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn running_server_takes_a_ready_folder() {
    let watch = tempfile::tempdir().unwrap();
    let site = watch.path().join("kamo");
    std::fs::create_dir_all(&site).unwrap();
    let dir = watch.path().to_path_buf();
    let server = TestServer::start(move |c| c.watch_dir = Some(dir)).await;
    server.create_site("kamo").await;
    let epoch = support::watch::small_scene();
    // written while the server runs; READY last
    let (_, truth) = write_epoch(&site, &epoch, "e1", "2026-11-20T09:00:00Z", true, 1);

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
    images_of_the_epoch(&server, &truth, &done).await;
    server.stop().await;
}

/// The report keeps every detection with its name, the epoch page draws them over the images, the
/// previews are served, and a missing image is said to be missing.
async fn images_of_the_epoch(
    server: &TestServer,
    truth: &BTreeMap<String, BTreeMap<String, [f64; 2]>>,
    done: &std::path::Path,
) {
    let (_, list) = server.get("/api/v1/sites/kamo/epochs").await;
    let id = list["items"][0]["id"].as_i64().expect("epoch id");
    let (status, epoch) = server.get(&format!("/api/v1/sites/kamo/epochs/{id}")).await;
    assert_eq!(status, 200, "{epoch}");
    let stations = epoch["identification"].as_array().unwrap().clone();
    assert_eq!(stations.len(), truth.len());
    let mut named = 0;
    for st in &stations {
        let station = st["station"].as_str().unwrap();
        // the scene's image ids are its stations
        let image_truth = &truth[station];
        assert_eq!(st["folder"], ".done/e1", "{st}");
        assert_eq!(st["image"], format!("{station}.png"), "{st}");
        let targets = st["targets"].as_array().unwrap();
        assert_eq!(targets.len() as u64, st["detected"].as_u64().unwrap());
        for t in targets {
            let Some(point) = t["point"].as_str() else {
                continue;
            };
            assert_eq!(t["status"], "identified");
            let [col, row] = image_truth[point];
            let err = (t["col"].as_f64().unwrap() - col).hypot(t["row"].as_f64().unwrap() - row);
            assert!(err < 0.3, "{station} {point}: {err:.3} px from the truth");
            named += 1;
        }
        assert_eq!(
            targets.iter().filter(|t| t["point"].is_string()).count() as u64,
            st["identified"].as_u64().unwrap()
        );
    }
    assert!(named >= 5 * 26, "{named} targets named");

    let page = |path: String| async move {
        let r = server.client.get(server.url(&path)).send().await.unwrap();
        (r.status().as_u16(), r.text().await.unwrap())
    };
    let (status, html) = page(format!("/sites/kamo/epochs/{id}")).await;
    assert_eq!(status, 200, "{html}");
    assert_eq!(
        html.matches("class=\"station-image\"").count(),
        stations.len()
    );
    assert_eq!(
        html.matches(" font-size=").count(),
        named,
        "one label per named target"
    );
    assert_eq!(
        html.matches("class=\"target ").count() as u64,
        stations
            .iter()
            .map(|s| s["detected"].as_u64().unwrap())
            .sum::<u64>()
    );

    let station = stations[0]["station"].as_str().unwrap();
    let url = format!("/sites/kamo/epochs/{id}/images/{station}");
    assert!(html.contains(&format!("src=\"{url}\"")), "{html}");
    let r = server.client.get(server.url(&url)).send().await.unwrap();
    assert_eq!(r.status(), 200);
    assert_eq!(r.headers()["content-type"], "image/jpeg");
    let jpeg = r.bytes().await.unwrap();
    let preview = image::load_from_memory(&jpeg).unwrap().to_luma8();
    assert_eq!(preview.dimensions(), (1080, 720), "not enlarged, not cut");
    // the preview is the station's picture: brighter at its identified targets than around them
    let mut at = vec![];
    let mut off = vec![];
    for t in stations[0]["targets"].as_array().unwrap() {
        let (c, r) = (t["col"].as_f64().unwrap(), t["row"].as_f64().unwrap());
        at.push(preview.get_pixel(c.round() as u32, r.round() as u32).0[0] as f64);
        off.push(
            preview
                .get_pixel((c + 12.0).min(1079.0) as u32, r.round() as u32)
                .0[0] as f64,
        );
    }
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    assert!(
        mean(&at) > mean(&off) + 40.0,
        "targets {} vs beside {}",
        mean(&at),
        mean(&off)
    );

    let (status, _) = page(format!("/sites/kamo/epochs/{id}/images/nowhere")).await;
    assert_eq!(status, 404);
    // the image gone from the watched directory: said so, not served
    std::fs::remove_file(done.join(format!("{station}.png"))).unwrap();
    let (status, _) = page(url).await;
    assert_eq!(status, 404);
    let (_, html) = page(format!("/sites/kamo/epochs/{id}")).await;
    assert_eq!(
        html.matches("no longer in the watched directory").count(),
        1
    );
}
