//! Epochs with their images, observations (as given, with residuals), adjusted coordinates with
//! covariance and the joint covariance of the stable points.

use std::collections::HashMap;

use chrono::{DateTime, Utc};
use serde::Serialize;
use serde_json::Value;
use sqlx::{AnyConnection, AnyExecutor, FromRow};
use utoipa::ToSchema;

use super::epoch_report::EpochReport;
use super::{display_timestamp, timestamp, StoreError};
use cliffwatch_core::photogrammetry::input::epoch::ImageInput;
use cliffwatch_core::photogrammetry::statistics::variance_components::PooledSigma;
use cliffwatch_core::photogrammetry::{Adjustment, EpochInput, Model};

/// What ingestion hands to [`insert`]: the parsed upload and its adjustment.
#[derive(Debug)]
pub struct EpochRecord<'a> {
    /// Site id.
    pub site: &'a str,
    /// Observation time in the store's format ([`super::timestamp`]).
    pub observed_at: &'a str,
    /// sha256 (hex) of the canonical JSON of the upload.
    pub body_sha256: &'a str,
    /// The upload.
    pub input: &'a EpochInput,
    /// Its adjustment.
    pub adjustment: &'a Adjustment,
    /// Points seen for the first time get the role `stable` when they are in this set (control).
    pub control_points: &'a [String],
    /// Watched epochs: per station, how its targets were identified (stored in the report as
    /// `identification`).
    pub identification: Option<&'a serde_json::Value>,
    /// The cameras' σ estimated from earlier epochs that the adjustment used (stored in the
    /// report as `apriori_sigma_estimated`).
    pub apriori_sigma_estimated: Option<&'a [PooledSigma]>,
    /// When the epoch was stored: the time of its transaction on the store's clock
    /// ([`super::clock`]), shared with the rows the same transaction writes.
    pub created_at: DateTime<Utc>,
}

/// What became of a stored epoch.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum EpochStatus {
    /// Adjusted, and its displacements analysed.
    Adjusted,
    /// Adjusted, but the displacement analysis failed (the reason is the report's
    /// `analysis_error`).
    AnalysisFailed,
}

cliffwatch_core::contract_names!(EpochStatus, "epoch status" {
    Adjusted => "adjusted",
    AnalysisFailed => "analysis_failed",
});

/// One line of the epoch list.
#[derive(Debug, Clone, Serialize, FromRow, ToSchema)]
pub struct EpochListItem {
    /// Integer id, unique within the site.
    pub id: i64,
    /// Observation time (RFC 3339).
    pub observed_at: String,
    /// Label of the upload.
    pub label: Option<String>,
    /// What became of it.
    #[sqlx(try_from = "String")]
    pub status: EpochStatus,
    /// Projection model.
    #[sqlx(try_from = "String")]
    pub model: Model,
    /// A-posteriori σ0 in image mm.
    pub sigma0_mm: f64,
    /// Principal distance of the first camera in mm.
    pub c_mm: Option<f64>,
    /// Its σ in mm (None when fixed).
    pub c_sigma_mm: Option<f64>,
    /// Iterations of the adjustment.
    pub iterations: i64,
    /// Observations dropped by data snooping (listed with their w in the epoch's report).
    pub dropped_observations: i64,
    /// Time of ingestion (RFC 3339).
    pub created_at: String,
    /// When the observation retention deleted the epoch's observations (image coordinates and
    /// residuals; RFC 3339), null while they are kept. The adjustment report, coordinates,
    /// covariances and displacements stay.
    pub observations_pruned_at: Option<String>,
    /// The adjustment's variance factor (σ̂0 / a-priori σ)², dimensionless.
    pub variance_factor: Option<f64>,
    /// Its degrees of freedom (redundancy).
    pub dof: Option<i64>,
}

impl EpochListItem {
    /// The item as read, its times (store form) in the API's form ([`display_timestamp`]).
    fn displayed(mut self) -> EpochListItem {
        self.observed_at = display_timestamp(&self.observed_at);
        self.created_at = display_timestamp(&self.created_at);
        self.observations_pruned_at = self
            .observations_pruned_at
            .as_deref()
            .map(display_timestamp);
        self
    }
}

/// Identity of a stored epoch: id and body hash.
#[derive(Debug, Clone, FromRow)]
pub struct EpochKey {
    /// Integer id.
    pub id: i64,
    /// sha256 (hex) of the canonical body.
    pub body_sha256: String,
}

/// Finds the epoch of a site with that observation time (store format).
pub async fn find_by_time(
    db: impl AnyExecutor<'_>,
    site: &str,
    observed_at: &str,
) -> Result<Option<EpochKey>, StoreError> {
    Ok(
        sqlx::query_as(
            "SELECT id, body_sha256 FROM epochs WHERE site_id = $1 AND observed_at = $2",
        )
        .bind(site)
        .bind(observed_at)
        .fetch_optional(db)
        .await?,
    )
}

/// Lists epochs newest first (by observation time); `before` is the observation time (store
/// format) of the last item of the previous page.
pub async fn list(
    db: impl AnyExecutor<'_>,
    site: &str,
    before: Option<&str>,
    limit: i64,
) -> Result<Vec<(String, EpochListItem)>, StoreError> {
    let rows: Vec<EpochListItem> = sqlx::query_as(
        "SELECT id, observed_at, label, status, model, sigma0_mm, c_mm, c_sigma_mm, iterations, dropped_observations, created_at, \
         observations_pruned_at, variance_factor, dof FROM epochs WHERE site_id = $1 AND observed_at < $2 \
         ORDER BY observed_at DESC LIMIT $3",
    )
    .bind(site)
    // A range from the cursor (or from the end) that the index on (site_id, observed_at) reads
    // directly, however deep the page.
    .bind(before.unwrap_or(super::TEXT_MAX))
    .bind(limit)
    .fetch_all(db)
    .await?;
    Ok(rows
        .into_iter()
        .map(|r| (r.observed_at.clone(), r.displayed()))
        .collect())
}

/// Number of epochs of a site.
pub async fn count(db: impl AnyExecutor<'_>, site: &str) -> Result<i64, StoreError> {
    Ok(
        sqlx::query_scalar("SELECT COUNT(*) FROM epochs WHERE site_id = $1")
            .bind(site)
            .fetch_one(db)
            .await?,
    )
}

/// The stored header of one epoch: list fields plus the report (without residuals).
pub async fn get(
    db: impl AnyExecutor<'_>,
    site: &str,
    id: i64,
) -> Result<Option<(EpochListItem, EpochReport)>, StoreError> {
    #[derive(FromRow)]
    struct Row {
        #[sqlx(flatten)]
        item: EpochListItem,
        report: String,
    }
    let row: Option<Row> = sqlx::query_as(
        "SELECT id, observed_at, label, status, model, sigma0_mm, c_mm, c_sigma_mm, iterations, dropped_observations, created_at, \
         observations_pruned_at, variance_factor, dof, report \
         FROM epochs WHERE site_id = $1 AND id = $2",
    )
    .bind(site)
    .bind(id)
    .fetch_optional(db)
    .await?;
    match row {
        None => Ok(None),
        Some(r) => {
            let report: EpochReport = serde_json::from_str(&r.report)?;
            Ok(Some((r.item.displayed(), report)))
        }
    }
}

/// Raw observation time (store format) of an epoch.
pub async fn observed_at_raw(
    db: impl AnyExecutor<'_>,
    site: &str,
    id: i64,
) -> Result<Option<String>, StoreError> {
    Ok(
        sqlx::query_scalar("SELECT observed_at FROM epochs WHERE site_id = $1 AND id = $2")
            .bind(site)
            .bind(id)
            .fetch_optional(db)
            .await?,
    )
}

/// The residuals of every observation of an epoch, in upload order (the report's `residuals`).
pub async fn residuals(
    db: impl AnyExecutor<'_>,
    site: &str,
    id: i64,
) -> Result<Vec<StoredResidual>, StoreError> {
    Ok(sqlx::query_as(
        "SELECT o.image_id, o.point, o.vx_mm, o.vy_mm, o.w, CAST(o.dropped AS INTEGER) AS dropped FROM observations o \
         JOIN images i ON i.site_id = o.site_id AND i.epoch_id = o.epoch_id AND i.id = o.image_id \
         WHERE o.site_id = $1 AND o.epoch_id = $2 ORDER BY i.seq, o.seq",
    )
    .bind(site)
    .bind(id)
    .fetch_all(db)
    .await?)
}

/// Deletes the observations (image coordinates and residuals) of at most `limit` epochs observed
/// before `cut`, oldest first, that still hold them, and marks each as pruned at `pruned_at`
/// (both store format). Epochs, reports, coordinates, covariances and displacements stay.
/// Returns the epochs pruned; an epoch another pass marked first is not counted.
pub async fn prune_observations(
    db: &mut AnyConnection,
    cut: &str,
    pruned_at: &str,
    limit: i64,
) -> Result<u64, StoreError> {
    // Marked first and deleted by the marked ids, so that an epoch stored meanwhile (on
    // PostgreSQL) is never marked without its observations deleted.
    let marked: Vec<(String, i64)> = sqlx::query_as(
        "UPDATE epochs SET observations_pruned_at = $1 WHERE observations_pruned_at IS NULL \
         AND (site_id, id) IN (SELECT site_id, id FROM epochs \
         WHERE observations_pruned_at IS NULL AND observed_at < $2 ORDER BY observed_at LIMIT $3) \
         RETURNING site_id, id",
    )
    .bind(pruned_at)
    .bind(cut)
    .bind(limit)
    .fetch_all(&mut *db)
    .await?;
    for (site, id) in &marked {
        sqlx::query("DELETE FROM observations WHERE site_id = $1 AND epoch_id = $2")
            .bind(site)
            .bind(id)
            .execute(&mut *db)
            .await?;
    }
    Ok(marked.len() as u64)
}

/// The residual of one stored observation, as `GET .../epochs/{epoch}` lists it.
#[derive(Debug, Serialize, FromRow, ToSchema)]
pub struct StoredResidual {
    /// Image id.
    #[serde(rename = "image")]
    pub image_id: String,
    /// Point name.
    pub point: String,
    /// Residual in x (observed − computed), mm; null when the adjustment gave none.
    pub vx_mm: Option<f64>,
    /// Residual in y, mm.
    pub vy_mm: Option<f64>,
    /// Largest |w| of the two coordinates.
    pub w: Option<f64>,
    /// Dropped by data snooping.
    #[sqlx(try_from = "super::Flag")]
    pub dropped: bool,
}

/// The cameras (upload form, JSON) of the site as last uploaded: cameras of CSV uploads.
pub async fn site_cameras(db: impl AnyExecutor<'_>, site: &str) -> Result<Vec<Value>, StoreError> {
    let defs: Vec<String> =
        sqlx::query_scalar("SELECT definition FROM cameras WHERE site_id = $1 ORDER BY id")
            .bind(site)
            .fetch_all(db)
            .await?;
    defs.iter()
        .map(|d| serde_json::from_str(d).map_err(StoreError::from))
        .collect()
}

/// Stores an epoch with its images, observations, coordinates and joint covariance; returns its
/// new integer id. Call inside a write transaction; the caller stores the derived rows
/// (displacements, alerts, outbox) in the same transaction.
pub async fn insert(db: &mut AnyConnection, rec: &EpochRecord<'_>) -> Result<i64, StoreError> {
    let id: i64 =
        sqlx::query_scalar("SELECT COALESCE(MAX(id), 0) + 1 FROM epochs WHERE site_id = $1")
            .bind(rec.site)
            .fetch_one(&mut *db)
            .await?;
    let adj = rec.adjustment;
    let mut report = serde_json::to_value(&adj.report)?;
    if let Some(obj) = report.as_object_mut() {
        obj.remove("residuals");
        if let Some(id) = rec.identification {
            obj.insert("identification".into(), id.clone());
        }
        if let Some(applied) = rec.apriori_sigma_estimated {
            obj.insert(
                "apriori_sigma_estimated".into(),
                serde_json::to_value(applied)?,
            );
        }
    }
    let first_camera = adj.report.cameras.first();
    let created = timestamp(rec.created_at);
    let components = (!adj.report.variance_components.is_empty())
        .then(|| serde_json::to_string(&adj.report.variance_components))
        .transpose()?;
    sqlx::query(
        "INSERT INTO epochs (site_id, id, observed_at, label, status, model, sigma0_mm, c_mm, c_sigma_mm, \
         iterations, dropped_observations, body_sha256, cameras, report, created_at, variance_factor, dof, \
         variance_components) \
         VALUES ($1, $2, $3, $4, 'adjusted', $5, $6, $7, $8, $9, $10, $11, $12, $13, $14, $15, $16, $17)",
    )
    .bind(rec.site)
    .bind(id)
    .bind(rec.observed_at)
    .bind(&rec.input.label)
    .bind(adj.report.model.as_str())
    .bind(adj.report.sigma0_mm)
    .bind(first_camera.map(|c| c.c_mm))
    .bind(first_camera.and_then(|c| c.c_sigma_mm))
    .bind(adj.report.iterations as i64)
    .bind(adj.report.dropped.len() as i64)
    .bind(rec.body_sha256)
    .bind(serde_json::to_string(&rec.input.cameras)?)
    .bind(report.to_string())
    .bind(&created)
    .bind(Some(adj.report.variance_factor).filter(|v| v.is_finite()))
    .bind(adj.report.dof)
    .bind(components)
    .execute(&mut *db)
    .await?;
    upsert_cameras(db, rec, &created).await?;
    insert_images(db, rec, id).await?;
    insert_observations(db, rec, id).await?;
    insert_coordinates(db, rec, id).await?;
    if let Some(joint) = &adj.joint_covariance {
        super::joint_covariances::insert(&mut *db, rec.site, id, &joint.points, &joint.matrix_m2)
            .await?;
    }
    Ok(id)
}

/// The upload's cameras, new or updated. Camera ids are unique within an upload (validated), so
/// one statement may update them all.
async fn upsert_cameras(
    db: &mut AnyConnection,
    rec: &EpochRecord<'_>,
    created: &str,
) -> Result<(), StoreError> {
    for chunk in rec.input.cameras.chunks(super::rows_per_insert(4)) {
        let sql = format!(
            "INSERT INTO cameras (site_id, id, definition, updated_at) VALUES {} \
             ON CONFLICT (site_id, id) DO UPDATE SET definition = excluded.definition, updated_at = excluded.updated_at",
            super::values_list(db, chunk.len(), 4)
        );
        let mut q = sqlx::query(&sql);
        for cam in chunk {
            q = q
                .bind(rec.site)
                .bind(&cam.id)
                .bind(serde_json::to_string(cam)?)
                .bind(created);
        }
        q.execute(&mut *db).await?;
    }
    Ok(())
}

/// The epoch's images, and the stations seen for the first time. One statement per table for all
/// images (each statement is a round trip on PostgreSQL).
async fn insert_images(
    db: &mut AnyConnection,
    rec: &EpochRecord<'_>,
    id: i64,
) -> Result<(), StoreError> {
    let stations: Vec<String> = rec
        .input
        .images
        .iter()
        .map(|image| image.station.clone().unwrap_or_else(|| image.id.clone()))
        .collect();
    let mut new_stations: Vec<&String> = stations.iter().collect();
    new_stations.sort();
    new_stations.dedup();
    for chunk in new_stations.chunks(super::rows_per_insert(3)) {
        let sql = format!(
            "INSERT INTO stations (site_id, name, first_epoch) VALUES {} ON CONFLICT (site_id, name) DO NOTHING",
            super::values_list(db, chunk.len(), 3)
        );
        let mut q = sqlx::query(&sql);
        for station in chunk {
            q = q.bind(rec.site).bind(*station).bind(id);
        }
        q.execute(&mut *db).await?;
    }
    let images: Vec<(usize, &ImageInput)> = rec.input.images.iter().enumerate().collect();
    for chunk in images.chunks(super::rows_per_insert(6)) {
        let sql = format!(
            "INSERT INTO images (site_id, epoch_id, id, camera, station, seq) VALUES {}",
            super::values_list(db, chunk.len(), 6)
        );
        let mut q = sqlx::query(&sql);
        for (seq, image) in chunk {
            q = q
                .bind(rec.site)
                .bind(id)
                .bind(&image.id)
                .bind(&image.camera)
                .bind(&stations[*seq])
                .bind(*seq as i64);
        }
        q.execute(&mut *db).await?;
    }
    Ok(())
}

/// The epoch's observations with their residuals, normalized residuals and whether data
/// snooping dropped them.
async fn insert_observations(
    db: &mut AnyConnection,
    rec: &EpochRecord<'_>,
    id: i64,
) -> Result<(), StoreError> {
    let residuals: HashMap<(&str, &str), _> = rec
        .adjustment
        .report
        .residuals
        .iter()
        .map(|r| ((r.image.as_str(), r.point.as_str()), r))
        .collect();
    let observations: Vec<(
        &str,
        usize,
        &cliffwatch_core::photogrammetry::input::epoch::ObservationInput,
    )> = rec
        .input
        .images
        .iter()
        .flat_map(|image| {
            image
                .observations
                .iter()
                .enumerate()
                .map(move |(oseq, o)| (image.id.as_str(), oseq, o))
        })
        .collect();
    for chunk in observations.chunks(super::rows_per_insert(13)) {
        let sql = format!(
            "INSERT INTO observations (site_id, epoch_id, image_id, point, seq, x_mm, y_mm, \
             col_px, row_px, vx_mm, vy_mm, w, dropped) VALUES {}",
            super::values_list(db, chunk.len(), 13)
        );
        let mut q = sqlx::query(&sql);
        for (image, oseq, o) in chunk {
            let r = residuals.get(&(*image, o.point.as_str()));
            q = q
                .bind(rec.site)
                .bind(id)
                .bind(*image)
                .bind(&o.point)
                .bind(*oseq as i64)
                .bind(o.x_mm)
                .bind(o.y_mm)
                .bind(o.col)
                .bind(o.row)
                .bind(r.map(|r| r.vx_mm))
                .bind(r.map(|r| r.vy_mm))
                .bind(r.map(|r| r.w))
                .bind(r.is_some_and(|r| r.dropped));
        }
        q.execute(&mut *db).await?;
    }
    Ok(())
}

/// The epoch's adjusted coordinates with their covariance, and the points seen for the first
/// time (a control point of the upload starts `stable`, any other `monitored`).
async fn insert_coordinates(
    db: &mut AnyConnection,
    rec: &EpochRecord<'_>,
    id: i64,
) -> Result<(), StoreError> {
    for chunk in rec.adjustment.points.chunks(super::rows_per_insert(13)) {
        let sql = format!(
            "INSERT INTO points (site_id, name, role) VALUES {} ON CONFLICT (site_id, name) DO NOTHING",
            super::values_list(db, chunk.len(), 3)
        );
        let mut q = sqlx::query(&sql);
        for p in chunk {
            let role = if rec.control_points.contains(&p.name) {
                "stable"
            } else {
                "monitored"
            };
            q = q.bind(rec.site).bind(&p.name).bind(role);
        }
        q.execute(&mut *db).await?;
        let sql = format!(
            "INSERT INTO coordinates (site_id, epoch_id, point, observed_at, x_m, y_m, z_m, \
             cxx_m2, cxy_m2, cxz_m2, cyy_m2, cyz_m2, czz_m2) VALUES {}",
            super::values_list(db, chunk.len(), 13)
        );
        let mut q = sqlx::query(&sql);
        for p in chunk {
            let c = &p.covariance_m2;
            q = q
                .bind(rec.site)
                .bind(id)
                .bind(&p.name)
                .bind(rec.observed_at)
                .bind(p.xyz[0])
                .bind(p.xyz[1])
                .bind(p.xyz[2])
                .bind(c[0][0])
                .bind(c[0][1])
                .bind(c[0][2])
                .bind(c[1][1])
                .bind(c[1][2])
                .bind(c[2][2]);
        }
        q.execute(&mut *db).await?;
    }
    Ok(())
}

/// One observation of an epoch with its residual, for the residual plot of an image.
#[derive(Debug, Clone, PartialEq, FromRow)]
pub struct ObservationResidual {
    /// Image id.
    pub image_id: String,
    /// Point name.
    pub point: String,
    /// Image coordinates as uploaded, mm (None when given in pixels).
    pub x_mm: Option<f64>,
    /// See `x_mm`.
    pub y_mm: Option<f64>,
    /// Image coordinates as uploaded, pixels (None when given in mm).
    pub col_px: Option<f64>,
    /// See `col_px`.
    pub row_px: Option<f64>,
    /// Residual (observed − computed) in mm.
    pub vx_mm: Option<f64>,
    /// See `vx_mm`.
    pub vy_mm: Option<f64>,
    /// Normalised residual of data snooping.
    pub w: Option<f64>,
    /// Dropped by data snooping.
    #[sqlx(try_from = "super::Flag")]
    pub dropped: bool,
}

/// Every observation of an epoch with its image coordinates and residual, image by image in
/// upload order.
pub async fn observation_residuals(
    db: impl AnyExecutor<'_>,
    site: &str,
    id: i64,
) -> Result<Vec<ObservationResidual>, StoreError> {
    Ok(sqlx::query_as(
        "SELECT o.image_id, o.point, o.x_mm, o.y_mm, o.col_px, o.row_px, o.vx_mm, o.vy_mm, o.w, CAST(o.dropped AS INTEGER) AS dropped \
         FROM observations o JOIN images i ON i.site_id = o.site_id AND i.epoch_id = o.epoch_id AND i.id = o.image_id \
         WHERE o.site_id = $1 AND o.epoch_id = $2 ORDER BY i.seq, o.seq",
    )
    .bind(site)
    .bind(id)
    .fetch_all(db)
    .await?)
}

/// Id of the site's earliest epoch (by observation time).
pub async fn earliest(db: impl AnyExecutor<'_>, site: &str) -> Result<Option<i64>, StoreError> {
    Ok(
        sqlx::query_scalar("SELECT id FROM epochs WHERE site_id = $1 ORDER BY observed_at LIMIT 1")
            .bind(site)
            .fetch_optional(db)
            .await?,
    )
}

/// Number of the site's epochs observed after `observed_at` (store format).
pub async fn count_after(
    db: impl AnyExecutor<'_>,
    site: &str,
    observed_at: &str,
) -> Result<i64, StoreError> {
    Ok(
        sqlx::query_scalar("SELECT COUNT(*) FROM epochs WHERE site_id = $1 AND observed_at > $2")
            .bind(site)
            .bind(observed_at)
            .fetch_one(db)
            .await?,
    )
}

/// Ids of the site's epochs in time order.
pub async fn ids_in_time_order(
    db: impl AnyExecutor<'_>,
    site: &str,
) -> Result<Vec<i64>, StoreError> {
    Ok(
        sqlx::query_scalar("SELECT id FROM epochs WHERE site_id = $1 ORDER BY observed_at")
            .bind(site)
            .fetch_all(db)
            .await?,
    )
}

/// Ids of at most `count` epochs from epoch `first` on, in time order (the epochs of a
/// reference of several epochs).
pub async fn window_from(
    db: impl AnyExecutor<'_>,
    site: &str,
    first: i64,
    count: i64,
) -> Result<Vec<i64>, StoreError> {
    Ok(sqlx::query_scalar(
        "SELECT id FROM epochs WHERE site_id = $1 AND observed_at >= \
         (SELECT observed_at FROM epochs WHERE site_id = $2 AND id = $3) ORDER BY observed_at LIMIT $4",
    )
    .bind(site)
    .bind(site)
    .bind(first)
    .bind(count)
    .fetch_all(db)
    .await?)
}

/// Observation time (store format) of the site's latest epoch.
pub async fn last_observed_at(
    db: impl AnyExecutor<'_>,
    site: &str,
) -> Result<Option<String>, StoreError> {
    Ok(
        sqlx::query_scalar("SELECT MAX(observed_at) FROM epochs WHERE site_id = $1")
            .bind(site)
            .fetch_one(db)
            .await?,
    )
}

/// Sets the analysis outcome of a stored epoch: status `adjusted` without `analysis_error` in
/// its report, or `analysis_failed` with the reason in `analysis_error`. Nothing changes for an
/// unknown epoch, or when the outcome is already the stored one.
pub async fn set_analysis_outcome(
    db: &mut AnyConnection,
    site: &str,
    epoch: i64,
    error: Option<&str>,
) -> Result<(), StoreError> {
    let report: Option<String> =
        sqlx::query_scalar("SELECT report FROM epochs WHERE site_id = $1 AND id = $2")
            .bind(site)
            .bind(epoch)
            .fetch_optional(&mut *db)
            .await?;
    let mut report: serde_json::Map<String, serde_json::Value> = match report {
        Some(r) => serde_json::from_str(&r)?,
        None => return Ok(()),
    };
    let status = match error {
        Some(e) => {
            report.insert("analysis_error".into(), e.into());
            EpochStatus::AnalysisFailed
        }
        None => {
            if report.remove("analysis_error").is_none() {
                return Ok(());
            }
            EpochStatus::Adjusted
        }
    };
    sqlx::query("UPDATE epochs SET status = $1, report = $2 WHERE site_id = $3 AND id = $4")
        .bind(status.as_str())
        .bind(serde_json::Value::Object(report).to_string())
        .bind(site)
        .bind(epoch)
        .execute(&mut *db)
        .await?;
    Ok(())
}
