//! What a person does to an alert: acknowledge it, or resolve it by hand.

use chrono::{DateTime, Utc};

use super::alert::{AlertEvent, AlertEventType, AlertState, AlertStatus};
use super::transition::Subject;
use crate::analysis::error::AnalysisError;

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
        },
    ))
}

/// Resolves an alert by hand (e.g. after a stable point was re-surveyed). Its rules are reset, so it is
/// raised again by the next epoch whose values still cross a threshold.
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
        (Some(p), _) => Some(Subject::Point(p)),
        (None, Some(g)) => Some(Subject::Group(g)),
        _ => None,
    };
    if let Some(subject) = subject {
        let prefix = format!("{}{}:", subject.memory_prefix(), alert.rule.as_str());
        st.rules.retain(|k, _| !k.starts_with(&prefix));
    }
    alert.status = AlertStatus::Resolved;
    alert.acknowledged_by.get_or_insert_with(|| by.to_string());
    alert.updated_at = now;
    Ok((
        st,
        AlertEvent {
            event_type: AlertEventType::Resolved,
            timestamp: now,
            alert,
        },
    ))
}
