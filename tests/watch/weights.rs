//! The site setting `image_weights`: the same rendered folder through the watched directory of a
//! site weighting by the camera's σ and of one weighting by each target's own σ. σ0 is expressed
//! in the observations' quadratic-mean a-priori σ (σ0 / √variance factor), which shows which σ
//! weighted the observations.

use crate::support;

use cliffwatch::watch::{scan_once, WatchOptions};
use cliffwatch_core::detect::SIGMA_FLOOR_PX;
use serde_json::json;
use support::server::TestServer;
use support::watch::{small_scene, write_epoch};

/// (σ0 mm, variance factor) of the site's one epoch.
async fn sigma0_and_factor(server: &TestServer, site: &str) -> (f64, f64) {
    let (sigma0, report): (f64, String) =
        sqlx::query_as("SELECT sigma0_mm, report FROM epochs WHERE site_id = ?")
            .bind(site)
            .fetch_one(server.store.reader())
            .await
            .unwrap();
    let report: serde_json::Value = serde_json::from_str(&report).unwrap();
    (sigma0, report["variance_factor"].as_f64().unwrap())
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_site_weighting_by_target_sigma_uses_each_targets_sigma() {
    let server = TestServer::start(|_| {}).await;
    server.create_site("camera").await;
    let (status, body) = server
        .post(
            "/api/v1/sites",
            &json!({"id": "target", "model": "orthogonal", "image_weights": "target"}),
        )
        .await;
    assert_eq!(status, 201, "{body}");
    let (_, site) = server.get("/api/v1/sites/target").await;
    assert_eq!(site["image_weights"], "target", "{site}");
    let (_, site) = server.get("/api/v1/sites/camera").await;
    assert_eq!(site["image_weights"], "camera", "{site}");
    let (status, body) = server
        .post(
            "/api/v1/sites",
            &json!({"id": "bad", "model": "orthogonal", "image_weights": "pixels"}),
        )
        .await;
    assert!((400..500).contains(&status), "{status}: {body}");

    let epoch = small_scene();
    let cam = &epoch.cameras[0];
    let pixel = cam.pixel_size_mm.unwrap();
    let camera_sigma = cam.sigma_mm.unwrap_or(0.5 * pixel);
    let watch = tempfile::tempdir().unwrap();
    for site in ["camera", "target"] {
        write_epoch(
            &watch.path().join(site),
            &epoch,
            "e1",
            "2026-11-20T09:00:00Z",
            true,
            1,
        );
    }
    let r = scan_once(
        &server.store,
        &WatchOptions::new(watch.path().to_path_buf()),
    )
    .await;
    for dest in &r {
        let dest = dest.as_ref().unwrap();
        let err = std::fs::read_to_string(dest.join("error.txt")).unwrap_or_default();
        assert!(dest.to_string_lossy().contains(".done"), "{dest:?}: {err}");
    }
    let (s_cam, vf_cam) = sigma0_and_factor(&server, "camera").await;
    let (s_tgt, vf_tgt) = sigma0_and_factor(&server, "target").await;
    let (ref_cam, ref_tgt) = (s_cam / vf_cam.sqrt(), s_tgt / vf_tgt.sqrt());
    eprintln!(
        "σ0 {:.4} / {:.4} px, a-priori σ {:.4} / {:.4} px (camera / target weights)",
        s_cam / pixel,
        s_tgt / pixel,
        ref_cam / pixel,
        ref_tgt / pixel
    );
    // camera weights: the camera's σ; target weights: the targets' σ, the floor and the
    // centring's few thousandths of a pixel on these rendered 8 px targets
    assert!((ref_cam / camera_sigma - 1.0).abs() < 1e-6, "{ref_cam} mm");
    let floor = SIGMA_FLOOR_PX * pixel;
    assert!(ref_tgt >= floor && ref_tgt < 1.1 * floor, "{ref_tgt} mm");
    // the same centres either way: σ0 agrees
    assert!(
        (s_tgt / s_cam - 1.0).abs() < 0.05,
        "σ0 {s_tgt} vs {s_cam} mm"
    );
    server.stop().await;
}
