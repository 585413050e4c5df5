//! Sites: a monitored cliff with its model, schedule, confidence and alert rules.

use serde::{Deserialize, Serialize};
use sqlx::{AnyConnection, AnyExecutor, FromRow};
use utoipa::ToSchema;

use super::{display_timestamp, now, StoreError};
use cliffwatch_core::analysis::site_frame::SiteFrame;
use cliffwatch_core::detect::settings::DetectionSettings;
use cliffwatch_core::photogrammetry::Model;

/// The version of the derived series (displacements, filtered values, block motions) this binary
/// writes. Sites stored by an older one (`sites.analysis_version` below it) are recomputed once at
/// start ([`crate::service::recompute::recompute_outdated`]); a new site starts at it. 2: block
/// motions with the joint covariance of their points, forecasts weighed by the epochs' own errors;
/// 3: the forecast's law fitted to the displacements in three dimensions; 4: time-to-failure
/// rules read at 0.95 by default (the alert state is replayed with the series); 5: a block's
/// motion series has its row at the reference epoch (zero), as its points' series do; 6: a block
/// needs 2 measured members for a motion (a one-point block repeated its point's alerts); 7:
/// filtered velocity and forecast at a reference moved later in the series, and measured from the
/// window's start rather than from that reference; 8: `reference_unstable` names a stable point
/// excluded in 2 of 3 epochs and lets it go after 10 kept (the alert state is replayed, so an
/// alert the older rule left open for good resolves where the series no longer confirms it); 9:
/// it counts only the exclusions in which the point also changed from its own earlier epochs
/// (`DatumReport::moved`), so a point whose reference coordinates erred is no longer named;
/// 10: forecasts fitted to daily means of epochs that come more often than daily, over the
/// last 40 days of them, and the pooled forecasts stored (series derived before have none).
pub const ANALYSIS_VERSION: i64 = 10;

/// A site as created (`POST /api/v1/sites` or `[[sites]]` of the configuration).
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct NewSite {
    /// Identifier, `[A-Za-z0-9._-]{1,64}`.
    #[schema(pattern = "^[A-Za-z0-9._-]{1,64}$")]
    pub id: String,
    /// Display name (default: the id), at most 200 characters, without the NUL character.
    #[serde(default)]
    #[schema(pattern = "^[^\\u0000]*$", max_length = 200)]
    pub name: Option<String>,
    /// `orthogonal` (default) or `central`.
    #[serde(default)]
    pub model: Option<Model>,
    /// Expected interval between campaigns in hours (> 0).
    #[serde(default)]
    #[schema(exclusive_minimum = 0.0)]
    pub schedule_hours: Option<f64>,
    /// Confidence level of the significance tests and the alert rules, one-sided (default 0.99;
    /// 0.500001 to 0.999999); time-to-failure rules read at most 0.95 unless they set their own.
    #[serde(default)]
    #[schema(minimum = 0.500_001, maximum = 0.999_999)]
    pub confidence: Option<f64>,
    /// Alert rules (`{"level", "metric", "above"|"below", "clear_below"|"clear_above", "source",
    /// "for_epochs", "group", "confidence"}`).
    #[serde(default)]
    #[schema(value_type = Option<Vec<cliffwatch_core::analysis::alerts::AlertRule>>)]
    pub alert_rules: Option<Vec<serde_json::Value>>,
    /// Epochs averaged into the reference (covariance-weighted, in the stable-point datum), ≥ 1
    /// (default 1).
    #[serde(
        default,
        deserialize_with = "cliffwatch_core::contract::json_integer::optional_i64"
    )]
    #[schema(minimum = 1, maximum = 100)]
    pub reference_epochs: Option<i64>,
    /// Process noise of the points' Kalman filter (white jerk, mm²/day⁵; > 0; default 0.05).
    #[serde(default)]
    #[schema(exclusive_minimum = 0.0)]
    pub process_noise: Option<f64>,
    /// The site's IANA time zone, e.g. `Asia/Tokyo`: the dashboard shows times in UTC and in it
    /// (default: UTC only).
    #[serde(default)]
    #[schema(max_length = 64, example = "Asia/Tokyo")]
    pub time_zone: Option<String>,
    /// Where the site's warnings apply (the area of its CAP messages; default: the site's name).
    #[serde(default)]
    pub area: Option<crate::cap::SiteArea>,
    /// What the staff on call are to do when the site alerts (plain text, at most 2000
    /// characters), shown in the headline of every page of the site.
    #[serde(default)]
    #[schema(max_length = 2000)]
    pub response_text: Option<String>,
    /// Whom to call, one entry each (`"Geotechnical engineer on call: +81 …"`; at most 20 of 1 to
    /// 200 characters), shown under the response text.
    #[serde(default)]
    #[schema(max_items = 20)]
    pub contacts: Option<Vec<String>>,
    /// How the watched directory weights the site's image observations: `camera` (default: the
    /// camera's one a-priori `sigma_mm`) or `target` (each detected target's own σ).
    #[serde(default)]
    pub image_weights: Option<ImageWeights>,
    /// The frame's orientation: its up axis (default `[0, 0, 1]`, as in E, N, Up) and the
    /// face's outward normal (default: from the stable points' plane); the face plan and the
    /// along / height / out-of-face components read it.
    #[serde(default)]
    pub frame: Option<SiteFrame>,
    /// Which a-priori σ of the image coordinates the site's adjustments use: `upload` (default:
    /// each camera's `sigma_mm` as uploaded) or `estimated` (each camera's σ estimated from the
    /// variance components of the site's last epochs, once there are enough of them).
    #[serde(default)]
    pub apriori_sigma: Option<AprioriSigma>,
    /// How the watched directory detects the site's targets: `polarity` (`auto`, `bright`,
    /// `dark`), `min_diameter_px`, `max_diameter_px`; a folder's `epoch.json` may override each
    /// (default: auto, 2.5 to 64 px).
    #[serde(default)]
    pub detection: Option<DetectionSettings>,
}

/// Which a-priori σ of the image coordinates a site's adjustments use.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum AprioriSigma {
    /// Each camera's `sigma_mm` as uploaded (or its default).
    #[default]
    Upload,
    /// Each camera's σ pooled from the variance components of the site's last epochs.
    Estimated,
}

impl AprioriSigma {
    /// `"upload"` or `"estimated"`.
    pub fn as_str(self) -> &'static str {
        match self {
            AprioriSigma::Upload => "upload",
            AprioriSigma::Estimated => "estimated",
        }
    }
}

/// How a site's detected image observations are weighted in its adjustment.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum ImageWeights {
    /// One a-priori σ per camera (its `sigma_mm`).
    #[default]
    Camera,
    /// Each target's own σ from detection (`Target::sigma_col_px`, `sigma_row_px`, their mean, in
    /// mm through the pixel size).
    Target,
}

impl ImageWeights {
    /// `"camera"` or `"target"`.
    pub fn as_str(self) -> &'static str {
        match self {
            ImageWeights::Camera => "camera",
            ImageWeights::Target => "target",
        }
    }
}

/// A stored site.
#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct Site {
    /// Identifier.
    pub id: String,
    /// Display name.
    pub name: String,
    /// Projection model.
    pub model: Model,
    /// Expected interval between campaigns in hours.
    pub schedule_hours: Option<f64>,
    /// Confidence level of the significance tests.
    pub confidence: f64,
    /// Alert rules (JSON objects).
    #[schema(value_type = Vec<Object>)]
    pub alert_rules: Vec<serde_json::Value>,
    /// Explicit reference epoch; `null`: the earliest.
    pub reference_epoch: Option<i64>,
    /// Epochs averaged into the reference from the reference epoch on.
    pub reference_epochs: i64,
    /// Process noise of the points' Kalman filter (mm²/day⁵); `null`: the default.
    pub process_noise: Option<f64>,
    /// IANA time zone; `null`: UTC only.
    pub time_zone: Option<String>,
    /// Where the site's warnings apply; `null`: not configured.
    pub area: Option<crate::cap::SiteArea>,
    /// What the staff on call are to do; `null`: not configured.
    pub response_text: Option<String>,
    /// Whom to call (empty: not configured).
    pub contacts: Vec<String>,
    /// How the watched directory weights the image observations.
    pub image_weights: ImageWeights,
    /// The frame's orientation (up axis, face normal when declared).
    pub frame: SiteFrame,
    /// Which a-priori σ the adjustments use.
    pub apriori_sigma: AprioriSigma,
    /// How the watched directory detects the targets (fields not given: the defaults).
    pub detection: DetectionSettings,
    /// Creation time (RFC 3339).
    pub created_at: String,
    /// When the site was retired (RFC 3339): no more uploads, its pages kept; absent while it
    /// is in service.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub retired_at: Option<String>,
    /// Why it was retired (given with the retirement); absent while it is in service.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub retired_reason: Option<String>,
    /// When its data was last exported (`GET .../export`, RFC 3339); absent if never.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub exported_at: Option<String>,
}

#[derive(FromRow)]
struct SiteRow {
    id: String,
    name: String,
    #[sqlx(try_from = "String")]
    model: Model,
    schedule_hours: Option<f64>,
    confidence: f64,
    alert_rules: String,
    reference_epoch: Option<i64>,
    reference_epochs: i64,
    process_noise: Option<f64>,
    time_zone: Option<String>,
    area: Option<String>,
    response_text: Option<String>,
    contacts: Option<String>,
    image_weights: Option<String>,
    frame: Option<String>,
    apriori_sigma: Option<String>,
    detection: Option<String>,
    created_at: String,
    retired_at: Option<String>,
    retired_reason: Option<String>,
    exported_at: Option<String>,
}

impl TryFrom<SiteRow> for Site {
    type Error = StoreError;
    fn try_from(r: SiteRow) -> Result<Site, StoreError> {
        let image_weights = match r.image_weights.as_deref() {
            None | Some("camera") => ImageWeights::Camera,
            Some("target") => ImageWeights::Target,
            Some(other) => {
                return Err(StoreError::Corrupt(format!(
                    "site '{}': image_weights '{other}'",
                    r.id
                )))
            }
        };
        let apriori_sigma = match r.apriori_sigma.as_deref() {
            None | Some("upload") => AprioriSigma::Upload,
            Some("estimated") => AprioriSigma::Estimated,
            Some(other) => {
                return Err(StoreError::Corrupt(format!(
                    "site '{}': apriori_sigma '{other}'",
                    r.id
                )))
            }
        };
        Ok(Site {
            id: r.id,
            name: r.name,
            model: r.model,
            schedule_hours: r.schedule_hours,
            confidence: r.confidence,
            alert_rules: serde_json::from_str(&r.alert_rules)?,
            reference_epoch: r.reference_epoch,
            reference_epochs: r.reference_epochs,
            process_noise: r.process_noise,
            time_zone: r.time_zone,
            area: r.area.as_deref().map(serde_json::from_str).transpose()?,
            response_text: r.response_text,
            contacts: r
                .contacts
                .as_deref()
                .map(serde_json::from_str)
                .transpose()?
                .unwrap_or_default(),
            image_weights,
            frame: r
                .frame
                .as_deref()
                .map(serde_json::from_str)
                .transpose()?
                .unwrap_or_default(),
            apriori_sigma,
            detection: r
                .detection
                .as_deref()
                .map(serde_json::from_str)
                .transpose()?
                .unwrap_or_default(),
            created_at: display_timestamp(&r.created_at),
            retired_at: r.retired_at.as_deref().map(display_timestamp),
            retired_reason: r.retired_reason,
            exported_at: r.exported_at.as_deref().map(display_timestamp),
        })
    }
}

const COLUMNS: &str =
    "id, name, model, schedule_hours, confidence, alert_rules, reference_epoch, reference_epochs, \
     process_noise, time_zone, area, response_text, contacts, image_weights, frame, apriori_sigma, detection, created_at, \
     retired_at, retired_reason, exported_at";

/// Reads one site.
pub async fn get(db: impl AnyExecutor<'_>, id: &str) -> Result<Option<Site>, StoreError> {
    let row: Option<SiteRow> =
        sqlx::query_as(&format!("SELECT {COLUMNS} FROM sites WHERE id = $1"))
            .bind(id)
            .fetch_optional(db)
            .await?;
    row.map(Site::try_from).transpose()
}

/// Lists sites newest first; `after` is the `(created_at, id)` cursor of the previous page.
pub async fn list(
    db: impl AnyExecutor<'_>,
    after: Option<(&str, &str)>,
    limit: i64,
) -> Result<Vec<Site>, StoreError> {
    let rows: Vec<SiteRow> = match after {
        None => {
            sqlx::query_as(&format!(
                "SELECT {COLUMNS} FROM sites ORDER BY created_at DESC, id DESC LIMIT $1"
            ))
            .bind(limit)
            .fetch_all(db)
            .await?
        }
        Some((t, id)) => {
            sqlx::query_as(&format!(
            "SELECT {COLUMNS} FROM sites WHERE created_at < $1 OR (created_at = $2 AND id < $3) \
                 ORDER BY created_at DESC, id DESC LIMIT $4"
        ))
            .bind(t)
            .bind(t)
            .bind(id)
            .bind(limit)
            .fetch_all(db)
            .await?
        }
    };
    rows.into_iter().map(Site::try_from).collect()
}

/// Raw `created_at` of a site (for cursors).
pub async fn created_at_raw(
    db: impl AnyExecutor<'_>,
    id: &str,
) -> Result<Option<String>, StoreError> {
    Ok(
        sqlx::query_scalar("SELECT created_at FROM sites WHERE id = $1")
            .bind(id)
            .fetch_optional(db)
            .await?,
    )
}

/// Creates a site; `Ok(false)` when the id exists already.
pub async fn insert(db: &mut AnyConnection, site: &NewSite) -> Result<bool, StoreError> {
    if get(&mut *db, &site.id).await?.is_some() {
        return Ok(false);
    }
    write(db, site, true).await?;
    Ok(true)
}

/// Creates a site or replaces its settings (configuration file).
pub async fn upsert(db: &mut AnyConnection, site: &NewSite) -> Result<(), StoreError> {
    let exists = get(&mut *db, &site.id).await?.is_some();
    write(db, site, !exists).await
}

async fn write(db: &mut AnyConnection, site: &NewSite, create: bool) -> Result<(), StoreError> {
    let rules = serde_json::to_string(&site.alert_rules.clone().unwrap_or_default())?;
    let name = site.name.clone().unwrap_or_else(|| site.id.clone());
    let model = site.model.unwrap_or_default().as_str();
    let confidence = site.confidence.unwrap_or(0.99);
    let reference_epochs = site.reference_epochs.unwrap_or(1);
    let area = site.area.as_ref().map(serde_json::to_string).transpose()?;
    let contacts = site
        .contacts
        .as_ref()
        .filter(|c| !c.is_empty())
        .map(serde_json::to_string)
        .transpose()?;
    let image_weights = site.image_weights.map(ImageWeights::as_str);
    let frame = site.frame.as_ref().map(serde_json::to_string).transpose()?;
    let apriori_sigma = site.apriori_sigma.map(AprioriSigma::as_str);
    let detection = site
        .detection
        .filter(|d| !d.is_empty())
        .as_ref()
        .map(serde_json::to_string)
        .transpose()?;
    if create {
        let at = now(&mut *db).await?;
        sqlx::query(
            "INSERT INTO sites (id, name, model, schedule_hours, confidence, alert_rules, \
             reference_epochs, process_noise, time_zone, area, response_text, contacts, created_at, \
             analysis_version, image_weights, frame, apriori_sigma, detection) \
             VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9, $10, $11, $12, $13, $14, $15, $16, $17, $18)",
        )
        .bind(&site.id)
        .bind(name)
        .bind(model)
        .bind(site.schedule_hours)
        .bind(confidence)
        .bind(rules)
        .bind(reference_epochs)
        .bind(site.process_noise)
        .bind(site.time_zone.as_deref())
        .bind(area.as_deref())
        .bind(site.response_text.as_deref())
        .bind(contacts.as_deref())
        .bind(&at)
        .bind(ANALYSIS_VERSION)
        .bind(image_weights)
        .bind(frame.as_deref())
        .bind(apriori_sigma)
        .bind(detection.as_deref())
        .execute(db)
        .await?;
    } else {
        sqlx::query(
            "UPDATE sites SET name = $1, model = $2, schedule_hours = $3, confidence = $4, alert_rules = $5, \
             reference_epochs = $6, process_noise = $7, time_zone = $8, area = $9, response_text = $10, \
             contacts = $11, image_weights = $12, frame = $13, apriori_sigma = $14, detection = $15 WHERE id = $16",
        )
        .bind(name)
        .bind(model)
        .bind(site.schedule_hours)
        .bind(confidence)
        .bind(rules)
        .bind(reference_epochs)
        .bind(site.process_noise)
        .bind(site.time_zone.as_deref())
        .bind(area.as_deref())
        .bind(site.response_text.as_deref())
        .bind(contacts.as_deref())
        .bind(image_weights)
        .bind(frame.as_deref())
        .bind(apriori_sigma)
        .bind(detection.as_deref())
        .bind(&site.id)
        .execute(db)
        .await?;
    }
    Ok(())
}

/// Sets (or clears) the explicit reference epoch.
pub async fn set_reference(
    db: impl AnyExecutor<'_>,
    site: &str,
    epoch: Option<i64>,
) -> Result<(), StoreError> {
    sqlx::query("UPDATE sites SET reference_epoch = $1 WHERE id = $2")
        .bind(epoch)
        .bind(site)
        .execute(db)
        .await?;
    Ok(())
}

/// Ids of the sites whose stored series an older binary derived (see [`ANALYSIS_VERSION`]).
pub async fn outdated(db: impl AnyExecutor<'_>) -> Result<Vec<String>, StoreError> {
    Ok(
        sqlx::query_scalar("SELECT id FROM sites WHERE analysis_version < $1 ORDER BY id")
            .bind(ANALYSIS_VERSION)
            .fetch_all(db)
            .await?,
    )
}

/// Whether the stored series of `site` was derived by an older binary (see [`ANALYSIS_VERSION`]).
pub async fn is_outdated(db: impl AnyExecutor<'_>, site: &str) -> Result<bool, StoreError> {
    let version: Option<i64> =
        sqlx::query_scalar("SELECT analysis_version FROM sites WHERE id = $1")
            .bind(site)
            .fetch_optional(db)
            .await?;
    Ok(version.is_some_and(|v| v < ANALYSIS_VERSION))
}

/// Marks the site's stored series as derived by this binary ([`ANALYSIS_VERSION`]).
pub async fn mark_current(db: impl AnyExecutor<'_>, site: &str) -> Result<(), StoreError> {
    sqlx::query("UPDATE sites SET analysis_version = $1 WHERE id = $2")
        .bind(ANALYSIS_VERSION)
        .bind(site)
        .execute(db)
        .await?;
    Ok(())
}

/// Ids of the sites in service (not retired) with a campaign schedule (`schedule_hours` set).
pub async fn scheduled(db: impl AnyExecutor<'_>) -> Result<Vec<String>, StoreError> {
    Ok(sqlx::query_scalar(
        "SELECT id FROM sites WHERE schedule_hours IS NOT NULL AND retired_at IS NULL ORDER BY id",
    )
    .fetch_all(db)
    .await?)
}

/// Marks `site` retired at `at` (store format) for `reason`.
pub async fn retire(
    db: impl AnyExecutor<'_>,
    site: &str,
    at: &str,
    reason: &str,
) -> Result<(), StoreError> {
    sqlx::query("UPDATE sites SET retired_at = $1, retired_reason = $2 WHERE id = $3")
        .bind(at)
        .bind(reason)
        .bind(site)
        .execute(db)
        .await?;
    Ok(())
}

/// Records that the data of `site` was exported at `at` (store format).
pub async fn mark_exported(
    db: impl AnyExecutor<'_>,
    site: &str,
    at: &str,
) -> Result<(), StoreError> {
    sqlx::query("UPDATE sites SET exported_at = $1 WHERE id = $2")
        .bind(at)
        .bind(site)
        .execute(db)
        .await?;
    Ok(())
}

/// Raw `retired_at` and `exported_at` of `site` (store format, comparable as text); `None`
/// when there is no such site.
pub async fn retirement_raw(
    db: impl AnyExecutor<'_>,
    site: &str,
) -> Result<Option<(Option<String>, Option<String>)>, StoreError> {
    Ok(
        sqlx::query_as("SELECT retired_at, exported_at FROM sites WHERE id = $1")
            .bind(site)
            .fetch_optional(db)
            .await?,
    )
}
