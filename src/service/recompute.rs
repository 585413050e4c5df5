//! Recomputing a site's derived series after a change of its history: a new reference, an epoch
//! that arrived out of order, changed analysis settings or groups, or a series derived by an
//! older version. Runs inside the caller's write transaction, so the change and everything
//! derived from it commit together.

use crate::store::{
    self, block_motions, displacements, epochs, pooled_forecasts, sites, Connection, Store,
    StoreError,
};
use cliffwatch_core::analysis::{analyse_series, AlertKind, REFERENCE_INDEPENDENT};

use super::alert_outcome;
use super::analysis_inputs::{
    alert_config, epoch_coordinates, point_configs, reference_coordinates, reference_epoch,
    site_analysis_config, to_rows,
};
use super::ServiceError;

/// Recomputes the derived series of a site:
/// 1. every displacement against the current reference, epoch by epoch in time order, each with
///    the history recomputed before it (velocities, forecasts), and the declared blocks' motions
///    ([`analyse_series`], on a blocking thread);
/// 2. each epoch's analysis status (`adjusted` / `analysis_failed` with the reason);
/// 3. the alert state: the rules are replayed over the recomputed series and the stored state is
///    brought to the result by [`alert_outcome::reconcile`], which announces only the net
///    change now (raised, escalated, de-escalated, resolved) and never re-sends transitions staff
///    already received; open alerts keep their id and acknowledgement.
///
/// The site is read inside `tx`, so changes the caller made to it there (a new reference) count.
/// `cause` says why (a resolved alert's message ends with it); the event bodies link under
/// `public_url` ([`alert_outcome::record_events`]).
///
/// Returns how many alerts were raised.
pub async fn recompute_site(
    tx: &mut Connection,
    site_id: &str,
    cause: &RecomputeCause,
    public_url: Option<&str>,
) -> Result<usize, ServiceError> {
    let site = sites::get(&mut *tx, site_id)
        .await?
        .ok_or_else(|| ServiceError::UnknownSite(site_id.to_string()))?;
    sites::mark_current(&mut *tx, &site.id).await?;
    displacements::delete_site(tx, &site.id).await?;
    block_motions::delete_site(tx, &site.id).await?;
    pooled_forecasts::delete_site(tx, &site.id).await?;
    let Some(reference) = reference_epoch(tx, &site).await? else {
        return Ok(0);
    };
    let config = site_analysis_config(tx, &site).await?;
    let points = point_configs(&mut *tx, &site.id).await?;
    let Some(reference) = reference_coordinates(tx, &site, reference, &points, &config).await?
    else {
        return Ok(0);
    };
    let mut series = Vec::new();
    for id in epochs::ids_in_time_order(&mut *tx, &site.id).await? {
        if let Some(e) = epoch_coordinates(tx, &site.id, id).await? {
            series.push(e);
        }
    }
    let reference_id = reference.epoch;
    let alerts = alert_config(&site);
    let out = tokio::task::spawn_blocking(move || {
        analyse_series(&reference, &series, &points, &config, &alerts)
    })
    .await?;
    displacements::insert(tx, &site.id, &to_rows(&out.records, reference_id)).await?;
    block_motions::insert(tx, &site.id, &to_rows(&out.block_records, reference_id)).await?;
    let pooled: Vec<pooled_forecasts::PooledForecast> = out
        .pooled
        .into_iter()
        .map(
            |(epoch, point, pooled_with)| pooled_forecasts::PooledForecast {
                epoch,
                point,
                pooled_with,
            },
        )
        .collect();
    pooled_forecasts::insert(tx, &site.id, &pooled).await?;
    for id in &out.analysed {
        epochs::set_analysis_outcome(tx, &site.id, *id, None).await?;
    }
    for (id, reason) in &out.failures {
        epochs::set_analysis_outcome(tx, &site.id, *id, Some(reason)).await?;
    }
    let kept = cause.kept_kinds();
    let cause = cause.to_string();
    let now = store::clock(&mut *tx).await?;
    Ok(
        alert_outcome::reconcile(tx, &site.id, &out.replayed, now, &cause, kept, public_url)
            .await?,
    )
}

/// Why a site's series is recomputed; its text ends the message of an alert the recompute
/// resolves.
#[derive(Debug, Clone, PartialEq)]
pub enum RecomputeCause {
    /// The reference epoch was set (`None`: back to the earliest epoch), by whom.
    Reference(Option<i64>, String),
    /// A block group was declared or replaced.
    Group(String),
    /// A point's role, group or direction changed.
    Point(String),
    /// An epoch arrived before epochs already analysed, or inside a reference of several epochs.
    EarlierEpoch(i64),
    /// The site's analysis settings changed in the configuration file.
    Settings,
    /// The stored series was derived by an older version.
    NewerVersion,
    /// Staff changed the site's settings: what, by whom (the audit row).
    Edit(String),
}

impl RecomputeCause {
    /// The alert kinds this change cannot lower: a new reference epoch (or a recomputation by a
    /// newer version, which changes no input) leaves velocity and time to failure to the next
    /// epoch's data ([`REFERENCE_INDEPENDENT`]); the other causes change what the rules read.
    pub fn kept_kinds(&self) -> &'static [AlertKind] {
        match self {
            RecomputeCause::Reference(..) | RecomputeCause::NewerVersion => &REFERENCE_INDEPENDENT,
            _ => &[],
        }
    }
}

impl std::fmt::Display for RecomputeCause {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            RecomputeCause::Reference(Some(e), by) => {
                write!(f, "the reference was set to epoch {e} by {by}")
            }
            RecomputeCause::Reference(None, by) => {
                write!(
                    f,
                    "the reference was set back to the earliest epoch by {by}"
                )
            }
            RecomputeCause::Group(g) => write!(f, "block group {g} was declared anew"),
            RecomputeCause::Point(p) => write!(f, "the settings of point {p} changed"),
            RecomputeCause::EarlierEpoch(e) => {
                write!(
                    f,
                    "epoch {e} arrived after later ones and the series was recomputed"
                )
            }
            RecomputeCause::Settings => {
                write!(f, "the site's analysis settings or alert rules changed")
            }
            RecomputeCause::NewerVersion => {
                write!(f, "the series was recomputed by a newer version")
            }
            RecomputeCause::Edit(what) => write!(f, "{what}"),
        }
    }
}

/// Recomputes, once, every site whose stored series an older binary derived
/// ([`sites::ANALYSIS_VERSION`]: e.g. rows without the filtered values), one write transaction per
/// site, skipping a site another node has recomputed meanwhile; called at start (`public_url`:
/// the links of the event bodies). Returns how many sites this call recomputed.
pub async fn recompute_outdated(
    store: &Store,
    public_url: Option<&str>,
) -> Result<usize, ServiceError> {
    let mut recomputed = 0;
    for id in &sites::outdated(store.reader()).await? {
        let mut tx = store.begin_write_site(id).await?;
        // Asked again under the site's lock: another node starting at the same time may have
        // recomputed it meanwhile.
        if !sites::is_outdated(&mut *tx, id).await? {
            continue;
        }
        tracing::info!(site = %id, "recomputing the series derived by an older version");
        let raised = recompute_site(&mut tx, id, &RecomputeCause::NewerVersion, public_url).await?;
        tx.commit().await.map_err(StoreError::from)?;
        super::alert_outcome::count_raised(raised);
        recomputed += 1;
    }
    Ok(recomputed)
}
