//! One station's image of a watched folder: its detection, and the counts and targets of its
//! naming that `identification.json` and the epoch's report keep.

use std::collections::BTreeMap;
use std::path::PathBuf;

use super::image_file::{read_image_file, ImageFileError};
use super::{WatchError, WatchOptions};
use cliffwatch_core::detect::detect_bytes;
use cliffwatch_core::detect::identify::Seed;
use cliffwatch_core::detect::settings::{DetectionSettings, DetectionUsed};
use cliffwatch_core::photogrammetry::input::epoch::{is_valid_identifier, CameraInput, ImageInput};
use cliffwatch_core::photogrammetry::{Camera, EpochError};

/// One station's image after detection.
pub(super) struct StationData {
    /// The station (the image's `station`, else its id).
    pub(super) station: String,
    /// Its camera, from the upload form.
    pub(super) camera: Camera,
    /// The image's file name in the folder.
    pub(super) image_file: String,
    /// Image size in px.
    pub(super) size: (u32, u32),
    /// Detected targets: (col, row) px.
    pub(super) targets: Vec<(f64, f64)>,
    /// Diameters of the detected targets in px.
    pub(super) diameters: Vec<f64>,
    /// σ of each detected target's centre coordinates in px (`Target::sigma_px`).
    pub(super) sigmas_px: Vec<f64>,
    /// The detection settings its image was measured with.
    pub(super) detection: DetectionUsed,
    /// The same in image mm.
    pub(super) blobs: Vec<[f64; 2]>,
    /// The seed observations of `epoch.json` for this station, in image mm.
    pub(super) seeds: Vec<Seed>,
}

/// A station's named detections: (point, detection index).
pub(super) type StationNamed = Vec<(String, usize)>;

/// How a station's targets were named, for the folder's `identification.json`, the epoch's report
/// (the dashboard draws `targets` over the image) and the log.
#[derive(Debug, Clone, serde::Serialize)]
pub(super) struct StationCounts {
    /// The station.
    pub(super) station: String,
    /// How its targets were named (`multi-view from seeds`, `seeds`, `previous orientation`).
    pub(super) method: &'static str,
    /// Targets detected.
    pub(super) detected: usize,
    /// Targets named.
    pub(super) identified: usize,
    /// Targets left out because two names were about equally likely.
    pub(super) ambiguous: usize,
    /// Targets matching no point.
    pub(super) unmatched: usize,
    /// Points named here but in no other station: left out of the epoch (one ray cannot place
    /// them).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub(super) in_one_station_only: Vec<String>,
    /// The folder after ingestion, relative to the site's directory (`.done/<epoch folder>`).
    pub(super) folder: String,
    /// The image's file name in that folder.
    pub(super) image: String,
    /// Image width in px.
    pub(super) width_px: u32,
    /// Image height in px.
    pub(super) height_px: u32,
    /// Every detected target.
    pub(super) targets: Vec<DetectedTarget>,
    /// The detection settings used.
    pub(super) detection: DetectionUsed,
}

/// One detected target of a station's image, as the report keeps it.
#[derive(Debug, Clone, serde::Serialize)]
pub(super) struct DetectedTarget {
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
    pub(super) fn new(
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
            in_one_station_only: Vec::new(),
            folder: String::new(),
            image: s.image_file.clone(),
            width_px: s.size.0,
            height_px: s.size.1,
            targets,
            detection: s.detection.clone(),
        }
    }
}

/// The station of an image of `epoch.json` (its `station`, else its `id`), which names its file:
/// an identifier, never a path (`../x`) out of the folder.
pub(super) fn station_of(image: &ImageInput) -> Result<String, WatchError> {
    let station = image.station.clone().unwrap_or_else(|| image.id.clone());
    if !is_valid_identifier(&station) {
        return Err(WatchError::BadStation(station));
    }
    Ok(station)
}

/// Decodes and searches one station's image, found in `images` (station → file, from
/// [`super::folders::station_images`]), in `spawn_blocking`.
pub(super) async fn detect_station(
    images: &BTreeMap<String, PathBuf>,
    image: &ImageInput,
    cameras: &[CameraInput],
    opts: &WatchOptions,
    detection_from: &[String],
) -> Result<StationData, WatchError> {
    let station = station_of(image)?;
    let cam_err = |reason: String| WatchError::Camera {
        station: station.clone(),
        reason,
    };
    let cam_in = cameras
        .iter()
        .find(|c| c.id == image.camera)
        .ok_or_else(|| cam_err(format!("unknown camera {}", image.camera)))?;
    let camera = Camera::from_input(cam_in).map_err(|e: EpochError| cam_err(e.to_string()))?;
    let path = images
        .get(&station)
        .ok_or_else(|| WatchError::MissingImage(station.clone()))?;
    let file = path
        .file_name()
        .unwrap_or_default()
        .to_string_lossy()
        .into_owned();
    let bytes = read_image_file(path).await.map_err(|e| match e {
        ImageFileError::TooLarge { bytes, max } => WatchError::ImageFileTooLarge {
            station: station.clone(),
            file: file.clone(),
            bytes,
            max,
        },
        ImageFileError::Io(e) => WatchError::Io(e),
    })?;
    let dopts = opts.detect.clone();
    let det = tokio::task::spawn_blocking(move || detect_bytes(&bytes, &dopts))
        .await
        .map_err(|e| WatchError::Task(e.to_string()))?
        .map_err(|source| WatchError::Detect {
            station: station.clone(),
            file: file.clone(),
            source,
        })?;
    let detection = DetectionSettings::used(&opts.detect, det.polarity, detection_from.to_vec());
    if det.targets.is_empty() {
        return Err(WatchError::NoTargets {
            station,
            file,
            polarity: detection.polarity.as_str(),
            min_diameter_px: detection.min_diameter_px,
            max_diameter_px: detection.max_diameter_px,
        });
    }
    // The image must be the size the camera declares: the image centre, and so every
    // coordinate in mm, comes from the declared size (a portrait or downscaled export would
    // shift or scale all of them without a word).
    if let (Some(w), Some(h)) = (cam_in.width_px, cam_in.height_px) {
        if (w, h) != (det.width, det.height) {
            return Err(cam_err(format!(
                "the image is {} × {} px, camera {} declares {w} × {h} px",
                det.width, det.height, cam_in.id
            )));
        }
    }
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
        image_file: file,
        size: (det.width, det.height),
        targets: det.targets.iter().map(|t| (t.col, t.row)).collect(),
        diameters: det.targets.iter().map(|t| t.diameter_px).collect(),
        sigmas_px: det.targets.iter().map(|t| t.sigma_px).collect(),
        detection,
        blobs,
        seeds,
    })
}
