//! The one ingestion path of an epoch, used by the HTTP API and the watched directory:
//! validate → (site history as start values) → adjust in `spawn_blocking` → store the epoch and
//! everything derived from it (coordinates, displacements, alerts, outbox) in **one** write
//! transaction, or nothing.
//!
//! Idempotency: the sha256 of [`EpochInput::canonical_json`] is stored with the epoch; the same body
//! again returns the stored epoch, another body for the same `observed_at` is a conflict.

use std::collections::BTreeMap;
use std::time::Instant;

use sha2::{Digest, Sha256};
use sqlx::SqliteConnection;
use thiserror::Error;

use crate::alerting;
use crate::analysis::EpochCoordinates;
use crate::photogrammetry::epoch::CameraInput;
use crate::photogrammetry::{
    adjust_problem, AdjustError, AdjustOptions, Adjustment, EpochError, EpochInput, Model,
};
use crate::store::block_motions;
use crate::store::displacements::{self, Displacement};
use crate::store::sites::Site;
use crate::store::{self, epochs, points, sites, Store, StoreError};
use chrono::Utc;

/// Why an epoch was not ingested.
#[derive(Debug, Error)]
pub enum IngestError {
    /// The site does not exist (uploads do not create sites).
    #[error("unknown site '{0}'")]
    UnknownSite(String),
    /// The upload is not a valid epoch (names the field, image or point).
    #[error(transparent)]
    Invalid(#[from] EpochError),
    /// The epoch cannot be adjusted (names the image or point).
    #[error(transparent)]
    Adjust(#[from] AdjustError),
    /// Another body was stored for this `observed_at`.
    #[error("epoch {epoch} of site '{site}' has observed_at {observed_at} with another body")]
    Conflict {
        /// Site id.
        site: String,
        /// Observation time.
        observed_at: String,
        /// The stored epoch's id.
        epoch: i64,
    },
    /// The database failed.
    #[error(transparent)]
    Store(#[from] StoreError),
    /// The adjustment task panicked or was cancelled.
    #[error("adjustment task failed: {0}")]
    Task(String),
}

impl From<sqlx::Error> for IngestError {
    fn from(e: sqlx::Error) -> Self {
        IngestError::Store(StoreError::Sql(e))
    }
}

/// The outcome of a successful ingestion.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Ingested {
    /// Site id.
    pub site: String,
    /// The epoch's integer id.
    pub epoch: i64,
    /// True when this call stored it; false when the same body was stored before.
    pub created: bool,
}

/// sha256 (hex) of the canonical JSON of an upload.
pub fn body_hash(input: &EpochInput) -> String {
    hex::encode(Sha256::digest(input.canonical_json().as_bytes()))
}

/// Networks up to this many points store the joint covariance of all of them; larger ones that of
/// their stable points only (the matrix grows with the square of the points: 28 points make
/// 84 × 84 values, about 150 kB of JSON per epoch).
pub const JOINT_COVARIANCE_ALL_POINTS_MAX: usize = 40;

/// The points whose joint covariance an epoch stores: every point of a network of up to
/// [`JOINT_COVARIANCE_ALL_POINTS_MAX`] points, else the stable ones. The displacement analysis
/// propagates the stable-point datum with the cross-covariances between each point and the datum
/// points; without them the depth σ of displacements came out 8 % optimistic in the calibration
/// test (`tests/adjust_calibration.rs`).
pub fn joint_covariance_points(points: &[String], stable: Vec<String>) -> Vec<String> {
    if points.len() <= JOINT_COVARIANCE_ALL_POINTS_MAX {
        points.to_vec()
    } else {
        stable
    }
}

/// Ingests one epoch of the upload form into a site.
pub async fn ingest(
    store: &Store,
    site_id: &str,
    input: EpochInput,
) -> Result<Ingested, IngestError> {
    ingest_with_identification(store, site_id, input, None).await
}

/// [`ingest`] of an epoch from the watched directory, storing with its report how each station's
/// targets were identified (`identification`: per station method and counts).
pub async fn ingest_with_identification(
    store: &Store,
    site_id: &str,
    input: EpochInput,
    identification: Option<serde_json::Value>,
) -> Result<Ingested, IngestError> {
    let problem = input.validate()?;
    let site = sites::get(store.reader(), site_id)
        .await?
        .ok_or_else(|| IngestError::UnknownSite(site_id.to_string()))?;
    let observed_at = store::timestamp(problem.observed_at);
    let hash = body_hash(&input);
    if let Some(done) = check_existing(store.reader(), &site.id, &observed_at, &hash).await? {
        return Ok(done);
    }

    let prior: BTreeMap<String, [f64; 3]> = points::latest_coordinates(store.reader(), &site.id)
        .await?
        .into_iter()
        .map(|c| (c.point, c.xyz))
        .collect();
    let options = AdjustOptions {
        model: site.model.parse().unwrap_or(Model::Orthogonal),
        prior,
        joint_covariance_of: joint_covariance_points(
            &problem.points,
            points::stable(store.reader(), &site.id).await?,
        ),
        ..AdjustOptions::default()
    };
    let started = Instant::now();
    let adjustment = tokio::task::spawn_blocking(move || adjust_problem(&problem, &options))
        .await
        .map_err(|e| IngestError::Task(e.to_string()))?;
    metrics::histogram!("cliffwatch_adjustment_seconds").record(started.elapsed().as_secs_f64());
    let outcome = if adjustment.is_ok() { "ok" } else { "failed" };
    metrics::counter!("cliffwatch_adjustments_total", "outcome" => outcome).increment(1);
    let adjustment = adjustment?;

    let mut tx = store.begin_write().await?;
    // Another upload of the same observed_at may have committed while this one adjusted.
    if let Some(done) = check_existing(&mut *tx, &site.id, &observed_at, &hash).await? {
        return Ok(done);
    }
    let control: Vec<String> = input.control.iter().map(|c| c.point.clone()).collect();
    let record = epochs::EpochRecord {
        site: &site.id,
        observed_at: &observed_at,
        body_sha256: &hash,
        input: &input,
        adjustment: &adjustment,
        control_points: &control,
        identification: identification.as_ref(),
    };
    let epoch = epochs::insert(&mut tx, &record).await?;
    let derived = derive(&mut tx, &site, epoch, &observed_at, &adjustment).await?;
    displacements::insert(&mut tx, &site.id, &derived.displacements).await?;
    block_motions::insert(&mut tx, &site.id, &derived.block_motions).await?;
    tx.commit().await?;
    metrics::counter!("cliffwatch_alerts_raised_total").increment(derived.raised as u64);
    Ok(Ingested {
        site: site.id,
        epoch,
        created: true,
    })
}

async fn check_existing<'c>(
    db: impl sqlx::SqliteExecutor<'c>,
    site: &str,
    observed_at: &str,
    hash: &str,
) -> Result<Option<Ingested>, IngestError> {
    match epochs::find_by_time(db, site, observed_at).await? {
        None => Ok(None),
        Some(k) if k.body_sha256 == hash => Ok(Some(Ingested {
            site: site.to_string(),
            epoch: k.id,
            created: false,
        })),
        Some(k) => Err(IngestError::Conflict {
            site: site.to_string(),
            observed_at: store::display_timestamp(observed_at),
            epoch: k.id,
        }),
    }
}

/// What an epoch makes besides its own rows: its displacements and how many alerts it raised
/// (alert rows and outbox rows are already written).
#[derive(Debug, Default)]
pub struct Derived {
    /// Displacements of this epoch (empty when the whole site was recomputed instead).
    pub displacements: Vec<Displacement>,
    /// Motion rows of the site's declared blocks in this epoch (likewise).
    pub block_motions: Vec<Displacement>,
    /// Alerts raised by this epoch.
    pub raised: usize,
}

async fn reference_epoch(
    tx: &mut SqliteConnection,
    site: &Site,
) -> Result<Option<i64>, IngestError> {
    Ok(match site.reference_epoch {
        Some(r) => Some(r),
        None => {
            sqlx::query_scalar(
                "SELECT id FROM epochs WHERE site_id = ? ORDER BY observed_at LIMIT 1",
            )
            .bind(&site.id)
            .fetch_optional(&mut *tx)
            .await?
        }
    })
}

/// The site's reference coordinates ([`alerting::reference_coordinates`]); when the epochs of a
/// several-epoch reference cannot be combined, the reference epoch alone (logged), so that an
/// upload and a recompute always agree.
async fn site_reference(
    tx: &mut SqliteConnection,
    site: &Site,
    reference: i64,
    points: &[crate::analysis::PointConfig],
    config: &crate::analysis::AnalysisConfig,
) -> Result<Option<EpochCoordinates>, IngestError> {
    Ok(
        match alerting::reference_coordinates(tx, site, reference, points, config).await? {
            None => None,
            Some(Ok(r)) => Some(r),
            Some(Err(e)) => {
                tracing::warn!(site = %site.id, reference, error = %e,
                    "the reference epochs cannot be combined; the reference epoch alone is used");
                alerting::epoch_coordinates(tx, &site.id, reference).await?
            }
        },
    )
}

/// THE seam of the displacement analysis and the alert rules: runs inside the epoch's write
/// transaction (history read from `tx` is consistent with what is written).
///
/// Loads the reference epoch's coordinates (with the stable points' joint covariance), the point
/// configurations and the history the windows need, runs [`crate::analysis::analyse_epoch`] on a
/// blocking thread, then evaluates the site's alert rules and writes the alert state, the alerts and
/// the webhook outbox. An epoch whose analysis fails (e.g. too few points in common with the
/// reference) is stored without displacements, with status `analysis_failed`, the reason in its
/// report (`analysis_error`) and a site-level `analysis_failed` alert for the staff.
async fn derive(
    tx: &mut SqliteConnection,
    site: &Site,
    epoch: i64,
    observed_at: &str,
    adjustment: &Adjustment,
) -> Result<Derived, IngestError> {
    let earliest: i64 =
        sqlx::query_scalar("SELECT id FROM epochs WHERE site_id = ? ORDER BY observed_at LIMIT 1")
            .bind(&site.id)
            .fetch_one(&mut *tx)
            .await?;
    let later: i64 =
        sqlx::query_scalar("SELECT COUNT(*) FROM epochs WHERE site_id = ? AND observed_at > ?")
            .bind(&site.id)
            .bind(observed_at)
            .fetch_one(&mut *tx)
            .await?;
    let reference = site.reference_epoch.unwrap_or(earliest);
    // An epoch inside a reference of several epochs changes the reference itself.
    let in_reference = site.reference_epochs > 1
        && reference != epoch
        && alerting::reference_window(tx, site, reference)
            .await?
            .contains(&epoch);
    if later > 0 || in_reference {
        // Out of order: later epochs' histories (velocities, forecasts) and, when this epoch is the
        // earliest without a set reference, the reference itself change. Recompute the series.
        let raised = recompute_site(tx, site).await?;
        return Ok(Derived {
            raised,
            ..Derived::default()
        });
    }
    let Some(t) = store::parse_timestamp(observed_at) else {
        return Ok(Derived::default());
    };
    let current = EpochCoordinates::from_adjustment(epoch, t, adjustment);
    let config = alerting::site_analysis_config(tx, site).await?;
    let points = alerting::point_configs(tx, &site.id).await?;
    let reference = if reference == epoch {
        current.clone()
    } else {
        match site_reference(tx, site, reference, &points, &config).await? {
            Some(r) => r,
            None => {
                let reason = format!("the reference epoch {reference} has no coordinates");
                return failed(tx, site, epoch, t, &reason).await;
            }
        }
    };
    let reference_id = reference.epoch;
    let history = alerting::history(tx, &site.id, observed_at, config.history_epochs()).await?;
    let analysis = alerting::analyse_blocking(reference, current, points, history, config)
        .await
        .map_err(|e| IngestError::Task(e.to_string()))?;
    let analysis = match analysis {
        Ok(a) => a,
        Err(e) => {
            let reason = format!("analysis against reference epoch {reference_id}: {e}");
            return failed(tx, site, epoch, t, &reason).await;
        }
    };
    for w in &analysis.warnings {
        tracing::info!(site = %site.id, epoch, "analysis: {w}");
    }
    let displacements = alerting::to_rows(&analysis.records(), analysis.reference_epoch);
    let block_motions = alerting::to_rows(&analysis.block_records(), analysis.reference_epoch);
    let raised = alerting::evaluate_and_record(tx, site, &analysis, Utc::now()).await?;
    Ok(Derived {
        displacements,
        block_motions,
        raised,
    })
}

/// Stores an epoch's failed analysis (see [`alerting::record_analysis_failure`]) and logs it.
async fn failed(
    tx: &mut SqliteConnection,
    site: &Site,
    epoch: i64,
    t: chrono::DateTime<Utc>,
    reason: &str,
) -> Result<Derived, IngestError> {
    tracing::warn!(site = %site.id, epoch, reason, "epoch stored without displacements");
    let raised = alerting::record_analysis_failure(tx, site, epoch, t, reason, Utc::now()).await?;
    Ok(Derived {
        raised,
        ..Derived::default()
    })
}

/// Recomputes every displacement of a site against its current reference (after
/// `PUT .../reference`); see [`recompute_site`]. Call inside a write transaction.
pub async fn recompute_displacements(
    tx: &mut SqliteConnection,
    site: &Site,
) -> Result<(), IngestError> {
    recompute_site(tx, site).await.map(|_| ())
}

/// Recomputes the derived series of a site after a change of its history (a new reference, an
/// epoch that arrived out of order), inside the caller's write transaction so the change and
/// everything derived from it commit together:
/// 1. every displacement against the current reference, epoch by epoch in time order, each with
///    the history recomputed before it (velocities, forecasts);
/// 2. each epoch's analysis status (`adjusted` / `analysis_failed` with the reason);
/// 3. the alert state: the rules are replayed over the recomputed series and the stored state is
///    brought to the result by [`alerting::reconcile_and_record`], which announces only the net
///    change now (raised, escalated, de-escalated, resolved) and never re-sends transitions staff
///    already received; open alerts keep their id and acknowledgement.
///
/// Returns how many alerts were raised.
pub async fn recompute_site(tx: &mut SqliteConnection, site: &Site) -> Result<usize, IngestError> {
    let site = sites::get(&mut *tx, &site.id)
        .await?
        .ok_or_else(|| IngestError::UnknownSite(site.id.clone()))?;
    sites::mark_current(&mut *tx, &site.id).await?;
    displacements::delete_site(tx, &site.id).await?;
    block_motions::delete_site(tx, &site.id).await?;
    let Some(reference) = reference_epoch(tx, &site).await? else {
        return Ok(0);
    };
    let config = alerting::site_analysis_config(tx, &site).await?;
    let points = alerting::point_configs(tx, &site.id).await?;
    let Some(reference) = site_reference(tx, &site, reference, &points, &config).await? else {
        return Ok(0);
    };
    let ids: Vec<i64> =
        sqlx::query_scalar("SELECT id FROM epochs WHERE site_id = ? ORDER BY observed_at")
            .bind(&site.id)
            .fetch_all(&mut *tx)
            .await?;
    let mut series = Vec::with_capacity(ids.len());
    for id in ids {
        if let Some(e) = alerting::epoch_coordinates(tx, &site.id, id).await? {
            series.push(e);
        }
    }
    let reference_id = reference.epoch;
    let out = alerting::analyse_series_blocking(
        reference,
        series,
        points,
        config,
        alerting::alert_config(&site),
    )
    .await
    .map_err(|e| IngestError::Task(e.to_string()))?;
    let rows = alerting::to_rows(&out.records, reference_id);
    displacements::insert(tx, &site.id, &rows).await?;
    let blocks = alerting::to_rows(&out.block_records, reference_id);
    block_motions::insert(tx, &site.id, &blocks).await?;
    for id in &out.analysed {
        alerting::set_analysis_status(tx, &site.id, *id, None).await?;
    }
    for (id, reason) in &out.failures {
        alerting::set_analysis_status(tx, &site.id, *id, Some(reason)).await?;
    }
    Ok(alerting::reconcile_and_record(tx, &site.id, &out.replayed, Utc::now()).await?)
}

/// Recomputes, once, every site whose stored series an older binary derived
/// ([`sites::ANALYSIS_VERSION`]: e.g. rows without the filtered values), one write transaction per
/// site; called at start. Returns how many sites were recomputed.
pub async fn recompute_outdated(store: &crate::store::Store) -> Result<usize, IngestError> {
    let ids = sites::outdated(store.reader()).await?;
    for id in &ids {
        let mut tx = store.begin_write().await?;
        if let Some(site) = sites::get(&mut *tx, id).await? {
            tracing::info!(site = %id, "recomputing the series derived by an older version");
            recompute_site(&mut tx, &site).await?;
        }
        tx.commit().await.map_err(crate::store::StoreError::from)?;
    }
    Ok(ids.len())
}

/// Why a CSV upload cannot be read.
#[derive(Debug, Error)]
pub enum CsvError {
    /// Not CSV of the form `image,point,x_mm,y_mm`.
    #[error("CSV line {line}: {reason}")]
    Malformed {
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        reason: String,
    },
    /// The site has no cameras yet (upload one JSON epoch first).
    #[error("the site has no cameras yet: upload a JSON epoch first")]
    NoCameras,
}

/// Builds an upload from the CSV form (`image,point,x_mm,y_mm` a line, optional header), the
/// observation time and the site's cameras (every image uses the first camera).
pub fn epoch_from_csv(
    text: &str,
    observed_at: &str,
    cameras: Vec<CameraInput>,
) -> Result<EpochInput, CsvError> {
    use crate::photogrammetry::epoch::{ImageInput, ObservationInput};
    let camera = cameras.first().ok_or(CsvError::NoCameras)?.id.clone();
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(false)
        .trim(csv::Trim::All)
        .comment(Some(b'#'))
        .from_reader(text.as_bytes());
    let mut images: Vec<ImageInput> = Vec::new();
    for (i, record) in reader.records().enumerate() {
        let line = i + 1;
        let record = record.map_err(|e| CsvError::Malformed {
            line,
            reason: e.to_string(),
        })?;
        if record.len() != 4 {
            return Err(CsvError::Malformed {
                line,
                reason: format!("{} fields, want image,point,x_mm,y_mm", record.len()),
            });
        }
        if i == 0 && &record[0] == "image" {
            continue;
        }
        let number = |k: usize| -> Result<f64, CsvError> {
            record[k].parse().map_err(|_| CsvError::Malformed {
                line,
                reason: format!("'{}' is not a number", &record[k]),
            })
        };
        let obs = ObservationInput {
            point: record[1].to_string(),
            x_mm: Some(number(2)?),
            y_mm: Some(number(3)?),
            col: None,
            row: None,
        };
        match images.iter_mut().find(|im| im.id == record[0]) {
            Some(im) => im.observations.push(obs),
            None => images.push(ImageInput {
                id: record[0].to_string(),
                camera: camera.clone(),
                station: None,
                observations: vec![obs],
            }),
        }
    }
    Ok(EpochInput {
        observed_at: observed_at.to_string(),
        label: None,
        cameras,
        images,
        control: Vec::new(),
        approx: Vec::new(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn csv_groups_observations_by_image() {
        let cam: CameraInput = serde_json::from_str(r#"{"id": "cam", "c_mm": 300.0}"#).unwrap();
        let e = epoch_from_csv(
            "image,point,x_mm,y_mm\nA,1,0.5,0.25\nA,2,1,2\nB,1,3,4\n",
            "2026-01-01T00:00:00Z",
            vec![cam],
        )
        .unwrap();
        assert_eq!(e.images.len(), 2);
        assert_eq!(e.images[0].observations.len(), 2);
        assert!(epoch_from_csv("A,1,x,2", "2026-01-01T00:00:00Z", vec![]).is_err());
    }
}
