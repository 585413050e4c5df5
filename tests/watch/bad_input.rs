//! Bad image files through the watched directory: a folder whose station image is a truncated
//! JPEG, a 1-pixel image, a PNG claiming 10¹⁰ pixels or a file above the size limit goes to
//! `.failed/` with an `error.txt` naming the file and why, and nothing is stored for its epoch; the
//! same station image as a big-endian planar 16-bit RGB TIFF is measured and stored.

use crate::support;
use crate::support::bad_images;

use std::path::{Path, PathBuf};

use cliffwatch::watch::{scan_once, WatchOptions};
use cliffwatch_core::detect::{decode, GreyImage};
use support::server::TestServer;
use support::watch::{small_scene, write_epoch};

/// The first station image (`.png`) of `folder`.
fn first_png(folder: &Path) -> PathBuf {
    let mut pngs: Vec<PathBuf> = std::fs::read_dir(folder)
        .unwrap()
        .flatten()
        .map(|f| f.path())
        .filter(|p| p.extension().is_some_and(|e| e == "png"))
        .collect();
    pngs.sort();
    pngs.remove(0)
}

/// Rows of `table` of `site`.
async fn count(server: &TestServer, table: &str, site: &str) -> i64 {
    sqlx::query_scalar(&format!("SELECT COUNT(*) FROM {table} WHERE site_id = ?"))
        .bind(site)
        .fetch_one(server.store.reader())
        .await
        .unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_bad_station_image_fails_its_folder_naming_the_file_and_stores_nothing() {
    let server = TestServer::start(|_| {}).await;
    let epoch = small_scene();
    let watch = tempfile::tempdir().unwrap();
    // (site, extension of the replaced station image, its bytes, the reason error.txt gives)
    type Make = fn(&GreyImage, &Path);
    let cases: [(&str, &str, Make, &str); 5] = [
        (
            "truncated",
            "jpg",
            |img, p| std::fs::write(p, bad_images::truncated_jpeg(img)).unwrap(),
            "truncated JPEG",
        ),
        (
            "onepixel",
            "png",
            |_, p| std::fs::write(p, bad_images::one_pixel_png()).unwrap(),
            "too small",
        ),
        (
            "huge",
            "png",
            |_, p| std::fs::write(p, bad_images::png_claiming(100_000, 100_000)).unwrap(),
            "too large",
        ),
        (
            "giant",
            "jpg",
            |_, p| bad_images::giant_file(p),
            "bytes are not read",
        ),
        (
            "odd",
            "tif",
            |img, p| {
                let d = img.data().iter().map(|&v| v * 257).collect();
                let wide = GreyImage::new(img.width(), img.height(), 16, d).unwrap();
                std::fs::write(p, bad_images::odd_tiff16(&wide)).unwrap()
            },
            "",
        ),
    ];
    let mut files = Vec::new();
    for (site, ext, make, _) in &cases {
        server.create_site(site).await;
        let (folder, _) = write_epoch(
            &watch.path().join(site),
            &epoch,
            "e1",
            "2026-11-20T09:00:00Z",
            true,
            1,
        );
        let png = first_png(&folder);
        let img = decode(&std::fs::read(&png).unwrap()).unwrap();
        std::fs::remove_file(&png).unwrap();
        let bad = png.with_extension(ext);
        make(&img, &bad);
        files.push(bad.file_name().unwrap().to_string_lossy().into_owned());
    }
    let taken = scan_once(
        &server.store,
        &WatchOptions::new(watch.path().to_path_buf()),
    )
    .await;
    assert_eq!(taken.len(), cases.len());
    for ((site, _, _, reason), file) in cases.iter().zip(&files) {
        let site_dir = watch.path().join(site);
        if reason.is_empty() {
            let done = site_dir.join(".done/e1");
            let err = std::fs::read_to_string(done.join("error.txt")).unwrap_or_default();
            assert!(done.is_dir(), "{site}: not taken ({err})");
            assert_eq!(count(&server, "epochs", site).await, 1, "{site}");
            continue;
        }
        let failed = site_dir.join(".failed/e1");
        let err = std::fs::read_to_string(failed.join("error.txt"))
            .unwrap_or_else(|e| panic!("{site}: no error.txt in .failed ({e})"));
        eprintln!("{site}: {}", err.trim());
        assert!(err.contains(file.as_str()), "{site}: {err}");
        assert!(err.contains(reason), "{site}: {err}");
        for table in ["epochs", "observations", "coordinates"] {
            assert_eq!(count(&server, table, site).await, 0, "{site}: {table}");
        }
    }
    // Prometheus counts each site's folders by outcome: one failed, or one done.
    let metrics = server
        .client
        .get(server.url("/metrics"))
        .send()
        .await
        .unwrap()
        .text()
        .await
        .unwrap();
    for (site, _, _, reason) in &cases {
        let outcome = if reason.is_empty() { "done" } else { "failed" };
        let line = metrics
            .lines()
            .find(|l| {
                l.starts_with("cliffwatch_watch_folders_total{")
                    && l.contains(&format!("site=\"{site}\""))
                    && l.contains(&format!("outcome=\"{outcome}\""))
            })
            .unwrap_or_else(|| panic!("{site} {outcome}: {metrics}"));
        assert!(line.ends_with(" 1"), "{line}");
    }
    server.stop().await;
}
