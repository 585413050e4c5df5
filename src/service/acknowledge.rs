//! Acknowledging an alert: the staff member on duty says they have seen it.

use chrono::{DateTime, Utc};

use crate::store::{self, alert_states, alerts, Connection, Store, StoreError};
use cliffwatch_core::analysis::{self, AnalysisError};

use super::alert_outcome::save_and_record;
use super::ServiceError;

/// Longest name of who acknowledges (characters, after trimming).
pub const MAX_NAME_CHARS: usize = 200;
/// Longest comment of an acknowledgement (characters, after trimming).
pub const MAX_COMMENT_CHARS: usize = 2000;

/// Acknowledges alert `id` for `by` (trimmed, 1 to [`MAX_NAME_CHARS`] characters) with an
/// optional comment (at most [`MAX_COMMENT_CHARS`]; blank is none), in one write transaction: an
/// open alert moves to `acknowledged` and queues an `alert.acknowledged` event; a resolved one
/// only records who acknowledged it. An acknowledgement already given stands
/// ([`analysis::may_acknowledge`]): acknowledging again is [`ServiceError::AlreadyAcknowledged`]
/// (an escalation opens the alert again, and then it can be). The event's body links under
/// `public_url` (the configuration's). Returns the alert as stored after.
pub async fn acknowledge(
    store: &Store,
    id: &str,
    by: &str,
    comment: Option<&str>,
    public_url: Option<&str>,
) -> Result<alerts::Alert, ServiceError> {
    let (by, comment) = checked_acknowledgement(by, comment)?;
    // The alert's site decides the write lock; the alert is read again inside the transaction.
    let Some(site) = alerts::get(store.reader(), id).await?.map(|a| a.site) else {
        return Err(ServiceError::UnknownAlert(id.to_string()));
    };
    let mut tx = store.begin_write_site(&site).await?;
    let now = store::clock(&mut tx).await?;
    acknowledge_in(&mut tx, id, by, comment, now, public_url).await?;
    let alert = alerts::get(&mut *tx, id)
        .await?
        .ok_or_else(|| ServiceError::UnknownAlert(id.to_string()))?;
    tx.commit().await.map_err(StoreError::from)?;
    Ok(alert)
}

/// `by` and `comment` of an acknowledgement, trimmed and checked: `by` 1 to [`MAX_NAME_CHARS`]
/// characters, `comment` at most [`MAX_COMMENT_CHARS`] (blank is none), neither with NUL.
pub(crate) fn checked_acknowledgement<'a>(
    by: &'a str,
    comment: Option<&'a str>,
) -> Result<(&'a str, Option<&'a str>), ServiceError> {
    let by = by.trim();
    if by.is_empty() || by.chars().count() > MAX_NAME_CHARS {
        return Err(ServiceError::BadAcknowledgement(format!(
            "by: a name of 1 to {MAX_NAME_CHARS} characters"
        )));
    }
    if by.contains('\0') || comment.is_some_and(|c| c.contains('\0')) {
        return Err(ServiceError::BadAcknowledgement(
            "by, comment: the NUL character (U+0000) is not allowed".into(),
        ));
    }
    let comment = comment.map(str::trim).filter(|c| !c.is_empty());
    if comment.is_some_and(|c| c.chars().count() > MAX_COMMENT_CHARS) {
        return Err(ServiceError::BadAcknowledgement(format!(
            "comment: at most {MAX_COMMENT_CHARS} characters"
        )));
    }
    Ok((by, comment))
}

/// Acknowledges alert `id` inside the site's write transaction `tx` at `now` (the store's
/// clock), `by` and `comment` checked ([`checked_acknowledgement`]): an open alert moves to
/// `acknowledged` and queues an `alert.acknowledged` event; a resolved one only records who
/// acknowledged it. The event's body links under `public_url`.
pub(crate) async fn acknowledge_in(
    tx: &mut Connection,
    id: &str,
    by: &str,
    comment: Option<&str>,
    now: DateTime<Utc>,
    public_url: Option<&str>,
) -> Result<(), ServiceError> {
    let Some(stored) = alerts::get(&mut *tx, id).await? else {
        return Err(ServiceError::UnknownAlert(id.to_string()));
    };
    let engine = alert_states::load(&mut *tx, &stored.site).await?;
    let refused = |e: AnalysisError| match e {
        AnalysisError::AlreadyAcknowledged { id, by } => {
            ServiceError::AlreadyAcknowledged { id, by }
        }
        _ => ServiceError::UnknownAlert(id.to_string()),
    };
    match analysis::acknowledge(&engine, id, by, comment, now) {
        Ok((engine, event)) => {
            save_and_record(&mut *tx, &stored.site, &engine, &[event], now, public_url).await?;
        }
        // Not active any more (resolved): note who acknowledged it, no event.
        Err(AnalysisError::UnknownAlert(_)) => {
            analysis::may_acknowledge(id, stored.state, stored.acknowledged_by.as_deref())
                .map_err(refused)?;
            alerts::acknowledge(&mut *tx, id, by, comment, now).await?;
        }
        Err(e) => return Err(refused(e)),
    }
    Ok(())
}
