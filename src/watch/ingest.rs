//! One ready folder taken (the use case): detected, named, ingested exactly as an upload (the
//! epoch's one transaction), then the watcher's state recorded and the folder moved.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use super::folders::{
    content_hash, free_destination, move_folder, move_to, read_state_file, station_images,
};
use super::inside::{check_folder, is_real_dir, read_to_string_inside, write_replacing};
use super::naming::name_targets;
use super::state::{load_orientations, save_state};
use super::stations::{detect_station, station_of, StationCounts, StationData, StationNamed};
use super::{WatchError, WatchOptions};
use crate::service::ingest::{ingest_watched, Ingested, WatchedFolder};
use crate::store::sites::ImageWeights;
use crate::store::{points, watch_state, Store};
use cliffwatch_core::detect::convergent::ConvergentSite;
use cliffwatch_core::detect::identify::{resect_seeds, Seed};
use cliffwatch_core::detect::settings::DetectionSettings;
use cliffwatch_core::photogrammetry::input::epoch::ObservationInput;
use cliffwatch_core::photogrammetry::{EpochInput, ImageOrientation, Model};

/// A folder's targets detected and named: the upload form with the named observations, and what
/// the resection of each station needs.
struct Identified {
    input: EpochInput,
    stations: Vec<StationData>,
    names: Vec<StationNamed>,
    counts: Vec<StationCounts>,
}

/// Detects, identifies and ingests one folder of content hash `hash` (does not move it; writes its
/// `identification.json`). `done` is where the folder will move, relative to the site's directory
/// (kept in the report so the dashboard finds the images). Returns the ingestion and the
/// orientations found per station (resected from this epoch's adjusted coordinates).
pub(super) async fn process(
    store: &Store,
    site: &str,
    folder: &Path,
    hash: &str,
    done: &str,
    opts: &WatchOptions,
) -> Result<(Ingested, BTreeMap<String, ImageOrientation>), WatchError> {
    let found = identify(store, site, folder, done, opts).await?;
    let watched = WatchedFolder {
        hash: hash.to_string(),
        identification: serde_json::to_value(&found.counts)?,
    };
    let public_url = opts.public_url.as_deref();
    let ingested =
        ingest_watched(store, site, found.input, opts.limits, &watched, public_url).await?;
    let orientations =
        resect_stations(store, site, ingested.epoch, &found.stations, &found.names).await?;
    Ok((ingested, orientations))
}

/// A folder's detection settings: the site's with `epoch.json`'s `detection` over them, and
/// their sources (`epoch.json`, `site`, `default`).
struct FolderDetection {
    settings: DetectionSettings,
    from: Vec<String>,
}

/// `epoch.json`: the upload form, and an optional `detection` object over the site's settings
/// (checked like the site's, the message naming the field).
fn parse_epoch_json(
    text: &str,
    site: &DetectionSettings,
) -> Result<(EpochInput, FolderDetection), WatchError> {
    let mut value: serde_json::Value = serde_json::from_str(text)?;
    let folder: DetectionSettings = match value.as_object_mut().and_then(|o| o.remove("detection"))
    {
        Some(d) => serde_json::from_value(d)
            .map_err(|e| WatchError::Detection(format!("detection: {e}")))?,
        None => DetectionSettings::default(),
    };
    folder.validate(Some(site)).map_err(WatchError::Detection)?;
    let input: EpochInput = serde_json::from_value(value)?;
    let settings = folder.over(*site);
    let given = |d: &DetectionSettings| {
        [
            d.polarity.is_some(),
            d.min_diameter_px.is_some(),
            d.max_diameter_px.is_some(),
        ]
    };
    let (f, st, all) = (given(&folder), given(site), given(&settings));
    let mut from = Vec::new();
    if f.contains(&true) {
        from.push("epoch.json".to_string());
    }
    if (0..3).any(|i| st[i] && !f[i]) {
        from.push("site".to_string());
    }
    if all.contains(&false) {
        from.push("default".to_string());
    }
    Ok((input, FolderDetection { settings, from }))
}

/// Detects and names the targets of `folder` (writes its `identification.json`; `done` as in
/// [`process`]).
async fn identify(
    store: &Store,
    site: &str,
    folder: &Path,
    done: &str,
    opts: &WatchOptions,
) -> Result<Identified, WatchError> {
    let site_dir = folder.parent().unwrap_or(Path::new("."));
    let Some(settings) = crate::store::sites::get(store.reader(), site).await? else {
        return Err(WatchError::UnknownSite(site.to_string()));
    };
    let per_target = settings.image_weights == ImageWeights::Target;
    // not through a link, nor from a FIFO ([`super::inside`])
    let path = folder.join("epoch.json");
    let text = tokio::task::spawn_blocking(move || read_to_string_inside(&path))
        .await
        .map_err(|e| WatchError::Task(e.to_string()))?
        .map_err(|source| WatchError::File {
            file: "epoch.json".into(),
            source,
        })?;
    let (mut input, detection) = parse_epoch_json(&text, &settings.detection)?;
    let mut opts = opts.clone();
    detection.settings.apply(&mut opts.detect);
    let opts = &opts;
    // known points: the site's latest coordinates, then the upload's control and approximations
    let mut known: BTreeMap<String, [f64; 3]> = BTreeMap::new();
    for a in &input.approx {
        known.insert(a.point.clone(), [a.X, a.Y, a.Z]);
    }
    for c in &input.control {
        known.insert(c.point.clone(), [c.X, c.Y, c.Z]);
    }
    // A failed read is the database's fault, not the folder's: it stays for the next scan
    // (naming without the site's points would send it to `.failed/` for the wrong reason).
    let mut db = store.read().await?;
    for c in points::latest_coordinates(&mut db, site).await? {
        known.insert(c.point, c.xyz);
    }
    drop(db);
    let listed: Vec<String> = input
        .images
        .iter()
        .map(station_of)
        .collect::<Result<_, _>>()?;
    let images = station_images(folder, &listed)?;
    let previous = load_orientations(store, site, site_dir).await?;
    let mut stations = Vec::with_capacity(input.images.len());
    for image in &input.images {
        stations.push(detect_station(&images, image, &input.cameras, opts, &detection.from).await?);
    }
    // Matching across stations and the assignments are CPU work: a blocking thread.
    let naming_opts = opts.clone();
    let central = (settings.model == Model::Central).then(|| {
        (
            input.cameras.clone(),
            input.control.clone(),
            input.observed_at.clone(),
        )
    });
    let (stations, named) = tokio::task::spawn_blocking(move || {
        let site = central
            .as_ref()
            .map(|(cameras, control, observed_at)| ConvergentSite {
                cameras,
                control,
                observed_at,
            });
        let named = name_targets(&stations, &known, &previous, site.as_ref(), &naming_opts);
        (stations, named)
    })
    .await
    .map_err(|e| WatchError::Task(e.to_string()))?;
    let (names, mut counts) = named?;
    for c in &mut counts {
        c.folder = done.to_string();
    }
    for c in &counts {
        tracing::info!(
            site,
            station = c.station,
            method = c.method,
            detected = c.detected,
            identified = c.identified,
            ambiguous = c.ambiguous,
            unmatched = c.unmatched,
            "watched image identified"
        );
    }
    let (path, text) = (
        folder.join("identification.json"),
        serde_json::to_string_pretty(&counts)?,
    );
    tokio::task::spawn_blocking(move || write_replacing(&path, text.as_bytes()))
        .await
        .map_err(|e| WatchError::Task(e.to_string()))??;
    for ((image, s), named) in input.images.iter_mut().zip(&stations).zip(&names) {
        image.observations = named
            .iter()
            .map(|(point, blob)| ObservationInput {
                point: point.clone(),
                x_mm: None,
                y_mm: None,
                col: Some(s.targets[*blob].0),
                row: Some(s.targets[*blob].1),
                // the site's setting: each target at its own σ, else the camera's
                sigma_mm: s
                    .camera
                    .pixel_size_mm
                    .filter(|_| per_target)
                    .map(|px| px * s.sigmas_px[*blob]),
            })
            .collect();
    }
    Ok(Identified {
        input,
        stations,
        names,
        counts,
    })
}

/// The stations' orientations for the next epoch, resected from the adjusted coordinates of
/// `epoch` (the folder's own: a folder taken late may hold an older epoch than the site's latest).
/// A station whose resection fails is left out (logged).
async fn resect_stations(
    store: &Store,
    site: &str,
    epoch: i64,
    stations: &[StationData],
    names: &[StationNamed],
) -> Result<BTreeMap<String, ImageOrientation>, WatchError> {
    let adjusted: BTreeMap<String, [f64; 3]> =
        points::epoch_coordinates(store.reader(), site, epoch)
            .await?
            .into_iter()
            .map(|c| (c.point, c.xyz))
            .collect();
    let measured: Vec<(String, Vec<Seed>, _)> = stations
        .iter()
        .zip(names)
        .map(|(s, named)| {
            let seeds = named
                .iter()
                .filter(|(p, _)| adjusted.contains_key(p))
                .map(|(p, blob)| Seed {
                    point: p.clone(),
                    xy_mm: s.blobs[*blob],
                })
                .collect();
            (s.station.clone(), seeds, s.camera.clone())
        })
        .collect();
    // The resections are least-squares fits: a blocking thread.
    let site = site.to_string();
    tokio::task::spawn_blocking(move || {
        let mut found = BTreeMap::new();
        for (station, seeds, camera) in &measured {
            match resect_seeds(seeds, &adjusted, camera) {
                Ok((o, _)) => {
                    found.insert(station.clone(), o);
                }
                Err(e) => tracing::warn!(site, station, error = %e, "no orientation kept"),
            }
        }
        found
    })
    .await
    .map_err(|e| WatchError::Task(e.to_string()))
}

/// Where `folder` will move in `.done/`: the path, and the same relative to the site's directory.
fn done_destination(folder: &Path) -> (PathBuf, String) {
    let done = free_destination(folder, ".done");
    let relative = format!(
        ".done/{}",
        done.file_name().unwrap_or_default().to_string_lossy()
    );
    (done, relative)
}

/// The stations' orientations of a folder whose epoch `epoch` is stored, saved again: the daemon
/// may have stopped between the epoch's commit and [`save_state`], which left them unsaved. The
/// targets are detected and named again and the stations resected from that epoch's coordinates;
/// an orientation stored from a later epoch stays ([`watch_state::set_orientation`]). A failure is
/// logged: the folder is ingested all the same.
async fn restore_orientations(
    store: &Store,
    site: &str,
    folder: &Path,
    hash: &str,
    epoch: i64,
    opts: &WatchOptions,
) {
    let (_, done) = done_destination(folder);
    let restored = async {
        let found = identify(store, site, folder, &done, opts).await?;
        let orientations =
            resect_stations(store, site, epoch, &found.stations, &found.names).await?;
        save_state(store, site, hash, epoch, &orientations).await?;
        Ok::<_, WatchError>(orientations.len())
    };
    match restored.await {
        Ok(n) => tracing::info!(
            site,
            epoch,
            stations = n,
            "orientations of an ingested folder saved"
        ),
        Err(e) => {
            tracing::warn!(site, epoch, error = %e, "orientations of an ingested folder not saved")
        }
    }
}

/// Takes one ready folder: skips it when its hash was ingested before, otherwise processes it; moves it
/// to `.done/` or `.failed/` (with `error.txt`). Returns the destination. When the database fails
/// ([`WatchError::is_transient`]) the folder stays where it is, for the next scan, and that is
/// what is returned. A folder holding a link, a file with several hard links or a special file
/// goes to `.failed/` with `error.txt` naming it, nothing behind it read ([`super::inside`]); a
/// `folder` or site folder that is itself a link is an error, and nothing is written.
pub async fn take_folder(
    store: &Store,
    site: &str,
    folder: &Path,
    opts: &WatchOptions,
) -> std::io::Result<PathBuf> {
    let site_dir = folder.parent().unwrap_or(Path::new(".")).to_path_buf();
    for dir in [site_dir.as_path(), folder] {
        if !is_real_dir(dir)? {
            return Err(std::io::Error::new(
                std::io::ErrorKind::NotFound,
                format!("{}: no such folder", dir.display()),
            ));
        }
    }
    let to_check = folder.to_path_buf();
    let refused = tokio::task::spawn_blocking(move || check_folder(&to_check))
        .await
        .map_err(std::io::Error::other)??;
    if let Some(r) = refused {
        return fail_folder(site, folder, &format!("not taken: {r}"));
    }
    // Hashing reads every file (images of up to 512 MiB): a blocking thread's work. A file that
    // cannot be read fails the folder, with the reason, instead of failing every scan.
    let to_hash = folder.to_path_buf();
    let hash = match tokio::task::spawn_blocking(move || content_hash(&to_hash))
        .await
        .map_err(std::io::Error::other)?
    {
        Ok(hash) => hash,
        Err(e) => {
            return fail_folder(
                site,
                folder,
                &format!("a file of the folder cannot be read: {e}"),
            )
        }
    };
    let legacy = read_state_file(&site_dir, "ingested").unwrap_or_default();
    let earlier = watch_state::folder_epoch(store.reader(), site, &hash)
        .await
        .map_err(std::io::Error::other)?;
    let seen = earlier.is_some()
        || legacy
            .lines()
            .any(|l| l.split_whitespace().next() == Some(hash.as_str()));
    if seen {
        tracing::warn!(site, folder = %folder.display(), "already ingested; not again");
        if let Some(epoch) = earlier {
            restore_orientations(store, site, folder, &hash, epoch, opts).await;
        }
        // The folder says so itself, next to the copy that was ingested in `.done/`.
        let as_epoch = earlier.map_or(String::new(), |e| format!(" as epoch {e}"));
        let dest = move_to(folder, ".done")?;
        write_replacing(
            &dest.join("duplicate.txt"),
            format!(
                "not ingested: a folder with the same files was ingested{as_epoch} before \
                 (same content hash {hash})\n"
            )
            .as_bytes(),
        )?;
        return Ok(dest);
    }
    let (done, done_rel) = done_destination(folder);
    match process(store, site, folder, &hash, &done_rel, opts).await {
        Ok((ing, found)) => {
            save_state(store, site, &hash, ing.epoch, &found)
                .await
                .map_err(std::io::Error::other)?;
            move_folder(folder, done)
        }
        Err(e) if e.is_transient() => {
            tracing::warn!(site, folder = %folder.display(), error = %e,
                "watched folder not taken: the database failed; taken again at the next scan");
            Ok(folder.to_path_buf())
        }
        Err(e) => fail_folder(site, folder, &e.to_string()),
    }
}

/// Moves `folder` to `.failed/` with `reason` in its `error.txt`; returns where it went.
fn fail_folder(site: &str, folder: &Path, reason: &str) -> std::io::Result<PathBuf> {
    tracing::warn!(site, folder = %folder.display(), error = %reason, "watched folder failed");
    // replaces (never writes through) a link or hard link standing at `error.txt`
    write_replacing(&folder.join("error.txt"), format!("{reason}\n").as_bytes())?;
    move_to(folder, ".failed")
}
