//! A site's current camera network for its pre-analysis (`service::plan`): the latest epoch's
//! cameras, images and kept observations (as uploaded), its adjusted coordinates and datum, and
//! the site's stable points.

use serde_json::Value;
use sqlx::{AnyConnection, FromRow};

use super::points::{self, StoredCoordinate};
use super::StoreError;
use cliffwatch_core::photogrammetry::input::epoch::{CameraInput, ImageInput, ObservationInput};

/// The latest epoch of a site as its network.
#[derive(Debug, Clone)]
pub struct StoredNetwork {
    /// Epoch id.
    pub epoch: i64,
    /// Observation time (store format).
    pub observed_at: String,
    /// The epoch's cameras (upload form, as stored with the epoch).
    pub cameras: Vec<CameraInput>,
    /// The epoch's images with the observations its adjustment kept (dropped ones left out).
    pub images: Vec<ImageInput>,
    /// The epoch's adjusted coordinates (m) with their covariance (m²).
    pub coordinates: Vec<StoredCoordinate>,
    /// The epoch's datum as its report states it (`control points` or `free network …`).
    pub datum: String,
    /// The a-posteriori variance factor of the epoch's adjustment (None when not finite).
    pub variance_factor: Option<f64>,
    /// The observations were deleted by retention (`observation_retention_days`).
    pub pruned: bool,
    /// The site's stable points.
    pub stable: Vec<String>,
}

#[derive(FromRow)]
struct EpochRow {
    id: i64,
    observed_at: String,
    cameras: String,
    report: String,
    variance_factor: Option<f64>,
    observations_pruned_at: Option<String>,
}

#[derive(FromRow)]
struct ObservationRow {
    image_id: String,
    camera: String,
    station: String,
    point: String,
    x_mm: Option<f64>,
    y_mm: Option<f64>,
    col_px: Option<f64>,
    row_px: Option<f64>,
}

/// The site's latest epoch (by observation time) as its network; None when it has no epoch.
pub async fn latest(
    db: &mut AnyConnection,
    site: &str,
) -> Result<Option<StoredNetwork>, StoreError> {
    let row: Option<EpochRow> = sqlx::query_as(
        "SELECT id, observed_at, cameras, report, variance_factor, observations_pruned_at \
         FROM epochs WHERE site_id = $1 ORDER BY observed_at DESC LIMIT 1",
    )
    .bind(site)
    .fetch_optional(&mut *db)
    .await?;
    let Some(row) = row else {
        return Ok(None);
    };
    let cameras: Vec<CameraInput> = serde_json::from_str(&row.cameras)?;
    let report: Value = serde_json::from_str(&row.report)?;
    let datum = report
        .get("datum")
        .and_then(Value::as_str)
        .unwrap_or_default()
        .to_string();
    let rows: Vec<ObservationRow> = sqlx::query_as(
        "SELECT o.image_id, i.camera, i.station, o.point, o.x_mm, o.y_mm, o.col_px, o.row_px \
         FROM observations o JOIN images i \
         ON i.site_id = o.site_id AND i.epoch_id = o.epoch_id AND i.id = o.image_id \
         WHERE o.site_id = $1 AND o.epoch_id = $2 AND CAST(o.dropped AS INTEGER) = 0 \
         ORDER BY i.seq, o.seq",
    )
    .bind(site)
    .bind(row.id)
    .fetch_all(&mut *db)
    .await?;
    let mut images: Vec<ImageInput> = Vec::new();
    for r in rows {
        if images.last().is_none_or(|i| i.id != r.image_id) {
            images.push(ImageInput {
                id: r.image_id.clone(),
                camera: r.camera.clone(),
                station: Some(r.station.clone()),
                observations: Vec::new(),
            });
        }
        if let Some(image) = images.last_mut() {
            image.observations.push(ObservationInput {
                point: r.point,
                x_mm: r.x_mm,
                y_mm: r.y_mm,
                col: r.col_px,
                row: r.row_px,
                sigma_mm: None,
            });
        }
    }
    Ok(Some(StoredNetwork {
        epoch: row.id,
        observed_at: row.observed_at,
        cameras,
        images,
        coordinates: points::epoch_coordinates(&mut *db, site, row.id).await?,
        datum,
        variance_factor: row.variance_factor.filter(|v| v.is_finite()),
        pruned: row.observations_pruned_at.is_some(),
        stable: points::stable(&mut *db, site).await?,
    }))
}
