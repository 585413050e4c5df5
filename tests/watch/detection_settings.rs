//! Per-site detection settings (issue 59, item 6): `detection` (`polarity`, `min_diameter_px`,
//! `max_diameter_px`) in the site's settings, each field overridable by a folder's `epoch.json`,
//! checked by name, and shown on the epoch page with where each came from. The rendered targets
//! are bright and 8 px across.

use std::path::Path;

use crate::support;

use cliffwatch::watch::{scan_once, WatchOptions};
use serde_json::{json, Value};
use support::dashboard::{html, text_of};
use support::server::TestServer;
use support::watch::{small_scene, write_epoch};

/// Sets `epoch.json`'s `detection` in `folder`.
fn override_detection(folder: &Path, detection: Value) {
    let path = folder.join("epoch.json");
    let mut v: Value = serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    v["detection"] = detection;
    std::fs::write(&path, v.to_string()).unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_sites_detection_settings_apply_a_folder_overrides_them_and_the_page_says_so() {
    let server = TestServer::start(|_| {}).await;
    for (id, detection) in [
        ("plain", Value::Null),
        ("narrow", json!({"max_diameter_px": 5.0})),
        ("dark", json!({"polarity": "dark"})),
    ] {
        let mut body = json!({"id": id, "model": "orthogonal"});
        if !detection.is_null() {
            body["detection"] = detection.clone();
        }
        let (status, r) = server.post("/api/v1/sites", &body).await;
        assert_eq!(status, 201, "{r}");
        let (_, site) = server.get(&format!("/api/v1/sites/{id}")).await;
        let shown = if detection.is_null() {
            json!({})
        } else {
            detection
        };
        assert_eq!(site["detection"], shown, "{site}");
    }
    // Refused by name, and nothing created.
    for (detection, field) in [
        (json!({"min_diameter_px": 0.5}), "detection.min_diameter_px"),
        (
            json!({"min_diameter_px": 80}),
            "detection.max_diameter_px 64",
        ),
        (json!({"polarity": "grey"}), "polarity"),
        (json!({"diameter": 8}), "diameter"),
    ] {
        let (status, r) = server
            .post(
                "/api/v1/sites",
                &json!({"id": "bad", "model": "orthogonal", "detection": detection}),
            )
            .await;
        assert!((400..500).contains(&status), "{detection}: {status} {r}");
        assert!(r.to_string().contains(field), "{detection}: {r}");
        let (status, _) = server.get("/api/v1/sites/bad").await;
        assert_eq!(status, 404, "{detection}");
    }

    let epoch = small_scene();
    let watch = tempfile::tempdir().unwrap();
    let dir = |site: &str| watch.path().join(site);
    write_epoch(&dir("plain"), &epoch, "e1", "2026-11-20T09:00:00Z", true, 1);
    let (bad, _) = write_epoch(&dir("plain"), &epoch, "e2", "2026-11-21T09:00:00Z", true, 2);
    override_detection(&bad, json!({"min_diameter_px": 0}));
    let (grey, _) = write_epoch(&dir("plain"), &epoch, "e3", "2026-11-22T09:00:00Z", true, 3);
    override_detection(&grey, json!({"polarity": "grey"}));
    write_epoch(
        &dir("narrow"),
        &epoch,
        "e1",
        "2026-11-20T09:00:00Z",
        true,
        1,
    );
    let (wide, _) = write_epoch(
        &dir("narrow"),
        &epoch,
        "e2",
        "2026-11-21T09:00:00Z",
        true,
        2,
    );
    override_detection(&wide, json!({"max_diameter_px": 20}));
    write_epoch(&dir("dark"), &epoch, "e1", "2026-11-20T09:00:00Z", true, 1);
    let mut opts = WatchOptions::new(watch.path().to_path_buf());
    opts.settle = std::time::Duration::ZERO;
    let taken: Vec<_> = scan_once(&server.store, &opts)
        .await
        .into_iter()
        .map(|r| r.unwrap())
        .collect();
    let outcome = |site: &str, folder: &str| -> (bool, String) {
        let done = dir(site).join(".done").join(folder);
        let failed = dir(site).join(".failed").join(folder);
        assert!(
            done.exists() || failed.exists(),
            "{site}/{folder} not taken: {taken:?}"
        );
        let err = std::fs::read_to_string(failed.join("error.txt")).unwrap_or_default();
        (done.exists(), err)
    };
    // The defaults measure the bright 8 px targets; so does the narrow site's folder that
    // widens the range; the narrow range alone and the dark polarity find none.
    let (ok, err) = outcome("plain", "e1");
    assert!(ok, "plain/e1: {err}");
    let (ok, err) = outcome("plain", "e2");
    assert!(
        !ok && err.contains("detection.min_diameter_px"),
        "plain/e2: {err}"
    );
    let (ok, err) = outcome("plain", "e3");
    assert!(
        !ok && err.contains("epoch.json: detection: unknown variant `grey`"),
        "plain/e3: {err}"
    );
    let (ok, err) = outcome("narrow", "e1");
    assert!(!ok, "narrow/e1 measured with targets above its 5 px: {err}");
    assert!(
        err.contains("no target found (polarity auto, diameters 2.5–5 px)"),
        "{err}"
    );
    let (ok, err) = outcome("narrow", "e2");
    assert!(ok, "narrow/e2: {err}");
    let (ok, err) = outcome("dark", "e1");
    assert!(!ok, "dark/e1 measured bright targets as dark: {err}");
    assert!(
        err.contains("no target found (polarity dark, diameters 2.5–64 px)"),
        "{err}"
    );

    for (site, expected) in [
        (
            "plain",
            "polarity auto, found bright · diameters 2.5–64 px · from default",
        ),
        (
            "narrow",
            "polarity auto, found bright · diameters 2.5–20 px · from epoch.json, default",
        ),
    ] {
        let (status, page) = html(&server, &format!("/sites/{site}/epochs/1")).await;
        assert_eq!(status, 200, "{site}");
        let text = text_of(&page);
        assert!(text.contains("detection settings"), "{site}: {text}");
        assert!(
            text.contains(expected),
            "{site}: '{expected}' not in {text}"
        );
    }
    server.stop().await;
}
