//! Ingestion of one epoch, the one path used by the HTTP API and the watched directory:
//! validate → (site history as start values) → adjust in `spawn_blocking` → store the epoch and
//! everything derived from it (coordinates, displacements, alerts, outbox) in **one** write
//! transaction, or nothing.
//!
//! Idempotency: the sha256 of [`EpochInput::canonical_json`] is stored with the epoch; the same body
//! again returns the stored epoch, another body for the same `observed_at` is a conflict.

use std::collections::BTreeMap;
use std::time::Instant;

use chrono::{DateTime, Utc};
use sha2::{Digest, Sha256};

use crate::store::block_motions;
use crate::store::displacements;
use crate::store::pooled_forecasts::{self, PooledForecast};
use crate::store::sites::{AprioriSigma, Site};
use crate::store::{self, epochs, groups, points, sites, watch_state, Connection, Store};
use cliffwatch_core::analysis::{self, EpochCoordinates, GroupKind, History};
use cliffwatch_core::photogrammetry::{
    adjust_problem, AdjustOptions, Adjustment, EpochError, EpochInput,
};

use super::admission::{CancelOnDrop, UploadSlot};
use super::alert_outcome;
use super::analysis_inputs::{
    analysis_config, history, history_reach, point_configs, reference_coordinates, reference_epoch,
    reference_window, site_analysis_config, to_rows,
};
use super::apriori_sigma;
use super::{recompute, ServiceError};

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
/// [`JOINT_COVARIANCE_ALL_POINTS_MAX`] points, else the stable ones and the members of the
/// declared blocks (`kept`). The displacement analysis propagates the stable-point datum with the
/// cross-covariances between each point and the datum points (without them the depth σ of
/// displacements came out 8 % optimistic in `crates/cliffwatch-core/tests/adjust/calibration.rs`), and a block's motion
/// uses those between its members.
pub fn joint_covariance_points(points: &[String], kept: Vec<String>) -> Vec<String> {
    if points.len() <= JOINT_COVARIANCE_ALL_POINTS_MAX {
        points.to_vec()
    } else {
        let mut kept = kept;
        kept.sort();
        kept.dedup();
        kept
    }
}

/// The site's stable points and the members of its declared blocks, for
/// [`joint_covariance_points`].
async fn stable_and_block_points(
    db: &mut Connection,
    site: &str,
) -> Result<Vec<String>, ServiceError> {
    let mut names = points::stable(&mut *db, site).await?;
    let blocks = groups::list(&mut *db, site).await?;
    if blocks.iter().any(|g| g.kind == GroupKind::Block) {
        let configs = point_configs(&mut *db, site).await?;
        for g in blocks.iter().filter(|g| g.kind == GroupKind::Block) {
            names.extend(g.members(&configs));
        }
    }
    Ok(names)
}

/// The largest epoch a node takes, checked before any computation (configuration
/// `max_epoch_points`, `max_epoch_observations`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct EpochLimits {
    /// Most distinct points an epoch may name (observed, known or approximated).
    pub points: usize,
    /// Most image observations over all of an epoch's images.
    pub observations: usize,
}

impl Default for EpochLimits {
    /// The configuration's defaults (20 000 points, 200 000 observations).
    fn default() -> Self {
        EpochLimits {
            points: crate::config::DEFAULT_MAX_EPOCH_POINTS,
            observations: crate::config::DEFAULT_MAX_EPOCH_OBSERVATIONS,
        }
    }
}

impl EpochLimits {
    /// The limits of the configuration.
    pub fn from_config(config: &crate::config::Config) -> Self {
        EpochLimits {
            points: config.max_epoch_points,
            observations: config.max_epoch_observations,
        }
    }

    /// Refuses an epoch over a limit ([`ServiceError::TooLarge`], naming the limit and its
    /// setting).
    pub fn check(&self, input: &EpochInput) -> Result<(), ServiceError> {
        let observations: usize = input.images.iter().map(|i| i.observations.len()).sum();
        if observations > self.observations {
            return Err(ServiceError::TooLarge {
                what: "image observations",
                count: observations,
                limit: self.observations,
                setting: "max_epoch_observations",
            });
        }
        let names = input
            .images
            .iter()
            .flat_map(|i| i.observations.iter().map(|o| &o.point));
        let names = names
            .chain(input.control.iter().map(|c| &c.point))
            .chain(input.approx.iter().map(|a| &a.point));
        let points = names.collect::<std::collections::HashSet<_>>().len();
        if points > self.points {
            return Err(ServiceError::TooLarge {
                what: "points",
                count: points,
                limit: self.points,
                setting: "max_epoch_points",
            });
        }
        Ok(())
    }
}

/// Ingests one epoch of the upload form into a site, holding the upload `slot` until the
/// adjustment has ended. The adjustment stops within one iteration once the slot's compute
/// budget is spent (the answer is then [`AdjustError::Cancelled`]) or once this future is
/// dropped (the client answered by the request time limit, or gone), so the slot is free again
/// within a moment of the answer. The bodies of the alert events it writes link under
/// `public_url` (the configuration's).
///
/// [`AdjustError::Cancelled`]: cliffwatch_core::photogrammetry::AdjustError::Cancelled
pub async fn ingest(
    store: &Store,
    site_id: &str,
    input: EpochInput,
    limits: EpochLimits,
    slot: UploadSlot,
    public_url: Option<&str>,
) -> Result<Ingested, ServiceError> {
    limits.check(&input)?;
    ingest_with_identification(store, site_id, input, None, Some(slot), public_url).await
}

/// The watched folder an epoch comes from.
pub struct WatchedFolder {
    /// The folder's content hash ([`crate::watch::content_hash`]), recorded in the epoch's own
    /// transaction: a daemon that dies right after the commit finds the folder taken on restart.
    pub hash: String,
    /// How each station's targets were identified (per station method and counts), stored with
    /// the epoch's report.
    pub identification: serde_json::Value,
}

/// [`ingest`] of an epoch from the watched directory `folder`.
pub async fn ingest_watched(
    store: &Store,
    site_id: &str,
    input: EpochInput,
    limits: EpochLimits,
    folder: &WatchedFolder,
    public_url: Option<&str>,
) -> Result<Ingested, ServiceError> {
    limits.check(&input)?;
    ingest_with_identification(store, site_id, input, Some(folder), None, public_url).await
}

/// How far after the server's clock an epoch's `observed_at` may lie, in days. An epoch from
/// the future (a mistyped year, a camera clock set wrong) would sort after every real epoch to
/// come: each of them would then arrive "earlier", recompute the site, and be announced only as
/// the net change up to that future epoch. A year's tolerance keeps clock skew and time zones far
/// inside it and catches a wrong year.
pub const MAX_DAYS_AHEAD: i64 = 366;

async fn ingest_with_identification(
    store: &Store,
    site_id: &str,
    input: EpochInput,
    folder: Option<&WatchedFolder>,
    slot: Option<UploadSlot>,
    public_url: Option<&str>,
) -> Result<Ingested, ServiceError> {
    // The form, then its units by orders of magnitude (mm for m, c in metres, pixels as mm).
    let mut problem = cliffwatch_core::photogrammetry::input::plausible::validate(&input)?;
    let now = Utc::now();
    if problem.observed_at > now + chrono::Duration::days(MAX_DAYS_AHEAD) {
        return Err(EpochError::TimestampAhead {
            observed_at: input.observed_at.clone(),
            now: store::timestamp(now),
            days: MAX_DAYS_AHEAD,
        }
        .into());
    }
    // The reads before the adjustment on one connection (one acquisition, and on PostgreSQL
    // one connection check, instead of one per read).
    let mut db = store.read().await?;
    let site = sites::get(&mut *db, site_id)
        .await?
        .ok_or_else(|| ServiceError::UnknownSite(site_id.to_string()))?;
    super::sites::ensure_in_service(&site)?;
    let observed_at = store::timestamp(problem.observed_at);
    let hash = body_hash(&input);
    if let Some(done) = check_existing(&mut db, &site.id, &observed_at, &hash).await? {
        return Ok(done);
    }

    let prior: BTreeMap<String, [f64; 3]> = points::latest_coordinates(&mut db, &site.id)
        .await?
        .into_iter()
        .map(|c| (c.point, c.xyz))
        .collect();
    // Dropping this future (the client answered or gone) cancels the adjustment it starts.
    let cancel = slot
        .as_ref()
        .map(|s| s.cancel().clone())
        .unwrap_or_default();
    let _cancel_when_dropped = CancelOnDrop(cancel.clone());
    let options = AdjustOptions {
        model: site.model,
        prior,
        joint_covariance_of: joint_covariance_points(
            &problem.points,
            stable_and_block_points(&mut db, &site.id).await?,
        ),
        variance_components: true,
        cancel,
        ..AdjustOptions::default()
    };
    let apriori_sigma_estimated = match site.apriori_sigma {
        AprioriSigma::Estimated => {
            let estimate = apriori_sigma::estimate(&mut db, &site.id, Some(&observed_at)).await?;
            Some(apriori_sigma::apply(&mut problem, &estimate)).filter(|a| !a.is_empty())
        }
        AprioriSigma::Upload => None,
    };
    drop(db);
    let started = Instant::now();
    // The slot goes with the blocking task and comes back when it ends (a dropped caller
    // leaves it with the task).
    let (adjustment, _slot) = tokio::task::spawn_blocking(move || {
        let adjustment = adjust_problem(&problem, &options);
        (adjustment, slot)
    })
    .await?;
    metrics::histogram!("cliffwatch_adjustment_seconds").record(started.elapsed().as_secs_f64());
    let outcome = if adjustment.is_ok() { "ok" } else { "failed" };
    metrics::counter!("cliffwatch_adjustments_total", "outcome" => outcome).increment(1);
    let adjustment = adjustment?;

    let mut tx = store.begin_write_site(&site.id).await?;
    // Another upload of the same observed_at may have committed while this one adjusted.
    if let Some(done) = check_existing(&mut tx, &site.id, &observed_at, &hash).await? {
        return Ok(done);
    }
    // The site's settings as of the lock: a reference change (or rules, confidence, process noise)
    // committed while this epoch adjusted has recomputed the site, and this epoch follows it.
    let site = sites::get(&mut *tx, &site.id)
        .await?
        .ok_or_else(|| ServiceError::UnknownSite(site.id.clone()))?;
    // Retired while this epoch adjusted: refused all the same.
    super::sites::ensure_in_service(&site)?;
    // The history the analysis needs is read on its own connection while `tx` stores the epoch.
    let history = HistoryPrefetch::start(store, &site, &observed_at);
    let control: Vec<String> = input.control.iter().map(|c| c.point.clone()).collect();
    // The transaction's time on the store's clock, read once: the epoch, its alerts and their
    // outbox messages record the same time, whichever node wrote them.
    let now = store::clock(&mut tx).await?;
    let record = epochs::EpochRecord {
        site: &site.id,
        observed_at: &observed_at,
        body_sha256: &hash,
        input: &input,
        adjustment: &adjustment,
        control_points: &control,
        identification: folder.map(|f| &f.identification),
        apriori_sigma_estimated: apriori_sigma_estimated.as_deref(),
        created_at: now,
    };
    let epoch = epochs::insert(&mut tx, &record).await?;
    if let Some(f) = folder {
        watch_state::record_folder(&mut tx, &site.id, &f.hash, epoch, now).await?;
    }
    let raised = derive(
        &mut tx,
        &site,
        epoch,
        &observed_at,
        &adjustment,
        history,
        now,
        public_url,
    )
    .await?;
    tx.commit().await.map_err(store::StoreError::from)?;
    super::alert_outcome::count_raised(raised);
    Ok(Ingested {
        site: site.id,
        epoch,
        created: true,
    })
}

async fn check_existing(
    db: &mut Connection,
    site: &str,
    observed_at: &str,
    hash: &str,
) -> Result<Option<Ingested>, ServiceError> {
    match epochs::find_by_time(db, site, observed_at).await? {
        None => Ok(None),
        Some(k) if k.body_sha256 == hash => Ok(Some(Ingested {
            site: site.to_string(),
            epoch: k.id,
            created: false,
        })),
        Some(k) => Err(ServiceError::Conflict {
            site: site.to_string(),
            observed_at: store::display_timestamp(observed_at),
            epoch: k.id,
        }),
    }
}

/// The history of a new epoch ([`history`]: the last committed displacements before it), read
/// on a task of its own from when the epoch's write transaction holds the site's lock, so that
/// its round trips overlap the transaction's writes. Dropped unused (an epoch out of order
/// recomputes the site instead), it is cancelled.
struct HistoryPrefetch(tokio::task::JoinHandle<Result<History, store::StoreError>>);

impl HistoryPrefetch {
    fn start(store: &Store, site: &Site, observed_at: &str) -> HistoryPrefetch {
        let (store, site_id, before) = (store.clone(), site.id.clone(), observed_at.to_string());
        let reach = history_reach(&analysis_config(site), &before);
        HistoryPrefetch(tokio::spawn(async move {
            history(&store, &site_id, &before, &reach).await
        }))
    }

    async fn get(mut self) -> Result<History, ServiceError> {
        Ok((&mut self.0).await??)
    }
}

impl Drop for HistoryPrefetch {
    fn drop(&mut self) {
        self.0.abort();
    }
}

/// THE seam of the displacement analysis and the alert rules: runs inside the epoch's write
/// transaction, which holds the site's write lock, so the history (`history`, read from the last
/// commit while `tx` holds the lock) is consistent with what is written.
///
/// Loads the reference epoch's coordinates (with the stable points' joint covariance), the point
/// configurations and the history the windows need, runs [`cliffwatch_core::analysis::analyse_epoch`] on a
/// blocking thread, writes every row derived from the epoch (displacements, the declared blocks'
/// motions, the pooled forecasts), then evaluates the site's alert rules and writes the alert
/// state, the alerts and the webhook outbox, all at `now` (the transaction's time on the store's
/// clock); returns how many alerts it raised. An out-of-order epoch recomputes the whole site
/// instead ([`recompute::recompute_site`]). An epoch whose
/// analysis fails (e.g. too few points in common with the reference) is stored without
/// displacements, with status `analysis_failed`, the reason in its report (`analysis_error`) and
/// a site-level `analysis_failed` alert for the staff. The events' bodies link under
/// `public_url`.
#[allow(clippy::too_many_arguments)]
async fn derive(
    tx: &mut Connection,
    site: &Site,
    epoch: i64,
    observed_at: &str,
    adjustment: &Adjustment,
    history: HistoryPrefetch,
    now: DateTime<Utc>,
    public_url: Option<&str>,
) -> Result<usize, ServiceError> {
    let later = epochs::count_after(&mut *tx, &site.id, observed_at).await?;
    let reference = reference_epoch(tx, site).await?.unwrap_or(epoch);
    // An epoch inside a reference of several epochs changes the reference itself.
    let in_reference = site.reference_epochs > 1
        && reference != epoch
        && reference_window(tx, site, reference)
            .await?
            .contains(&epoch);
    if later > 0 || in_reference {
        // Out of order: later epochs' histories (velocities, forecasts) and, when this epoch is the
        // earliest without a set reference, the reference itself change. Recompute the series.
        let cause = recompute::RecomputeCause::EarlierEpoch(epoch);
        let mut raised = recompute::recompute_site(tx, &site.id, &cause, public_url).await?;
        // The newest epoch, inside a reference of several: a campaign arrived on time after all
        // (a recompute keeps `campaign_overdue` as it was; it depends on the clock).
        if let (0, Some(t)) = (later, store::parse_timestamp(observed_at)) {
            raised += alert_outcome::campaign_arrived(tx, site, epoch, t, now, public_url).await?;
        }
        return Ok(raised);
    }
    let Some(t) = store::parse_timestamp(observed_at) else {
        return Ok(0);
    };
    let current = EpochCoordinates::from_adjustment(epoch, t, adjustment);
    let config = site_analysis_config(tx, site).await?;
    let points = point_configs(&mut *tx, &site.id).await?;
    let reference = if reference == epoch {
        current.clone()
    } else {
        match reference_coordinates(tx, site, reference, &points, &config).await? {
            Some(r) => r,
            None => {
                let reason = format!("the reference epoch {reference} has no coordinates");
                return failed(tx, site, epoch, t, &reason, now, public_url).await;
            }
        }
    };
    let reference_id = reference.epoch;
    let history = history.get().await?;
    let analysis = tokio::task::spawn_blocking(move || {
        analysis::analyse_epoch(&reference, &current, &points, &history, &config)
    })
    .await?;
    let analysis = match analysis {
        Ok(a) => a,
        Err(e) => {
            let reason = format!("analysis against reference epoch {reference_id}: {e}");
            return failed(tx, site, epoch, t, &reason, now, public_url).await;
        }
    };
    for w in &analysis.warnings {
        tracing::warn!(site = %site.id, epoch, "analysis: {w}");
    }
    let displacements = to_rows(&analysis.records(), analysis.reference_epoch);
    displacements::insert(tx, &site.id, &displacements).await?;
    let block_motions = to_rows(&analysis.block_records(), analysis.reference_epoch);
    block_motions::insert(tx, &site.id, &block_motions).await?;
    let pooled: Vec<PooledForecast> = analysis
        .pooled()
        .into_iter()
        .map(|(point, pooled_with)| PooledForecast {
            epoch,
            point,
            pooled_with,
        })
        .collect();
    pooled_forecasts::insert(tx, &site.id, &pooled).await?;
    Ok(alert_outcome::evaluate(tx, site, &analysis, now, public_url).await?)
}

/// Stores an epoch's failed analysis (see [`alert_outcome::analysis_failed`]) and logs it.
async fn failed(
    tx: &mut Connection,
    site: &Site,
    epoch: i64,
    t: DateTime<Utc>,
    reason: &str,
    now: DateTime<Utc>,
    public_url: Option<&str>,
) -> Result<usize, ServiceError> {
    tracing::warn!(site = %site.id, epoch, reason, "epoch stored without displacements");
    Ok(alert_outcome::analysis_failed(tx, site, epoch, t, reason, now, public_url).await?)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Small networks keep every point; larger ones the stable points and the blocks' members,
    /// each once, in order.
    #[test]
    fn joint_covariance_keeps_all_points_or_the_datum_and_the_blocks() {
        let names = |n: usize| (0..n).map(|i| format!("P{i:02}")).collect::<Vec<_>>();
        let small = names(JOINT_COVARIANCE_ALL_POINTS_MAX);
        assert_eq!(joint_covariance_points(&small, vec!["P01".into()]), small);
        let large = names(JOINT_COVARIANCE_ALL_POINTS_MAX + 1);
        let kept = vec!["P07".into(), "P01".into(), "P30".into(), "P07".into()];
        assert_eq!(
            joint_covariance_points(&large, kept),
            vec!["P01".to_string(), "P07".into(), "P30".into()]
        );
    }
}
