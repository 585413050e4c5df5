//! The campaign schedule: a site with `schedule_hours` whose last epoch is older than that gets
//! a `campaign_overdue` alert (resolved by the next epoch). Checked periodically by the daemon.

use std::time::Duration;

use chrono::{DateTime, Utc};

use crate::shutdown::Shutdown;
use crate::store::{self, alert_states, epochs, sites, Store, StoreError};
use cliffwatch_core::analysis;

use crate::service::alert_outcome::save_and_record;
use crate::service::analysis_inputs::alert_config;

/// Checks every site with a schedule at `now`, one write transaction per site that changes;
/// the events' bodies link under `public_url` (the configuration's). Returns how many alerts
/// were raised.
pub async fn check_all(
    store: &Store,
    now: DateTime<Utc>,
    public_url: Option<&str>,
) -> Result<usize, StoreError> {
    let mut raised = 0;
    for id in sites::scheduled(store.reader()).await? {
        let mut tx = store.begin_write_site(&id).await?;
        let Some(site) = sites::get(&mut *tx, &id).await? else {
            continue;
        };
        let last = epochs::last_observed_at(&mut *tx, &id).await?;
        let last = last.as_deref().and_then(store::parse_timestamp);
        let state = alert_states::load(&mut tx, &id).await?;
        let (state, events) = analysis::check_overdue(&alert_config(&site), &state, last, now);
        if events.is_empty() {
            continue;
        }
        // Recorded at this transaction's time: a sweep over many sites takes a while.
        let at = store::clock(&mut tx).await?;
        raised += save_and_record(&mut tx, &id, &state, &events, at, public_url).await?;
        tx.commit().await?;
    }
    Ok(raised)
}

/// Runs [`check_all`] every `every` until shutdown; with several nodes on one database, one
/// node at a time ([`Store::try_job_lock`]), the others skip the pass. The time checked against
/// is the store's clock ([`Store::clock`]), so a node whose clock runs ahead raises no campaign
/// early and one whose clock runs behind none late. `public_url`: as for [`check_all`].
pub async fn run(store: Store, every: Duration, public_url: Option<String>, shutdown: Shutdown) {
    loop {
        match check_once(&store, public_url.as_deref()).await {
            Ok(n) if n > 0 => crate::service::alert_outcome::count_raised(n),
            Ok(_) => {}
            Err(e) => tracing::warn!(error = %e, "campaign schedule check failed"),
        }
        if shutdown.sleep(every).await {
            break;
        }
    }
    tracing::info!("campaign schedule check stopped");
}

async fn check_once(store: &Store, public_url: Option<&str>) -> Result<usize, StoreError> {
    match store.try_job_lock("campaign schedule").await? {
        Some(_held) => check_all(store, store.clock().await?, public_url).await,
        None => Ok(0),
    }
}
