//! Acknowledging an alert: the staff member on duty says they have seen it.

use chrono::Utc;

use crate::analysis::{self, AlertStatus};
use crate::store::{alert_states, alerts, Store, StoreError};

use super::alert_outcome::save_and_record;
use super::ServiceError;

/// Longest name of who acknowledges (characters, after trimming).
pub const MAX_NAME_CHARS: usize = 200;
/// Longest comment of an acknowledgement (characters, after trimming).
pub const MAX_COMMENT_CHARS: usize = 2000;

/// Acknowledges alert `id` for `by` (trimmed, 1 to [`MAX_NAME_CHARS`] characters) with an optional comment (at most [`MAX_COMMENT_CHARS`]; blank is none), in one write transaction: an open
/// alert moves to `acknowledged` and queues an `alert.acknowledged` event; a resolved one only
/// records who acknowledged it. An acknowledgement already given stands: acknowledging again is
/// [`ServiceError::AlreadyAcknowledged`] (an escalation opens the alert again, and then it can
/// be). Returns the alert as stored after.
pub async fn acknowledge(
    store: &Store,
    id: &str,
    by: &str,
    comment: Option<&str>,
) -> Result<alerts::Alert, ServiceError> {
    let by = by.trim();
    if by.is_empty() || by.chars().count() > MAX_NAME_CHARS {
        return Err(ServiceError::BadAcknowledgement(
            "by: a name of 1 to 200 characters",
        ));
    }
    let comment = comment.map(str::trim).filter(|c| !c.is_empty());
    if comment.is_some_and(|c| c.chars().count() > MAX_COMMENT_CHARS) {
        return Err(ServiceError::BadAcknowledgement(
            "comment: at most 2000 characters",
        ));
    }
    // The alert's site decides the write lock; the alert is read again inside the transaction.
    let Some(site) = alerts::get(store.reader(), id).await?.map(|a| a.site) else {
        return Err(ServiceError::UnknownAlert(id.to_string()));
    };
    let mut tx = store.begin_write_site(&site).await?;
    let Some(stored) = alerts::get(&mut *tx, id).await? else {
        return Err(ServiceError::UnknownAlert(id.to_string()));
    };
    if let (Some(by), false) = (&stored.acknowledged_by, stored.state == AlertStatus::Open) {
        return Err(ServiceError::AlreadyAcknowledged {
            id: id.to_string(),
            by: by.clone(),
        });
    }
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
