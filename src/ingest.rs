//! The one ingestion path of an epoch, used by the HTTP API and the watched directory:
//! validate → (site history as start values) → adjust in `spawn_blocking` → store the epoch and
//! everything derived from it (coordinates, displacements, alerts, outbox) in **one** write
//! transaction, or nothing.
//!
//! Idempotency: the sha256 of [`EpochInput::canonical_json`] is stored with the epoch; the same body
//! again returns the stored epoch, another body for the same `observed_at` is a conflict.

use std::collections::{BTreeMap, HashMap};
use std::time::Instant;

use sha2::{Digest, Sha256};
use sqlx::SqliteConnection;
use thiserror::Error;

use crate::photogrammetry::epoch::CameraInput;
use crate::photogrammetry::{
    adjust_problem, AdjustError, AdjustOptions, Adjustment, EpochError, EpochInput, Model,
};
use crate::store::displacements::{self, Displacement};
use crate::store::points::StoredCoordinate;
use crate::store::sites::Site;
use crate::store::{self, alerts, epochs, points, sites, webhooks, Store, StoreError};

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

/// Ingests one epoch of the upload form into a site.
pub async fn ingest(
    store: &Store,
    site_id: &str,
    input: EpochInput,
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
        joint_covariance_of: points::stable(store.reader(), &site.id).await?,
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
    };
    let epoch = epochs::insert(&mut tx, &record).await?;
    let derived = derive(&mut tx, &site, epoch, &observed_at, &adjustment).await?;
    displacements::insert(&mut tx, &site.id, &derived.displacements).await?;
    alerts::insert(&mut tx, &site.id, &derived.alerts).await?;
    webhooks::enqueue(&mut tx, &derived.events).await?;
    tx.commit().await?;
    metrics::counter!("cliffwatch_alerts_raised_total").increment(derived.alerts.len() as u64);
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

/// What an epoch makes besides its own rows: displacements, alerts and webhook events.
#[derive(Debug, Default)]
pub struct Derived {
    /// Displacements of this epoch (or of the whole site when the reference moved).
    pub displacements: Vec<Displacement>,
    /// Alerts raised.
    pub alerts: Vec<alerts::NewAlert>,
    /// Webhook events for them.
    pub events: Vec<webhooks::NewEvent>,
}

/// THE seam of the displacement analysis and the alert rules: runs inside the epoch's write
/// transaction (history read from `tx` is consistent with what is written).
///
/// For now displacement = coordinates − the reference epoch's, with σ from the two 3 × 3
/// covariances (correlation ignored) and no alerts; `crate::analysis` replaces the body.
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
    if site.reference_epoch.is_none() && earliest == epoch && epoch != 1 {
        // An epoch earlier than the reference arrived: it is the new default reference.
        recompute_displacements(tx, site).await?;
        return Ok(Derived::default());
    }
    let reference = site.reference_epoch.unwrap_or(earliest);
    let reference: HashMap<String, StoredCoordinate> =
        points::epoch_coordinates(&mut *tx, &site.id, reference)
            .await?
            .into_iter()
            .map(|c| (c.point.clone(), c))
            .collect();
    let directions = point_directions(tx, &site.id).await?;
    let mut out = Vec::new();
    for p in &adjustment.points {
        let Some(r) = reference.get(&p.name) else {
            continue;
        };
        let previous = displacements::previous(&mut *tx, &site.id, &p.name, observed_at).await?;
        let current = StoredCoordinate {
            point: p.name.clone(),
            epoch,
            observed_at: observed_at.to_string(),
            xyz: p.xyz,
            covariance_m2: p.covariance_m2,
        };
        out.push(displacement(
            r,
            &current,
            previous.as_ref().map(|(t, d)| (t.as_str(), *d)),
            directions.get(&p.name).copied(),
            site.confidence,
        ));
    }
    Ok(Derived {
        displacements: out,
        ..Derived::default()
    })
}

async fn point_directions(
    tx: &mut SqliteConnection,
    site: &str,
) -> Result<HashMap<String, [f64; 3]>, IngestError> {
    Ok(points::list(&mut *tx, site, None, i64::MAX)
        .await?
        .into_iter()
        .filter_map(|p| p.direction.map(|d| (p.name, d)))
        .collect())
}

/// Recomputes every displacement of a site against its current reference (after
/// `PUT .../reference` or when an earlier epoch arrives). Call inside a write transaction.
pub async fn recompute_displacements(
    tx: &mut SqliteConnection,
    site: &Site,
) -> Result<(), IngestError> {
    let site = sites::get(&mut *tx, &site.id)
        .await?
        .ok_or_else(|| IngestError::UnknownSite(site.id.clone()))?;
    displacements::delete_site(tx, &site.id).await?;
    let reference = match site.reference_epoch {
        Some(r) => Some(r),
        None => {
            sqlx::query_scalar(
                "SELECT id FROM epochs WHERE site_id = ? ORDER BY observed_at LIMIT 1",
            )
            .bind(&site.id)
            .fetch_optional(&mut *tx)
            .await?
        }
    };
    let Some(reference) = reference else {
        return Ok(());
    };
    let reference: HashMap<String, StoredCoordinate> =
        points::epoch_coordinates(&mut *tx, &site.id, reference)
            .await?
            .into_iter()
            .map(|c| (c.point.clone(), c))
            .collect();
    let directions = point_directions(tx, &site.id).await?;
    let all = points::all_coordinates(&mut *tx, &site.id).await?;
    let mut previous: HashMap<String, (String, f64)> = HashMap::new();
    let mut rows = Vec::with_capacity(all.len());
    for c in &all {
        let Some(r) = reference.get(&c.point) else {
            continue;
        };
        let prev = previous.get(&c.point).map(|(t, d)| (t.as_str(), *d));
        let d = displacement(
            r,
            c,
            prev,
            directions.get(&c.point).copied(),
            site.confidence,
        );
        previous.insert(c.point.clone(), (c.observed_at.clone(), d.d_mm));
        rows.push(d);
    }
    displacements::insert(tx, &site.id, &rows).await?;
    Ok(())
}

/// χ² quantile with 3 degrees of freedom at the given confidence (table, nearest level at or above).
fn chi2_3(confidence: f64) -> f64 {
    const TABLE: [(f64, f64); 6] = [
        (0.90, 6.251),
        (0.95, 7.815),
        (0.975, 9.348),
        (0.99, 11.345),
        (0.995, 12.838),
        (0.999, 16.266),
    ];
    TABLE
        .iter()
        .find(|(p, _)| confidence <= *p + 1e-12)
        .map(|(_, q)| *q)
        .unwrap_or(16.266)
}

/// The placeholder displacement of one point: `current − reference` in mm, σ from the sum of the
/// two covariances, significance by the χ²(3) test of the 3-D vector, velocity of `d_mm` against
/// `previous = (observed_at, d_mm)`, `d_along` on the unit `direction`.
pub fn displacement(
    reference: &StoredCoordinate,
    current: &StoredCoordinate,
    previous: Option<(&str, f64)>,
    direction: Option<[f64; 3]>,
    confidence: f64,
) -> Displacement {
    use nalgebra::{Matrix3, Vector3};
    let same = reference.epoch == current.epoch;
    let d = Vector3::from_fn(|i, _| (current.xyz[i] - reference.xyz[i]) * 1000.0);
    let cov = if same {
        Matrix3::zeros()
    } else {
        Matrix3::from_fn(|i, j| (current.covariance_m2[i][j] + reference.covariance_m2[i][j]) * 1e6)
    };
    let length = d.norm();
    let sigma = if length > 0.0 {
        let g = d / length;
        (g.transpose() * cov * g)[(0, 0)].max(0.0).sqrt()
    } else {
        (cov.trace() / 3.0).max(0.0).sqrt()
    };
    let significant = !same
        && cov
            .try_inverse()
            .map(|inv| (d.transpose() * inv * d)[(0, 0)] > chi2_3(confidence))
            .unwrap_or(false);
    let d_along = direction.and_then(|n| {
        let n = Vector3::from(n);
        let norm = n.norm();
        (norm > 0.0).then(|| d.dot(&n) / norm)
    });
    let velocity = previous.and_then(|(t, d_prev)| {
        let t0 = store::parse_timestamp(t)?;
        let t1 = store::parse_timestamp(&current.observed_at)?;
        let days = (t1 - t0).num_milliseconds() as f64 / 86_400_000.0;
        (days > 0.0).then(|| (length - d_prev) / days)
    });
    Displacement {
        point: current.point.clone(),
        epoch: current.epoch,
        observed_at: current.observed_at.clone(),
        reference_epoch: reference.epoch,
        dx_mm: d[0],
        dy_mm: d[1],
        dz_mm: d[2],
        d_mm: length,
        sigma_dx_mm: cov[(0, 0)].max(0.0).sqrt(),
        sigma_dy_mm: cov[(1, 1)].max(0.0).sqrt(),
        sigma_dz_mm: cov[(2, 2)].max(0.0).sqrt(),
        sigma_mm: sigma,
        d_along_mm: d_along,
        significant,
        velocity_mm_per_day: velocity,
        time_to_failure_hours: None,
    }
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

    fn coord(epoch: i64, t: &str, xyz: [f64; 3]) -> StoredCoordinate {
        let s = 1e-8; // (0.1 mm)²
        StoredCoordinate {
            point: "P".into(),
            epoch,
            observed_at: t.into(),
            xyz,
            covariance_m2: [[s, 0.0, 0.0], [0.0, s, 0.0], [0.0, 0.0, s]],
        }
    }

    #[test]
    fn displacement_is_current_minus_reference_in_mm() {
        let r = coord(1, "2026-01-01T00:00:00.000000Z", [1.0, 2.0, 3.0]);
        let c = coord(2, "2026-01-03T00:00:00.000000Z", [1.003, 2.0, 2.996]);
        let d = displacement(
            &r,
            &c,
            Some(("2026-01-01T00:00:00.000000Z", 0.0)),
            Some([0.0, 0.0, -2.0]),
            0.99,
        );
        assert!((d.dx_mm - 3.0).abs() < 1e-9 && (d.dz_mm + 4.0).abs() < 1e-9);
        assert!((d.d_mm - 5.0).abs() < 1e-9);
        assert!((d.d_along_mm.unwrap() - 4.0).abs() < 1e-9);
        assert!((d.sigma_dx_mm - 0.1 * 2f64.sqrt()).abs() < 1e-9);
        assert!(d.significant);
        assert!((d.velocity_mm_per_day.unwrap() - 2.5).abs() < 1e-9);
        let zero = displacement(&r, &r, None, None, 0.99);
        assert_eq!(
            (zero.d_mm, zero.sigma_mm, zero.significant),
            (0.0, 0.0, false)
        );
    }

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
