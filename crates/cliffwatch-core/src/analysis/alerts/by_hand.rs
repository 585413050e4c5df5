//! What a person does to an alert: acknowledge it, or resolve it by hand.

use chrono::{DateTime, Utc};

use super::alert::{AlertEvent, AlertEventType, AlertState, AlertStatus};
use super::transition::Subject;
use crate::analysis::error::AnalysisError;

/// Whether alert `id`, in `status` and acknowledged by `acknowledged_by`, may be acknowledged:
/// an acknowledgement stands until an escalation opens the alert again (which clears it), so an
/// alert that is acknowledged, or resolved after it was, is
/// [`AnalysisError::AlreadyAcknowledged`].
pub fn may_acknowledge(
    id: &str,
    status: AlertStatus,
    acknowledged_by: Option<&str>,
) -> Result<(), AnalysisError> {
    match (status, acknowledged_by) {
        (AlertStatus::Open, _) | (_, None) => Ok(()),
        (_, Some(by)) => Err(AnalysisError::AlreadyAcknowledged {
            id: id.to_string(),
            by: by.to_string(),
        }),
    }
}

/// Acknowledges the active alert `alert_id` of `state` for `by` with an optional comment: it moves
/// to `acknowledged`, and the returned event announces it. [`AnalysisError::UnknownAlert`] when
/// no active alert has that id; [`AnalysisError::AlreadyAcknowledged`] when it was acknowledged
/// already (see [`may_acknowledge`]).
pub fn acknowledge(
    state: &AlertState,
    alert_id: &str,
    by: &str,
    comment: Option<&str>,
    now: DateTime<Utc>,
) -> Result<(AlertState, AlertEvent), AnalysisError> {
    let mut st = state.clone();
    let a = st
        .alerts
        .iter_mut()
        .find(|a| a.id == alert_id)
        .ok_or_else(|| AnalysisError::UnknownAlert(alert_id.to_string()))?;
    may_acknowledge(&a.id, a.status, a.acknowledged_by.as_deref())?;
    a.status = AlertStatus::Acknowledged;
    a.acknowledged_by = Some(by.to_string());
    a.comment = comment.map(str::to_string);
    a.updated_at = now;
    let alert = a.clone();
    Ok((
        st,
        AlertEvent {
            event_type: AlertEventType::Acknowledged,
            timestamp: now,
            alert,
            cleared_by: None,
        },
    ))
}

/// Resolves an alert by hand (e.g. after a stable point was re-surveyed). Its rules are reset, so it is
/// raised again by the next epoch whose values still cross a threshold (for `reference_unstable`:
/// once a stable point is excluded in 2 of 3 epochs again).
pub fn resolve(
    state: &AlertState,
    alert_id: &str,
    by: &str,
    now: DateTime<Utc>,
) -> Result<(AlertState, AlertEvent), AnalysisError> {
    let mut st = state.clone();
    let i = st
        .alerts
        .iter()
        .position(|a| a.id == alert_id)
        .ok_or_else(|| AnalysisError::UnknownAlert(alert_id.to_string()))?;
    let mut alert = st.alerts.remove(i);
    let subject = match (&alert.point, &alert.group) {
        (Some(p), _) => Subject::Point(p),
        (None, Some(g)) => Subject::Group(g),
        _ => Subject::Site,
    };
    let prefix = format!("{}{}:", subject.memory_prefix(), alert.rule.as_str());
    st.rules.retain(|k, _| !k.starts_with(&prefix));
    alert.status = AlertStatus::Resolved;
    alert.acknowledged_by.get_or_insert_with(|| by.to_string());
    alert.updated_at = now;
    Ok((
        st,
        AlertEvent {
            event_type: AlertEventType::Resolved,
            timestamp: now,
            alert,
            cleared_by: None,
        },
    ))
}
