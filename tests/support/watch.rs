//! Shared helpers of the watched-directory tests: rendering an epoch of a scene into a folder
//! `<site_dir>/<name>/` (one PNG per station, `epoch.json`, `READY`).
#![allow(dead_code)]

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use cliffwatch_core::photogrammetry::input::epoch::ObservationInput;
use cliffwatch_core::photogrammetry::EpochInput;
use cliffwatch_sim::images::{encode_png, render, ImageSpec, TargetTruth};
use cliffwatch_sim::scenes::{long_range, LongRangeParams};

/// The long-range scene at 1080 × 720 px (21 µm pixels), without image noise, its approximations
/// known to 1 cm (a site with earlier epochs; ±0.5 m would leave every target ambiguous, as it
/// should): what the watched-directory tests render.
pub fn small_scene() -> EpochInput {
    long_range(&LongRangeParams {
        width_px: 1080,
        height_px: 720,
        pixel_size_mm: 0.021,
        noise_px: 0.0,
        approx_sigma_m: 0.01,
        ..LongRangeParams::default()
    })
    .unwrap()
    .0
}

/// Target diameter of the rendered images in px.
pub const TARGET_PX: f64 = 8.0;

/// The 4 observations of an image nearest its corners (the hand-measured seeds of a first epoch).
pub fn corner_seeds(obs: &[ObservationInput]) -> Vec<ObservationInput> {
    let mut chosen: Vec<ObservationInput> = Vec::new();
    for (sx, sy) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
        let f = |o: &ObservationInput| sx * o.col.unwrap() + sy * o.row.unwrap();
        let best = obs
            .iter()
            .filter(|o| !chosen.iter().any(|c| c.point == o.point))
            .max_by(|a, b| f(a).total_cmp(&f(b)))
            .unwrap();
        chosen.push(best.clone());
    }
    chosen
}

/// Writes `<site_dir>/<name>/`: per image of `epoch` a PNG (8-bit, contrast-to-noise 50, targets of
/// [`TARGET_PX`] at the observations' pixel positions, image noise from `noise_seed`) and
/// `epoch.json` keeping only the 4 corner seeds per image (`seeds`) or no observations. `READY` is
/// written last. Returns the folder and the rendered truth (image id → point → (col, row)).
pub fn write_epoch(
    site_dir: &Path,
    epoch: &EpochInput,
    name: &str,
    observed_at: &str,
    seeds: bool,
    noise_seed: u64,
) -> (PathBuf, BTreeMap<String, BTreeMap<String, [f64; 2]>>) {
    let folder = site_dir.join(name);
    std::fs::create_dir_all(&folder).unwrap();
    let cam = &epoch.cameras[0];
    let (w, h) = (cam.width_px.unwrap(), cam.height_px.unwrap());
    let mut upload = epoch.clone();
    upload.observed_at = observed_at.into();
    let mut truth = BTreeMap::new();
    for (k, image) in upload.images.iter_mut().enumerate() {
        let mut spec = ImageSpec::new(w, h, 8);
        spec.targets = image
            .observations
            .iter()
            .map(|o| TargetTruth {
                col: o.col.unwrap(),
                row: o.row.unwrap(),
                semi_major_px: 0.5 * TARGET_PX,
                semi_minor_px: 0.5 * TARGET_PX,
                angle_rad: 0.0,
                contrast: 50.0 * spec.noise_sigma,
            })
            .collect();
        let img = render(&spec, noise_seed * 100 + k as u64).unwrap().image;
        let station = image.station.clone().unwrap_or_else(|| image.id.clone());
        std::fs::write(
            folder.join(format!("{station}.png")),
            encode_png(&img).unwrap(),
        )
        .unwrap();
        truth.insert(
            image.id.clone(),
            image
                .observations
                .iter()
                .map(|o| (o.point.clone(), [o.col.unwrap(), o.row.unwrap()]))
                .collect(),
        );
        let obs = std::mem::take(&mut image.observations);
        if seeds {
            image.observations = corner_seeds(&obs);
        }
    }
    std::fs::write(
        folder.join("epoch.json"),
        serde_json::to_string(&upload).unwrap(),
    )
    .unwrap();
    std::fs::write(folder.join("READY"), "").unwrap();
    (folder, truth)
}

/// Takes folders of sites `kura` and `kamo` (both created by the caller) from `watch_dir`. First
/// `kura`: its epochs 1 and 2, of 30 and 1 November, have the ids that `kamo`'s will have but run
/// backwards in time. Then `kamo`: epochs of 20 and 22 November, then a folder of 21 November last.
/// Asserts that each went to `.done/` and that every station of `kamo` keeps the orientation of
/// 22 November (its newest epoch), neither that of the folder taken last nor one chosen by
/// `kura`'s epochs of the same ids.
pub async fn folders_taken_out_of_order(store: &cliffwatch::store::Store, watch_dir: &Path) {
    let epoch = small_scene();
    let opts = cliffwatch::watch::WatchOptions::new(watch_dir.to_path_buf());
    let kura = watch_dir.join("kura");
    for (name, at, seeds, noise) in [
        ("k30", "2026-11-30T09:00:00Z", true, 4),
        ("k01", "2026-11-01T09:00:00Z", false, 5),
    ] {
        write_epoch(&kura, &epoch, name, at, seeds, noise);
        let r = cliffwatch::watch::scan_once(store, &opts).await;
        let dest = r[0].as_ref().unwrap();
        assert!(dest.starts_with(kura.join(".done")), "{name}: {dest:?}");
    }
    let site = watch_dir.join("kamo");
    for (name, at, seeds, noise) in [
        ("e20", "2026-11-20T09:00:00Z", true, 1),
        ("e22", "2026-11-22T09:00:00Z", false, 2),
        ("e21", "2026-11-21T09:00:00Z", true, 3),
    ] {
        write_epoch(&site, &epoch, name, at, seeds, noise);
        let r = cliffwatch::watch::scan_once(store, &opts).await;
        let dest = r[0].as_ref().unwrap();
        let err = std::fs::read_to_string(dest.join("error.txt")).unwrap_or_default();
        assert!(
            dest.starts_with(site.join(".done")),
            "{name}: {dest:?}: {err}"
        );
    }
    let epochs: Vec<i64> =
        sqlx::query_scalar("SELECT id FROM epochs WHERE site_id = 'kamo' ORDER BY observed_at")
            .fetch_all(store.reader())
            .await
            .unwrap();
    let kept: Vec<i64> =
        sqlx::query_scalar("SELECT epoch_id FROM watch_orientations WHERE site_id = 'kamo'")
            .fetch_all(store.reader())
            .await
            .unwrap();
    assert_eq!(epochs.len(), 3);
    assert_eq!(
        kept.len(),
        epoch.images.len(),
        "one orientation per station"
    );
    assert!(
        kept.iter().all(|e| *e == epochs[2]),
        "orientations of epochs {kept:?}, the newest is {}",
        epochs[2]
    );
}
