//! The watched directory of the contract: `<watch_dir>/<site>/<epoch>/` holds one image per station
//! (`<station>.jpg|.png|.tif`) and an `epoch.json` in the upload form; the folder is taken when `READY`
//! appears. Each image is decoded and searched for targets (in `spawn_blocking`). The targets are
//! identified: stations with ≥ 4 seed observations in `epoch.json` together, by multi-view matching
//! that needs the approximations only to name the targets ([`crate::detect::first_epoch`]; a station
//! seeded alone, or stations that do not share 4 seeded targets, from their own seeds,
//! [`crate::detect::identify`]); stations without seeds from the orientation the watcher kept from
//! their previous epoch. The epoch is ingested exactly as an upload
//! ([`crate::service::ingest::ingest_with_identification`]: the counts below are stored with its report),
//! and the stations' orientations for the next epoch are resected from its adjusted coordinates.
//! The folder then moves to `<site>/.done/` with `identification.json` (per station: method,
//! detected, identified, ambiguous, unmatched, where the image is kept and every detection with its
//! name, which the report keeps too, so the dashboard can draw them over the image) or, with
//! `error.txt`, to `<site>/.failed/`;
//! when too few targets can be named, `error.txt` gives the same counts, the likely cause and what
//! to add. A folder whose content hash (sha256 of its files' names and bytes, the watcher's own
//! outputs excluded) is in the database ([`crate::store::watch_state`]) is never ingested
//! again; the stations' orientations are kept there too, so the state is backed up and restored with
//! the database. (Files `<site>/.state/ingested` and `<site>/.state/orientations.json` of earlier
//! versions are still read, never written.) The state is written after the epoch's own transaction:
//! when the daemon dies in between, the folder is taken again on restart and ingestion recognises
//! the identical upload (same body hash), so it still becomes one epoch.
//!
//! Watching: `notify` events and a periodic rescan (events can be lost, e.g. on network shares).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Duration;

use sha2::{Digest, Sha256};

use crate::detect::first_epoch::{
    identify_first_epoch, FirstEpochError, FirstEpochOptions, StationView,
};
use crate::detect::identify::{
    identify, resect_seeds, IdentifyError, IdentifyOptions, Prior, Seed,
};
use crate::detect::{detect_bytes, DetectError, DetectOptions};
use crate::photogrammetry::input::epoch::ObservationInput;
use crate::photogrammetry::{Camera, EpochError, EpochInput, ImageOrientation};
use crate::service::ingest::{ingest_with_identification, Ingested};
use crate::service::ServiceError;
use crate::shutdown::Shutdown;
use crate::store::{points, watch_state, Store, StoreError};

/// Why a watched folder failed (written to its `error.txt`).
#[derive(Debug, thiserror::Error)]
pub enum WatchError {
    /// Reading or moving files failed.
    #[error("file system: {0}")]
    Io(#[from] std::io::Error),
    /// `epoch.json` is not the upload form.
    #[error("epoch.json: {0}")]
    Json(#[from] serde_json::Error),
    /// An image of `epoch.json` has no file.
    #[error("no image file <{0}>.jpg|.png|.tif for station {0}")]
    MissingImage(String),
    /// A camera is invalid or lacks pixel size and image size.
    #[error("camera of station {station}: {reason}")]
    Camera {
        /// Station.
        station: String,
        /// Why.
        reason: String,
    },
    /// Detection failed.
    #[error("detection on station {station}: {source}")]
    Detect {
        /// Station.
        station: String,
        /// Cause.
        source: DetectError,
    },
    /// Identification failed.
    #[error("identification on station {station}: {source}")]
    Identify {
        /// Station.
        station: String,
        /// Cause.
        source: IdentifyError,
    },
    /// Multi-view identification of a first epoch failed.
    #[error("identification: {0}")]
    FirstEpoch(FirstEpochError),
    /// Too few targets could be named; the message names the stations, the cause and what to add.
    #[error("{0}")]
    Unidentified(String),
    /// A station seen for the first time without ≥ 4 seed observations.
    #[error("station {0} has no previous orientation and fewer than 4 seed observations")]
    NoPrior(String),
    /// Ingestion refused the epoch.
    #[error("ingestion: {0}")]
    Ingest(#[from] ServiceError),
    /// The blocking task panicked.
    #[error("detection task failed: {0}")]
    Task(String),
}

/// Options of the watcher.
#[derive(Debug, Clone)]
pub struct WatchOptions {
    /// The watched directory.
    pub dir: PathBuf,
    /// Period of the rescan.
    pub rescan: Duration,
    /// Detection options.
    pub detect: DetectOptions,
    /// Identification options (a station from its previous orientation, or alone from its seeds).
    pub identify: IdentifyOptions,
    /// Multi-view identification options (stations of a first epoch, from their seeds).
    pub first_epoch: FirstEpochOptions,
}

impl WatchOptions {
    /// Defaults for `dir`: rescan every 30 s.
    pub fn new(dir: PathBuf) -> Self {
        Self {
            dir,
            rescan: Duration::from_secs(30),
            detect: DetectOptions::default(),
            identify: IdentifyOptions::default(),
            first_epoch: FirstEpochOptions::default(),
        }
    }
}

const IMAGE_EXTENSIONS: [&str; 6] = ["jpg", "jpeg", "png", "tif", "tiff", "JPG"];

/// Folders `<dir>/<site>/<epoch>/` holding `READY` (names starting with `.` skipped), sorted.
pub fn ready_folders(dir: &Path) -> Vec<(String, PathBuf)> {
    let mut out = Vec::new();
    let Ok(sites) = std::fs::read_dir(dir) else {
        return out;
    };
    for site in sites.flatten() {
        let name = site.file_name().to_string_lossy().into_owned();
        if name.starts_with('.') || !site.path().is_dir() {
            continue;
        }
        let Ok(epochs) = std::fs::read_dir(site.path()) else {
            continue;
        };
        for e in epochs.flatten() {
            let en = e.file_name().to_string_lossy().into_owned();
            if !en.starts_with('.') && e.path().join("READY").is_file() {
                out.push((name.clone(), e.path()));
            }
        }
    }
    out.sort();
    out
}

/// Files the watcher writes into a folder (not part of its content).
const OUTPUT_FILES: [&str; 3] = ["READY", "error.txt", "identification.json"];

/// sha256 (hex) over the sorted names and bytes of the folder's files (`READY` and the watcher's own
/// outputs excluded).
pub fn content_hash(folder: &Path) -> std::io::Result<String> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(folder)?
        .flatten()
        .map(|e| e.path())
        .filter(|p| {
            p.is_file()
                && p.file_name()
                    .is_some_and(|n| !OUTPUT_FILES.iter().any(|o| n == *o))
        })
        .collect();
    files.sort();
    let mut h = Sha256::new();
    for f in files {
        h.update(f.file_name().unwrap_or_default().as_encoded_bytes());
        h.update([0]);
        h.update(std::fs::read(&f)?);
    }
    Ok(hex::encode(h.finalize()))
}

fn state_dir(site_dir: &Path) -> PathBuf {
    site_dir.join(".state")
}

/// Orientations from the file of earlier versions (`<site>/.state/orientations.json`), if any.
fn legacy_orientations(site_dir: &Path) -> BTreeMap<String, ImageOrientation> {
    std::fs::read_to_string(state_dir(site_dir).join("orientations.json"))
        .ok()
        .and_then(|s| serde_json::from_str::<BTreeMap<String, StoredOrientation>>(&s).ok())
        .map(|m| {
            m.into_iter()
                .map(|(k, v)| (k, v.into_orientation()))
                .collect()
        })
        .unwrap_or_default()
}

/// The stations' orientations: the database's, else the legacy file's.
async fn load_orientations(
    store: &Store,
    site: &str,
    site_dir: &Path,
) -> Result<BTreeMap<String, ImageOrientation>, StoreError> {
    let mut all = legacy_orientations(site_dir);
    all.extend(watch_state::orientations(store.reader(), site).await?);
    Ok(all)
}

#[derive(serde::Deserialize)]
struct StoredOrientation {
    camera: String,
    rotation: [[f64; 3]; 3],
    center: [f64; 3],
}

impl StoredOrientation {
    fn into_orientation(self) -> ImageOrientation {
        ImageOrientation {
            image: String::new(),
            station: String::new(),
            camera: self.camera,
            rotation: self.rotation,
            center: self.center,
        }
    }
}

/// Where `folder` would move in `<site>/<sub>/`: its own name, or `<name>.<k>` when that is taken.
fn free_destination(folder: &Path, sub: &str) -> PathBuf {
    let site_dir = folder.parent().unwrap_or(Path::new("."));
    let dest_dir = site_dir.join(sub);
    let name = folder
        .file_name()
        .unwrap_or_default()
        .to_string_lossy()
        .into_owned();
    let mut dest = dest_dir.join(&name);
    let mut k = 1;
    while dest.exists() {
        dest = dest_dir.join(format!("{name}.{k}"));
        k += 1;
    }
    dest
}

/// Moves `folder` to `dest` (a [`free_destination`]), or to the next free name when `dest` was taken
/// in the meantime.
fn move_folder(folder: &Path, dest: PathBuf) -> std::io::Result<PathBuf> {
    let sub = dest
        .parent()
        .and_then(Path::file_name)
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let dest = if dest.exists() {
        free_destination(folder, &sub)
    } else {
        dest
    };
    if let Some(dir) = dest.parent() {
        std::fs::create_dir_all(dir)?;
    }
    std::fs::rename(folder, &dest)?;
    Ok(dest)
}

/// Moves `folder` into `<site>/<sub>/`, with a numeric suffix when the name is taken.
fn move_to(folder: &Path, sub: &str) -> std::io::Result<PathBuf> {
    move_folder(folder, free_destination(folder, sub))
}

fn find_image(folder: &Path, station: &str) -> Option<PathBuf> {
    IMAGE_EXTENSIONS
        .iter()
        .map(|e| folder.join(format!("{station}.{e}")))
        .find(|p| p.is_file())
}

/// One station's image after detection.
struct StationData {
    station: String,
    camera: Camera,
    /// The image's file name in the folder.
    image_file: String,
    /// Image size in px.
    size: (u32, u32),
    /// Detected targets: (col, row) px.
    targets: Vec<(f64, f64)>,
    /// Diameters of the detected targets in px.
    diameters: Vec<f64>,
    /// The same in image mm.
    blobs: Vec<[f64; 2]>,
    seeds: Vec<Seed>,
}

/// A station's named detections: (point, detection index).
type StationNamed = Vec<(String, usize)>;

/// How a station's targets were named, for the folder's `identification.json`, the epoch's report
/// (the dashboard draws `targets` over the image) and the log.
#[derive(Debug, Clone, serde::Serialize)]
struct StationCounts {
    station: String,
    method: &'static str,
    detected: usize,
    identified: usize,
    ambiguous: usize,
    unmatched: usize,
    /// The folder after ingestion, relative to the site's directory (`.done/<epoch folder>`).
    folder: String,
    /// The image's file name in that folder.
    image: String,
    /// Image width in px.
    width_px: u32,
    /// Image height in px.
    height_px: u32,
    /// Every detected target.
    targets: Vec<DetectedTarget>,
}

/// One detected target of a station's image, as the report keeps it.
#[derive(Debug, Clone, serde::Serialize)]
struct DetectedTarget {
    /// Centre column in px (0.01 px).
    col: f64,
    /// Centre row in px (0.01 px).
    row: f64,
    /// Equivalent diameter in px (0.1 px).
    diameter_px: f64,
    /// The point it was named, when identified.
    #[serde(skip_serializing_if = "Option::is_none")]
    point: Option<String>,
    /// `identified`, `ambiguous` or `unmatched`.
    status: &'static str,
}

impl StationCounts {
    /// The counts and targets of station `s` from its named detections and the indices of the
    /// ambiguous and unmatched ones.
    fn new(
        s: &StationData,
        method: &'static str,
        named: &StationNamed,
        ambiguous: &[usize],
        unmatched: &[usize],
    ) -> Self {
        let round = |v: f64, k: f64| (v * k).round() / k;
        let targets = s
            .targets
            .iter()
            .zip(&s.diameters)
            .enumerate()
            .map(|(i, (&(col, row), &d))| {
                let point = named.iter().find(|(_, b)| *b == i).map(|(p, _)| p.clone());
                let status = if point.is_some() {
                    "identified"
                } else if ambiguous.contains(&i) {
                    "ambiguous"
                } else {
                    "unmatched"
                };
                DetectedTarget {
                    col: round(col, 100.0),
                    row: round(row, 100.0),
                    diameter_px: round(d, 10.0),
                    point,
                    status,
                }
            })
            .collect();
        StationCounts {
            station: s.station.clone(),
            method,
            detected: s.blobs.len(),
            identified: named.len(),
            ambiguous: ambiguous.len(),
            unmatched: unmatched.len(),
            folder: String::new(),
            image: s.image_file.clone(),
            width_px: s.size.0,
            height_px: s.size.1,
            targets,
        }
    }
}

/// Decodes and searches one station's image (in `spawn_blocking`).
async fn detect_station(
    folder: &Path,
    image: &crate::photogrammetry::input::epoch::ImageInput,
    cameras: &[crate::photogrammetry::input::epoch::CameraInput],
    opts: &WatchOptions,
) -> Result<StationData, WatchError> {
    let station = image.station.clone().unwrap_or_else(|| image.id.clone());
    let cam_err = |reason: String| WatchError::Camera {
        station: station.clone(),
        reason,
    };
    let cam_in = cameras
        .iter()
        .find(|c| c.id == image.camera)
        .ok_or_else(|| cam_err(format!("unknown camera {}", image.camera)))?;
    let camera = Camera::from_input(cam_in).map_err(|e: EpochError| cam_err(e.to_string()))?;
    let path =
        find_image(folder, &station).ok_or_else(|| WatchError::MissingImage(station.clone()))?;
    let bytes = tokio::fs::read(&path).await?;
    let dopts = opts.detect.clone();
    let det = tokio::task::spawn_blocking(move || detect_bytes(&bytes, &dopts))
        .await
        .map_err(|e| WatchError::Task(e.to_string()))?
        .map_err(|source| WatchError::Detect {
            station: station.clone(),
            source,
        })?;
    let mut blobs = Vec::with_capacity(det.targets.len());
    for t in &det.targets {
        blobs.push(
            t.image_mm(&camera)
                .ok_or_else(|| cam_err("pixel size and image size are needed".into()))?,
        );
    }
    let seeds = image
        .observations
        .iter()
        .filter_map(|o| {
            let xy = match (o.x_mm, o.y_mm, o.col, o.row) {
                (Some(x), Some(y), _, _) => Some([x, y]),
                (_, _, Some(c), Some(r)) => camera.pixel_to_mm(c, r),
                _ => None,
            }?;
            Some(Seed {
                point: o.point.clone(),
                xy_mm: xy,
            })
        })
        .collect();
    Ok(StationData {
        station,
        camera,
        image_file: path
            .file_name()
            .unwrap_or_default()
            .to_string_lossy()
            .into_owned(),
        size: (det.width, det.height),
        targets: det.targets.iter().map(|t| (t.col, t.row)).collect(),
        diameters: det.targets.iter().map(|t| t.diameter_px).collect(),
        blobs,
        seeds,
    })
}

/// Names the detections of every station: stations with ≥ 4 seeds together by multi-view matching
/// ([`identify_first_epoch`]) when there are at least 2 of them and they share 4 seeded targets,
/// otherwise each from its seeds; stations without seeds from their previous orientation. Returns
/// per station the (point, detection index) pairs and the counts.
fn name_targets(
    stations: &[StationData],
    known: &BTreeMap<String, [f64; 3]>,
    previous: &BTreeMap<String, ImageOrientation>,
    opts: &WatchOptions,
) -> Result<(Vec<StationNamed>, Vec<StationCounts>), WatchError> {
    let mut names: Vec<StationNamed> = vec![Vec::new(); stations.len()];
    let mut counts: Vec<Option<StationCounts>> = vec![None; stations.len()];
    let seeded: Vec<usize> = (0..stations.len())
        .filter(|&k| stations[k].seeds.len() >= 4)
        .collect();
    if seeded.len() >= 2 {
        let views: Vec<StationView> = seeded
            .iter()
            .map(|&k| StationView {
                station: &stations[k].station,
                blobs_mm: &stations[k].blobs,
                seeds: &stations[k].seeds,
            })
            .collect();
        match identify_first_epoch(&views, known, &opts.first_epoch) {
            Ok(first) => {
                if let Some(msg) = first.refusal() {
                    return Err(WatchError::Unidentified(msg));
                }
                for (r, &k) in first.stations.iter().zip(&seeded) {
                    names[k] = r
                        .matched
                        .iter()
                        .map(|m| (m.point.clone(), m.blob))
                        .collect();
                    counts[k] = Some(StationCounts::new(
                        &stations[k],
                        "multi-view from seeds",
                        &names[k],
                        &r.ambiguous_blobs,
                        &r.unmatched_blobs,
                    ));
                }
            }
            Err(FirstEpochError::TooFewCommonSeeds { .. }) => {
                tracing::info!(
                    "stations seed different targets; each is identified from its own seeds"
                );
            }
            Err(e) => return Err(WatchError::FirstEpoch(e)),
        }
    }
    for (k, s) in stations.iter().enumerate() {
        if counts[k].is_some() {
            continue;
        }
        let (prior, method) = if s.seeds.len() >= 4 {
            (Prior::Seeds(&s.seeds), "seeds")
        } else if let Some(o) = previous.get(&s.station) {
            (Prior::Orientation(o), "previous orientation")
        } else {
            return Err(WatchError::NoPrior(s.station.clone()));
        };
        let id = identify(&s.blobs, known, &s.camera, prior, &opts.identify).map_err(|source| {
            WatchError::Identify {
                station: s.station.clone(),
                source,
            }
        })?;
        names[k] = id
            .matched
            .iter()
            .map(|m| (m.point.clone(), m.blob))
            .collect();
        counts[k] = Some(StationCounts::new(
            s,
            method,
            &names[k],
            &id.ambiguous_blobs,
            &id.unmatched_blobs,
        ));
    }
    Ok((names, counts.into_iter().flatten().collect()))
}

/// Detects, identifies and ingests one folder (does not move it; writes its `identification.json`).
/// `done` is where the folder will move, relative to the site's directory (kept in the report so the
/// dashboard finds the images). Returns the ingestion and the orientations found per station
/// (resected from the epoch's adjusted coordinates).
async fn process(
    store: &Store,
    site: &str,
    folder: &Path,
    done: &str,
    opts: &WatchOptions,
) -> Result<(Ingested, BTreeMap<String, ImageOrientation>), WatchError> {
    let site_dir = folder.parent().unwrap_or(Path::new("."));
    let mut input: EpochInput =
        serde_json::from_str(&tokio::fs::read_to_string(folder.join("epoch.json")).await?)?;
    // known points: the site's latest coordinates, then the upload's control and approximations
    let mut known: BTreeMap<String, [f64; 3]> = BTreeMap::new();
    for a in &input.approx {
        known.insert(a.point.clone(), [a.X, a.Y, a.Z]);
    }
    for c in &input.control {
        known.insert(c.point.clone(), [c.X, c.Y, c.Z]);
    }
    let stored = match store.read().await {
        Ok(mut db) => points::latest_coordinates(&mut db, site).await,
        Err(e) => Err(e),
    };
    if let Ok(stored) = stored {
        for c in stored {
            known.insert(c.point, c.xyz);
        }
    }
    let previous = load_orientations(store, site, site_dir)
        .await
        .map_err(|e| WatchError::Io(std::io::Error::other(e)))?;
    let mut stations = Vec::with_capacity(input.images.len());
    for image in &input.images {
        stations.push(detect_station(folder, image, &input.cameras, opts).await?);
    }
    let (names, mut counts) = name_targets(&stations, &known, &previous, opts)?;
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
    tokio::fs::write(
        folder.join("identification.json"),
        serde_json::to_string_pretty(&counts)?,
    )
    .await?;
    for ((image, s), named) in input.images.iter_mut().zip(&stations).zip(&names) {
        image.observations = named
            .iter()
            .map(|(point, blob)| ObservationInput {
                point: point.clone(),
                x_mm: None,
                y_mm: None,
                col: Some(s.targets[*blob].0),
                row: Some(s.targets[*blob].1),
            })
            .collect();
    }
    let ingested =
        ingest_with_identification(store, site, input, Some(serde_json::to_value(&counts)?))
            .await?;
    // the stations' orientations for the next epoch, from this epoch's adjusted coordinates
    let mut db = store
        .read()
        .await
        .map_err(|e| WatchError::Io(std::io::Error::other(e)))?;
    let adjusted: BTreeMap<String, [f64; 3]> = points::latest_coordinates(&mut db, site)
        .await
        .map_err(|e| WatchError::Io(std::io::Error::other(e)))?
        .into_iter()
        .map(|c| (c.point, c.xyz))
        .collect();
    drop(db);
    let mut found = BTreeMap::new();
    for (s, named) in stations.iter().zip(&names) {
        let measured: Vec<Seed> = named
            .iter()
            .filter(|(p, _)| adjusted.contains_key(p))
            .map(|(p, blob)| Seed {
                point: p.clone(),
                xy_mm: s.blobs[*blob],
            })
            .collect();
        match resect_seeds(&measured, &adjusted, &s.camera) {
            Ok((o, _)) => {
                found.insert(s.station.clone(), o);
            }
            Err(e) => tracing::warn!(site, station = s.station, error = %e, "no orientation kept"),
        }
    }
    Ok((ingested, found))
}

/// Takes one ready folder: skips it when its hash was ingested before, otherwise processes it; moves it
/// to `.done/` or `.failed/` (with `error.txt`). Returns the destination.
pub async fn take_folder(
    store: &Store,
    site: &str,
    folder: &Path,
    opts: &WatchOptions,
) -> std::io::Result<PathBuf> {
    let site_dir = folder.parent().unwrap_or(Path::new(".")).to_path_buf();
    let hash = content_hash(folder)?;
    let legacy = std::fs::read_to_string(state_dir(&site_dir).join("ingested")).unwrap_or_default();
    let seen = watch_state::folder_epoch(store.reader(), site, &hash)
        .await
        .map_err(std::io::Error::other)?
        .is_some()
        || legacy
            .lines()
            .any(|l| l.split_whitespace().next() == Some(hash.as_str()));
    if seen {
        tracing::warn!(site, folder = %folder.display(), "already ingested; not again");
        return move_to(folder, ".done");
    }
    let done = free_destination(folder, ".done");
    let done_rel = format!(
        ".done/{}",
        done.file_name().unwrap_or_default().to_string_lossy()
    );
    match process(store, site, folder, &done_rel, opts).await {
        Ok((ing, found)) => {
            save_state(store, site, &hash, ing.epoch, &found)
                .await
                .map_err(std::io::Error::other)?;
            move_folder(folder, done)
        }
        Err(e) => {
            tracing::warn!(site, folder = %folder.display(), error = %e, "watched folder failed");
            std::fs::write(folder.join("error.txt"), format!("{e}\n"))?;
            move_to(folder, ".failed")
        }
    }
}

/// Records the folder's hash and the stations' orientations in one transaction.
async fn save_state(
    store: &Store,
    site: &str,
    hash: &str,
    epoch: i64,
    found: &BTreeMap<String, ImageOrientation>,
) -> Result<(), StoreError> {
    let mut tx = store.begin_write_site(site).await?;
    for (station, o) in found {
        watch_state::set_orientation(&mut tx, site, station, o, epoch).await?;
    }
    watch_state::record_folder(&mut tx, site, hash, epoch).await?;
    tx.commit().await?;
    Ok(())
}

/// Takes every ready folder once (sequentially). Several nodes may watch one shared directory:
/// each folder is claimed ([`Store::try_job_lock`] on its site and name) and held until it has
/// moved to `.done/` or `.failed/`; a folder another node holds, or has already moved, is left.
pub async fn scan_once(store: &Store, opts: &WatchOptions) -> Vec<std::io::Result<PathBuf>> {
    let mut out = Vec::new();
    for (site, folder) in ready_folders(&opts.dir) {
        let name = folder.file_name().unwrap_or_default().to_string_lossy();
        let claim = match store.try_job_lock(&format!("watch {site}/{name}")).await {
            Ok(Some(claim)) => claim,
            Ok(None) => continue,
            Err(e) => {
                out.push(Err(std::io::Error::other(e)));
                continue;
            }
        };
        if folder.is_dir() {
            out.push(take_folder(store, &site, &folder, opts).await);
        }
        drop(claim);
    }
    out
}

/// Watches `opts.dir` until shutdown: a scan at start, on every file-system event and every
/// `opts.rescan`.
pub async fn run(store: Store, opts: WatchOptions, shutdown: Shutdown) -> Result<(), WatchError> {
    use notify::Watcher;
    let (tx, mut rx) = tokio::sync::mpsc::channel::<()>(16);
    let mut watcher = notify::recommended_watcher(move |_res: notify::Result<notify::Event>| {
        let _ = tx.try_send(());
    })
    .map_err(|e| WatchError::Io(std::io::Error::other(e)))?;
    if let Err(e) = watcher.watch(&opts.dir, notify::RecursiveMode::Recursive) {
        tracing::warn!(error = %e, "file-system events unavailable; rescanning only");
    }
    let mut tick = tokio::time::interval(opts.rescan);
    loop {
        tokio::select! {
            _ = shutdown.requested() => return Ok(()),
            _ = tick.tick() => {}
            Some(()) = rx.recv() => {
                // let the writer finish its burst of events
                tokio::time::sleep(Duration::from_millis(200)).await;
                while rx.try_recv().is_ok() {}
            }
        }
        for r in scan_once(&store, &opts).await {
            if let Err(e) = r {
                tracing::warn!(error = %e, "watched folder could not be moved");
            }
        }
    }
}
