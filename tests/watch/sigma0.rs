//! End to end through the watched directory on the scene: the long-range cliff (28 targets,
//! 5 stations, 2160 × 1440 px, default seed) rendered as 8-bit PNGs (targets of 8 px, contrast-to-noise
//! 50) becomes an epoch whose σ0 is within 1.5 × that of uploading the same scene's true image
//! centres with Gaussian noise of 0.02/√2 px per coordinate — the centring bound for targets
//! ≥ 6 px (radial RMS 0.02 px) — on a second site; every target is identified with its true label.
//! A second epoch with three targets moved by 25–30 mm (≈ 10 px on the images), without seeds, is
//! identified from the first epoch's orientations, again every label right.

use crate::support;

use std::collections::BTreeMap;

use cliffwatch::store::Store;
use cliffwatch::watch::{scan_once, WatchOptions};
use cliffwatch_sim::scenes::{long_range, project, LongRangeParams};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use support::server::TestServer;
use support::watch::write_epoch;

/// σ0 (image mm) of every epoch of a site, by epoch id.
async fn sigma0s(store: &Store, site: &str) -> Vec<(i64, f64)> {
    sqlx::query_as("SELECT id, sigma0_mm FROM epochs WHERE site_id = ? ORDER BY id")
        .bind(site)
        .fetch_all(store.reader())
        .await
        .unwrap()
}

/// Stored pixel observations of an epoch: (image, point, col, row).
async fn observations(store: &Store, site: &str, epoch: i64) -> Vec<(String, String, f64, f64)> {
    sqlx::query_as(
        "SELECT image_id, point, col_px, row_px FROM observations \
         WHERE site_id = ? AND epoch_id = ? ORDER BY image_id, point",
    )
    .bind(site)
    .bind(epoch)
    .fetch_all(store.reader())
    .await
    .unwrap()
}

/// Asserts that the stored observations are exactly the truth's (image, point) pairs, each within
/// 0.5 px of its true centre (a wrong label is ≥ 100 px off here); returns the radial RMS in px.
fn check_labels(
    obs: &[(String, String, f64, f64)],
    truth: &BTreeMap<String, BTreeMap<String, [f64; 2]>>,
    what: &str,
) -> f64 {
    let n_truth: usize = truth.values().map(|m| m.len()).sum();
    assert_eq!(
        obs.len(),
        n_truth,
        "{what}: identified {} of {n_truth}",
        obs.len()
    );
    let mut sum = 0.0;
    for (image, point, col, row) in obs {
        let t = truth[image][point];
        let e = (col - t[0]).hypot(row - t[1]);
        assert!(
            e < 0.5,
            "{what}: {image}/{point} is {e:.2} px from its truth"
        );
        sum += e * e;
    }
    (sum / obs.len() as f64).sqrt()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn watched_epochs_match_true_centres_precision_and_follow_moved_targets() {
    let server = TestServer::start(|_| {}).await;
    server.create_site("cliff").await;
    server.create_site("truth").await;
    let params = LongRangeParams {
        noise_px: 0.0,
        // the site's coordinates known to 1 cm (earlier epochs); see tests/watch/dir.rs
        approx_sigma_m: 0.01,
        ..LongRangeParams::default()
    };
    assert_eq!(
        (params.n_points, params.n_stations),
        (28, 5),
        "the issue's scene"
    );
    assert_eq!((params.width_px, params.height_px), (2160, 1440));
    let (epoch, truth) = long_range(&params).unwrap();
    let watch = tempfile::tempdir().unwrap();
    let site = watch.path().join("cliff");
    let opts = WatchOptions::new(watch.path().to_path_buf());

    // epoch 1: images + 4 seeds per station
    let (_, truth1) = write_epoch(&site, &epoch, "e1", "2026-11-20T09:00:00Z", true, 1);
    let r = scan_once(&server.store, &opts).await;
    let dest = r[0].as_ref().unwrap();
    let err = std::fs::read_to_string(dest.join("error.txt")).unwrap_or_default();
    assert!(dest.starts_with(site.join(".done")), "{dest:?}: {err}");
    let watched = sigma0s(&server.store, "cliff").await;
    assert_eq!(watched.len(), 1);
    let rms1 = check_labels(
        &observations(&server.store, "cliff", watched[0].0).await,
        &truth1,
        "epoch 1",
    );

    // the same scene uploaded with the true centres plus the noise a detector at the bound has
    let sigma_px = 0.02 / std::f64::consts::SQRT_2;
    let normal = Normal::new(0.0, sigma_px).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let mut noisy = epoch.clone();
    noisy.observed_at = "2026-11-20T09:00:00Z".into();
    for image in &mut noisy.images {
        for o in &mut image.observations {
            o.col = Some(o.col.unwrap() + normal.sample(&mut rng));
            o.row = Some(o.row.unwrap() + normal.sample(&mut rng));
        }
    }
    let (status, body) = server
        .upload("truth", &serde_json::to_value(&noisy).unwrap())
        .await;
    assert!(status < 300, "{status}: {body}");
    let reference = sigma0s(&server.store, "truth").await;
    let (s_watch, s_ref) = (watched[0].1, reference[0].1);
    let px = params.pixel_size_mm;
    eprintln!(
        "epoch 1: detected centres radial RMS {rms1:.4} px; σ0 watched {:.4} px, true centres + \
         {sigma_px:.4} px noise {:.4} px, ratio {:.2}",
        s_watch / px,
        s_ref / px,
        s_watch / s_ref
    );
    assert!(
        s_watch <= 1.5 * s_ref,
        "σ0 watched {s_watch} mm vs true centres with noise {s_ref} mm"
    );

    // epoch 2: three targets moved (site frame: along the face, up, toward the cameras), no seeds
    let moves: BTreeMap<&str, [f64; 3]> = [
        ("T105", [0.025, 0.0, 0.0]),
        ("T115", [0.0, -0.02, 0.015]),
        ("T124", [-0.015, 0.02, 0.01]),
    ]
    .into_iter()
    .collect();
    let interior = [truth.c_mm, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];
    let (w, h) = (params.width_px as f64, params.height_px as f64);
    let mut moved = epoch.clone();
    for image in &mut moved.images {
        let cam = &truth.cameras[&image.id];
        for o in &mut image.observations {
            let mut x = truth.points[&o.point];
            if let Some(d) = moves.get(o.point.as_str()) {
                x = [x[0] + d[0], x[1] + d[1], x[2] + d[2]];
            }
            let xy = project(&cam.r, cam.xo, &interior, x).unwrap();
            let (col, row) = (xy[0] / px + (w - 1.0) / 2.0, (h - 1.0) / 2.0 - xy[1] / px);
            if !moves.contains_key(o.point.as_str()) {
                // the same projection as the scene's (noise-free) observations
                assert!((col - o.col.unwrap()).hypot(row - o.row.unwrap()) < 1e-6);
            }
            (o.col, o.row) = (Some(col), Some(row));
        }
    }
    let (_, truth2) = write_epoch(&site, &moved, "e2", "2026-11-21T09:00:00Z", false, 2);
    let r = scan_once(&server.store, &opts).await;
    let dest = r[0].as_ref().unwrap();
    let err = std::fs::read_to_string(dest.join("error.txt")).unwrap_or_default();
    assert!(dest.starts_with(site.join(".done")), "{dest:?}: {err}");
    let watched = sigma0s(&server.store, "cliff").await;
    assert_eq!(watched.len(), 2);
    let obs2 = observations(&server.store, "cliff", watched[1].0).await;
    let rms2 = check_labels(&obs2, &truth2, "epoch 2");
    // the moved targets did move on the images (by more than a few px), and were followed
    let shift = |p: &str| -> f64 {
        truth1
            .iter()
            .filter_map(|(img, m)| {
                m.get(p)
                    .map(|a| (a[0] - truth2[img][p][0]).hypot(a[1] - truth2[img][p][1]))
            })
            .fold(0.0, f64::max)
    };
    for p in moves.keys() {
        assert!(shift(p) > 3.0, "{p} moved only {:.2} px", shift(p));
    }
    eprintln!(
        "epoch 2: all {} observations labelled right, radial RMS {rms2:.4} px, σ0 {:.4} px; image \
         motion of the moved targets {:?} px",
        obs2.len(),
        watched[1].1 / px,
        moves
            .keys()
            .map(|p| (shift(p) * 10.0).round() / 10.0)
            .collect::<Vec<_>>()
    );
    server.stop().await;
}
