//! Acknowledging an alert: the staff member on duty says they have seen it.

use chrono::Utc;

use crate::analysis;
use crate::store::{alert_states, alerts, Store, StoreError};

use super::alert_outcome::save_and_record;
use super::ServiceError;

/// Acknowledges alert `id` for `by` with an optional comment, in one write transaction: an open
/// alert moves to `acknowledged` and queues an `alert.acknowledged` event; a resolved one only
/// records who acknowledged it. Returns the alert as stored after.
pub async fn acknowledge(
    store: &Store,
    id: &str,
    by: &str,
    comment: Option<&str>,
) -> Result<alerts::Alert, ServiceError> {
    // The alert's site decides the write lock; the alert is read again inside the transaction.
    let Some(site) = alerts::get(store.reader(), id).await?.map(|a| a.site) else {
        return Err(ServiceError::UnknownAlert(id.to_string()));
    };
    let mut tx = store.begin_write_site(&site).await?;
    let Some(stored) = alerts::get(&mut *tx, id).await? else {
        return Err(ServiceError::UnknownAlert(id.to_string()));
    };
    let engine = alert_states::load(&mut tx, &stored.site).await?;
    match analysis::acknowledge(&engine, id, by, comment, Utc::now()) {
        Ok((engine, event)) => {
            save_and_record(&mut tx, &stored.site, &engine, &[event]).await?;
        }
        // Not open any more (resolved): note who acknowledged it, no event.
        Err(_) => {
            alerts::acknowledge(&mut tx, id, by, comment).await?;
        }
    }
    let alert = alerts::get(&mut *tx, id)
        .await?
        .ok_or_else(|| ServiceError::UnknownAlert(id.to_string()))?;
    tx.commit().await.map_err(StoreError::from)?;
    Ok(alert)
}
