//! The watched directory end to end: rendered station images of the long-range scene + `epoch.json`
//! with 4 seeds per station → detection, identification, ingestion, `.done/`; a second epoch without
//! seeds from the orientations kept in the database; the same folder again is not ingested twice
//! (content hashes in the database); a broken folder goes to `.failed/` with `error.txt`.

use crate::support;

use std::path::Path;

use cliffwatch::watch::{scan_once, WatchOptions};
use cliffwatch_core::photogrammetry::input::epoch::ObservationInput;
use cliffwatch_core::photogrammetry::EpochInput;
use cliffwatch_sim::images::{encode_png, render, ImageSpec, TargetTruth};
use support::server::TestServer;

/// The first station image (`.png`) that `folder` lists.
fn first_png(folder: &Path) -> std::path::PathBuf {
    std::fs::read_dir(folder)
        .unwrap()
        .flatten()
        .find(|f| f.path().extension().is_some_and(|e| e == "png"))
        .unwrap()
        .path()
}

/// Writes `<dir>/<epoch>/` with one PNG per station (targets of 8 px where the scene observes them) and
/// `epoch.json` keeping `seeds` observations per image (the corner-most ones).
fn write_epoch(
    dir: &Path,
    epoch: &EpochInput,
    name: &str,
    observed_at: &str,
    seeds: bool,
    noise_seed: u64,
) {
    let folder = dir.join(name);
    std::fs::create_dir_all(&folder).unwrap();
    let cam = &epoch.cameras[0];
    let (w, h) = (cam.width_px.unwrap(), cam.height_px.unwrap());
    let mut upload = epoch.clone();
    upload.observed_at = observed_at.into();
    for (k, image) in upload.images.iter_mut().enumerate() {
        let mut spec = ImageSpec::new(w, h, 8);
        spec.supersample = 4;
        spec.targets = image
            .observations
            .iter()
            .map(|o| TargetTruth {
                col: o.col.unwrap(),
                row: o.row.unwrap(),
                semi_major_px: 4.0,
                semi_minor_px: 4.0,
                angle_rad: 0.0,
                contrast: 150.0,
            })
            .collect();
        let img = render(&spec, noise_seed * 100 + k as u64).unwrap().image;
        let station = image.station.clone().unwrap_or_else(|| image.id.clone());
        std::fs::write(
            folder.join(format!("{station}.png")),
            encode_png(&img).unwrap(),
        )
        .unwrap();
        let obs = std::mem::take(&mut image.observations);
        if seeds {
            let mut chosen: Vec<ObservationInput> = Vec::new();
            for (sx, sy) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                let best = obs
                    .iter()
                    .filter(|o| !chosen.iter().any(|c| c.point == o.point))
                    .max_by(|a, b| {
                        let f = |o: &ObservationInput| sx * o.col.unwrap() + sy * o.row.unwrap();
                        f(a).total_cmp(&f(b))
                    })
                    .unwrap();
                chosen.push(best.clone());
            }
            image.observations = chosen;
        }
    }
    std::fs::write(
        folder.join("epoch.json"),
        serde_json::to_string(&upload).unwrap(),
    )
    .unwrap();
    std::fs::write(folder.join("READY"), "").unwrap();
}

/// Folders taken (content hashes in the database) and stations with a kept orientation.
async fn taken(store: &cliffwatch::store::Store) -> i64 {
    sqlx::query_scalar("SELECT COUNT(*) FROM watch_folders WHERE site_id = 'kamo'")
        .fetch_one(store.reader())
        .await
        .unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn watched_folders_are_detected_identified_ingested_once() {
    let server = TestServer::start(|_| {}).await;
    server.create_site("kamo").await;
    let watch = tempfile::tempdir().unwrap();
    let site = watch.path().join("kamo");
    let epoch = support::watch::small_scene();
    let opts = WatchOptions::new(watch.path().to_path_buf());

    write_epoch(&site, &epoch, "e1", "2026-11-20T09:00:00Z", true, 1);
    let r = scan_once(&server.store, &opts).await;
    assert_eq!(r.len(), 1);
    let dest = r[0].as_ref().unwrap();
    let err = std::fs::read_to_string(dest.join("error.txt")).unwrap_or_default();
    assert!(dest.starts_with(site.join(".done")), "{dest:?}: {err}");
    assert_eq!(taken(&server.store).await, 1);
    let stations: i64 =
        sqlx::query_scalar("SELECT COUNT(*) FROM watch_orientations WHERE site_id = 'kamo'")
            .fetch_one(server.store.reader())
            .await
            .unwrap();
    assert_eq!(stations, 5, "orientations kept in the database");
    assert!(!site.join(".state/orientations.json").exists());

    // epoch 2: no seeds, identified from the kept orientations; one image's extension in capitals
    write_epoch(&site, &epoch, "e2", "2026-11-21T09:00:00Z", false, 2);
    let png = first_png(&site.join("e2"));
    std::fs::rename(&png, png.with_extension("PNG")).unwrap();
    let r = scan_once(&server.store, &opts).await;
    let dest = r[0].as_ref().unwrap();
    let err = std::fs::read_to_string(dest.join("error.txt")).unwrap_or_default();
    assert!(dest.starts_with(site.join(".done")), "{dest:?}: {err}");
    assert_eq!(taken(&server.store).await, 2);
    let (status, body) = server.get("/api/v1/sites/kamo/epochs").await;
    assert_eq!(status, 200, "{body}");
    assert_eq!(body.to_string().matches("observed_at").count(), 2, "{body}");

    // the same content again: not ingested twice
    let again = site.join("e2-again");
    std::fs::create_dir_all(&again).unwrap();
    for f in std::fs::read_dir(dest).unwrap().flatten() {
        std::fs::copy(f.path(), again.join(f.file_name())).unwrap();
    }
    let r = scan_once(&server.store, &opts).await;
    let dest = r[0].as_ref().unwrap();
    assert!(dest.starts_with(site.join(".done")));
    assert_eq!(taken(&server.store).await, 2);
    let note = std::fs::read_to_string(dest.join("duplicate.txt")).unwrap();
    assert!(
        note.starts_with("not ingested: a folder with the same files was ingested as epoch "),
        "{note}"
    );

    // broken: an image missing
    write_epoch(&site, &epoch, "e3", "2026-11-22T09:00:00Z", false, 3);
    std::fs::remove_file(first_png(&site.join("e3"))).unwrap();
    let r = scan_once(&server.store, &opts).await;
    let dest = r[0].as_ref().unwrap();
    assert!(dest.starts_with(site.join(".failed")), "{dest:?}");
    let err = std::fs::read_to_string(dest.join("error.txt")).unwrap();
    assert!(err.contains("no image file"), "{err}");

    // An image the watcher would leave unused is refused and named: a station missing from
    // epoch.json, or a second file of a station.
    for (folder, day, seed, extra, says) in [
        ("e8", "2026-11-28", 9, "spare-photo.png", "names no station"),
        (
            "e9",
            "2026-11-29",
            10,
            "{station}.JPG",
            "has several image files",
        ),
    ] {
        write_epoch(
            &site,
            &epoch,
            folder,
            &format!("{day}T09:00:00Z"),
            false,
            seed,
        );
        let png = first_png(&site.join(folder));
        let station = png.file_stem().unwrap().to_str().unwrap();
        let extra = extra.replace("{station}", station);
        std::fs::copy(&png, site.join(folder).join(&extra)).unwrap();
        let r = scan_once(&server.store, &opts).await;
        let dest = r[0].as_ref().unwrap();
        assert!(dest.starts_with(site.join(".failed")), "{dest:?}");
        let err = std::fs::read_to_string(dest.join("error.txt")).unwrap();
        assert!(err.contains(says) && err.contains(&extra), "{err}");
    }

    // An image file larger than any the detection reads (sparse: no disk used) is refused
    // without being read into memory.
    write_epoch(&site, &epoch, "e7", "2026-11-27T09:00:00Z", false, 8);
    let png = first_png(&site.join("e7"));
    std::fs::File::options()
        .write(true)
        .open(&png)
        .unwrap()
        .set_len(cliffwatch_core::detect::MAX_IMAGE_FILE_BYTES + 1)
        .unwrap();
    let r = scan_once(&server.store, &opts).await;
    let dest = r[0].as_ref().unwrap();
    assert!(dest.starts_with(site.join(".failed")), "{dest:?}");
    let err = std::fs::read_to_string(dest.join("error.txt")).unwrap();
    assert!(
        err.contains("files above 536870912 bytes are not read"),
        "{err}"
    );

    // An image of another size than its camera declares (a portrait or downscaled export):
    // refused, naming both sizes, not measured from the wrong centre.
    write_epoch(&site, &epoch, "e10", "2026-11-30T09:00:00Z", false, 11);
    let json = site.join("e10/epoch.json");
    let mut upload: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let (w, h) = (
        upload["cameras"][0]["width_px"].clone(),
        upload["cameras"][0]["height_px"].clone(),
    );
    upload["cameras"][0]["width_px"] = h.clone();
    upload["cameras"][0]["height_px"] = w.clone();
    std::fs::write(&json, upload.to_string()).unwrap();
    let r = scan_once(&server.store, &opts).await;
    let dest = r[0].as_ref().unwrap();
    assert!(dest.starts_with(site.join(".failed")), "{dest:?}");
    let err = std::fs::read_to_string(dest.join("error.txt")).unwrap();
    assert!(
        err.contains(&format!("the image is {w} × {h} px"))
            && err.contains(&format!("declares {h} × {w} px")),
        "{err}"
    );

    // A station that is not an identifier names no file of the folder (never `../`).
    write_epoch(&site, &epoch, "e5", "2026-11-24T09:00:00Z", false, 5);
    let json = site.join("e5/epoch.json");
    let mut upload: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    upload["images"][0]["station"] = serde_json::json!("../e3");
    std::fs::write(&json, upload.to_string()).unwrap();
    let r = scan_once(&server.store, &opts).await;
    let dest = r[0].as_ref().unwrap();
    assert!(dest.starts_with(site.join(".failed")), "{dest:?}");
    let err = std::fs::read_to_string(dest.join("error.txt")).unwrap();
    assert!(err.contains("station '../e3'"), "{err}");

    // No epoch.json: the message names the file.
    write_epoch(&site, &epoch, "e6", "2026-11-25T09:00:00Z", false, 6);
    std::fs::remove_file(site.join("e6/epoch.json")).unwrap();
    let r = scan_once(&server.store, &opts).await;
    let dest = r[0].as_ref().unwrap();
    assert!(dest.starts_with(site.join(".failed")), "{dest:?}");
    let err = std::fs::read_to_string(dest.join("error.txt")).unwrap();
    assert!(err.starts_with("epoch.json: "), "{err}");

    // A directory that names no site: said before anything about the folder's files.
    let nosite = site.parent().unwrap().join("nosite");
    write_epoch(&nosite, &epoch, "e1", "2026-11-26T09:00:00Z", false, 7);
    let r = scan_once(&server.store, &opts).await;
    let dest = r
        .iter()
        .flatten()
        .find(|d| d.starts_with(&nosite))
        .expect("the folder of the unknown site was taken");
    assert!(dest.starts_with(nosite.join(".failed")), "{dest:?}");
    let err = std::fs::read_to_string(dest.join("error.txt")).unwrap();
    assert!(err.contains("no site 'nosite'"), "{err}");

    // The database gone (a restart of PostgreSQL, the pools closed at shutdown): the folder is
    // not the one at fault, so it stays for the next scan instead of going to `.failed/`.
    write_epoch(&site, &epoch, "e4", "2026-11-23T09:00:00Z", false, 4);
    server.store.close().await;
    let stays =
        cliffwatch::watch::take_folder(&server.store, "kamo", &site.join("e4"), &opts).await;
    assert!(site.join("e4/READY").is_file(), "{stays:?}");
    assert!(!site.join("e4/error.txt").exists());
    assert!(!site.join(".failed/e4").exists());
    server.stop().await;
}

/// Epochs of 20 and 22 November, then a folder of 21 November taken last: the stations keep the
/// orientations of 22 November, for the next folder to be named from the newest poses.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_folder_taken_late_leaves_the_newer_orientations() {
    let server = TestServer::start(|_| {}).await;
    server.create_site("kamo").await;
    server.create_site("kura").await;
    let watch = tempfile::tempdir().unwrap();
    support::watch::folders_taken_out_of_order(&server.store, watch.path()).await;
    server.stop().await;
}

/// The daemon died after an epoch's commit, before the watcher recorded its state: taken again on
/// restart, the folder is known (its hash was written in the epoch's transaction) and moves to
/// `.done/` as already ingested. It is not named again against coordinates that now include its
/// own epoch, which made another body, a 409 and a move to `.failed/`. The stations'
/// orientations, not saved before the crash, are saved then.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_folder_whose_epoch_committed_before_a_crash_is_not_failed() {
    use cliffwatch::service::ingest::{ingest_watched, WatchedFolder};
    let server = TestServer::start(|_| {}).await;
    server.create_site("kamo").await;
    let watch = tempfile::tempdir().unwrap();
    let site = watch.path().join("kamo");
    let epoch = support::watch::small_scene();
    let opts = WatchOptions::new(watch.path().to_path_buf());
    let at = "2026-11-20T09:00:00Z";
    write_epoch(&site, &epoch, "e1", at, true, 1);
    let folder = site.join("e1");
    // what the first take committed: the epoch, with the folder's hash, and nothing else
    let mut committed = epoch.clone();
    committed.observed_at = at.into();
    let watched = WatchedFolder {
        hash: cliffwatch::watch::content_hash(&folder).unwrap(),
        identification: serde_json::json!([]),
    };
    let first = ingest_watched(
        &server.store,
        "kamo",
        committed,
        Default::default(),
        &watched,
        None,
    )
    .await
    .unwrap();
    assert_eq!(
        taken(&server.store).await,
        1,
        "hash recorded with the epoch"
    );

    let kept = || async {
        sqlx::query_scalar::<_, i64>(
            "SELECT epoch_id FROM watch_orientations WHERE site_id = 'kamo'",
        )
        .fetch_all(server.store.reader())
        .await
        .unwrap()
    };
    assert!(kept().await.is_empty(), "the crash left no orientation");

    let r = scan_once(&server.store, &opts).await;
    let dest = r[0].as_ref().unwrap();
    let err = std::fs::read_to_string(dest.join("error.txt")).unwrap_or_default();
    assert!(dest.starts_with(site.join(".done")), "{dest:?}: {err}");
    let note = std::fs::read_to_string(dest.join("duplicate.txt")).unwrap();
    assert!(
        note.contains(&format!("as epoch {}", first.epoch)),
        "{note}"
    );
    // the stations' orientations, which the crash kept from being saved, are saved now
    assert_eq!(
        kept().await,
        vec![first.epoch; epoch.images.len()],
        "one orientation per station, from the folder's epoch"
    );
    let epochs: Vec<i64> = sqlx::query_scalar("SELECT id FROM epochs WHERE site_id = 'kamo'")
        .fetch_all(server.store.reader())
        .await
        .unwrap();
    assert_eq!(epochs, vec![first.epoch]);
    server.stop().await;
}
