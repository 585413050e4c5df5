//! What the displacement analysis needs, loaded from the store: the site's analysis and alert
//! settings, its point configurations, an epoch's coordinates (with its joint covariance), the
//! reference coordinates (one epoch or the weighted mean of several) and the recent history of
//! every point. Read inside the caller's transaction, so what is analysed is what is written.

use std::collections::HashMap;

use crate::store::displacements::{self, Displacement};
use crate::store::sites::Site;
use crate::store::{self, epochs, joint_covariances, points, Connection, Store, StoreError};
use cliffwatch_core::analysis::{
    self, AlertConfig, AlertRule, AnalysisConfig, AnalysisError, DisplacementRecord,
    EpochCoordinates, History, PointConfig, PointCoordinates,
};

use super::ServiceError;

/// The analysis settings of a site (its `confidence` for the significance tests, its
/// `process_noise` for the Kalman filter; library defaults otherwise), without its groups (see
/// [`site_analysis_config`]).
pub fn analysis_config(site: &Site) -> AnalysisConfig {
    let mut config = AnalysisConfig {
        confidence: site.confidence,
        ..AnalysisConfig::default()
    };
    if let Some(q) = site.process_noise {
        config.kalman.process_noise = q;
    }
    config
}

/// [`analysis_config`] with the site's declared block groups.
pub async fn site_analysis_config(
    tx: &mut Connection,
    site: &Site,
) -> Result<AnalysisConfig, StoreError> {
    let mut config = analysis_config(site);
    config.groups = store::groups::list(&mut *tx, &site.id).await?;
    Ok(config)
}

/// The alert configuration of a site: its `alert_rules` (from the API or the configuration file;
/// rules that do not parse are skipped with a warning) and `schedule_hours`.
pub fn alert_config(site: &Site) -> AlertConfig {
    let rules: Vec<AlertRule> = site
        .alert_rules
        .iter()
        .filter_map(|v| match serde_json::from_value::<AlertRule>(v.clone()) {
            Ok(r) => Some(r),
            Err(e) => {
                tracing::warn!(site = %site.id, rule = %v, error = %e, "alert rule ignored");
                None
            }
        })
        .collect();
    let mut c = AlertConfig::new(site.id.clone(), rules);
    c.schedule_hours = site.schedule_hours;
    c.confidence = site.confidence;
    c
}

/// Role, group and direction of interest of every configured point of a site.
pub async fn point_configs(
    db: &mut Connection,
    site: &str,
) -> Result<Vec<PointConfig>, StoreError> {
    Ok(points::list(db, site, None, i64::MAX)
        .await?
        .into_iter()
        .map(|p| PointConfig {
            name: p.name,
            role: p.role,
            group: p.group,
            direction: p.direction,
        })
        .collect())
}

/// The stored coordinates of one epoch (with the joint covariance its adjustment stored) as
/// analysis input; `None` when the epoch has no coordinates.
pub async fn epoch_coordinates(
    tx: &mut Connection,
    site: &str,
    epoch: i64,
) -> Result<Option<EpochCoordinates>, StoreError> {
    let coords = points::epoch_coordinates(&mut *tx, site, epoch).await?;
    let Some(first) = coords.first() else {
        return Ok(None);
    };
    let Some(observed_at) = store::parse_timestamp(&first.observed_at) else {
        return Ok(None);
    };
    let joint = joint_covariances::get(&mut *tx, site, epoch).await?;
    Ok(Some(EpochCoordinates {
        epoch,
        observed_at,
        points: coords
            .into_iter()
            .map(|c| PointCoordinates {
                name: c.point,
                xyz_m: c.xyz,
                covariance_m2: c.covariance_m2,
            })
            .collect(),
        joint,
    }))
}

/// The reference epoch of a site: the one set, else its earliest epoch.
pub async fn reference_epoch(tx: &mut Connection, site: &Site) -> Result<Option<i64>, StoreError> {
    Ok(match site.reference_epoch {
        Some(r) => Some(r),
        None => epochs::earliest(&mut *tx, &site.id).await?,
    })
}

/// The ids of the epochs that make the reference: the reference epoch and the next
/// `reference_epochs − 1` epochs in time.
pub async fn reference_window(
    tx: &mut Connection,
    site: &Site,
    reference: i64,
) -> Result<Vec<i64>, StoreError> {
    epochs::window_from(&mut *tx, &site.id, reference, site.reference_epochs.max(1)).await
}

/// The reference coordinates of a site: those of `reference`, or with `reference_epochs` K > 1
/// the covariance-weighted mean of the K epochs from it on
/// ([`analysis::reference::combine_reference`], on a blocking thread). When those epochs cannot
/// be combined, the reference epoch alone (logged), so that an upload and a recompute always
/// agree. `None` when the reference epoch has no coordinates.
pub async fn reference_coordinates(
    tx: &mut Connection,
    site: &Site,
    reference: i64,
    points: &[PointConfig],
    config: &AnalysisConfig,
) -> Result<Option<EpochCoordinates>, ServiceError> {
    let Some(first) = epoch_coordinates(tx, &site.id, reference).await? else {
        return Ok(None);
    };
    if site.reference_epochs <= 1 {
        return Ok(Some(first));
    }
    let mut epochs = vec![first.clone()];
    for id in reference_window(tx, site, reference).await? {
        if id == reference {
            continue;
        }
        if let Some(e) = epoch_coordinates(tx, &site.id, id).await? {
            epochs.push(e);
        }
    }
    let (points, config) = (points.to_vec(), config.clone());
    let combined: Result<EpochCoordinates, AnalysisError> =
        tokio::task::spawn_blocking(move || {
            analysis::reference::combine_reference(&epochs, &points, &config)
        })
        .await?;
    Ok(Some(match combined {
        Ok(r) => r,
        Err(e) => {
            tracing::warn!(site = %site.id, reference, error = %e,
                "the reference epochs cannot be combined; the reference epoch alone is used");
            first
        }
    }))
}

/// How far back the analysis of an epoch observed at `before` (stored timestamp form) reads
/// each point's history under `config`: the records its windows count
/// ([`AnalysisConfig::history_epochs`]), and every record of the filter's bins
/// ([`AnalysisConfig::history_span_days`]: an hourly site's last 40 days), at most
/// [`cliffwatch_core::analysis::MAX_FILTER_EPOCHS`] per point.
pub fn history_reach(config: &AnalysisConfig, before: &str) -> displacements::Reach {
    let records = config.history_epochs();
    let span_ms = (config.history_span_days() * 86_400_000.0).ceil() as i64;
    let since = store::parse_timestamp(before)
        .and_then(|t| t.checked_sub_signed(chrono::Duration::milliseconds(span_ms)))
        .map(store::timestamp)
        .unwrap_or_else(|| before.to_string());
    displacements::Reach {
        records,
        since,
        cap: cliffwatch_core::analysis::MAX_FILTER_EPOCHS.max(records),
    }
}

/// The displacement records of every point observed before `before` (stored timestamp form)
/// that `reach` covers ([`history_reach`]), oldest first per point. One range scan of the
/// primary key (site, point, observed_at) per point, so the cost does not grow with the
/// length of the site's history.
/// It reads the last committed state on its own connection ([`displacements::recent`]): call
/// it while the epoch's write transaction holds the site's lock, before it commits.
pub async fn history(
    store: &Store,
    site: &str,
    before: &str,
    reach: &displacements::Reach,
) -> Result<History, StoreError> {
    let mut out: History = HashMap::new();
    for (point, mut rows) in displacements::recent(store, site, before, reach).await? {
        rows.reverse();
        let records: Vec<DisplacementRecord> =
            rows.iter().filter_map(Displacement::to_record).collect();
        if !records.is_empty() {
            out.insert(point, records);
        }
    }
    Ok(out)
}

/// The store's time-series rows of analysis records against `reference_epoch` (timestamps in the
/// stored form).
pub fn to_rows(records: &[DisplacementRecord], reference_epoch: i64) -> Vec<Displacement> {
    records
        .iter()
        .map(|r| Displacement::from_record(r, reference_epoch))
        .collect()
}
