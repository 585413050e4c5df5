//! The campaign schedule: `campaign_overdue` when no epoch arrived in time.

use chrono::{DateTime, Utc};

use super::alert::{AlertEvent, AlertState};
use super::metric::AlertKind;
use super::rule::AlertConfig;
use super::transition::{apply, fmt_time, Update};

/// Checks the campaign schedule: raises `campaign_overdue` when more than
/// `schedule_hours × (1 + overdue_grace)` hours passed since `last_observed_at` (the latest epoch's
/// observation time; None = no epoch yet, nothing to check). Call it periodically.
pub fn check_overdue(
    config: &AlertConfig,
    state: &AlertState,
    last_observed_at: Option<DateTime<Utc>>,
    now: DateTime<Utc>,
) -> (AlertState, Vec<AlertEvent>) {
    let mut st = state.clone();
    let mut events = vec![];
    let (Some(schedule), Some(last)) = (config.schedule_hours, last_observed_at) else {
        return (st, events);
    };
    let hours = (now - last).num_seconds() as f64 / 3600.0;
    if schedule > 0.0
        && hours > schedule * (1.0 + config.overdue_grace.max(0.0))
        && st.find(None, AlertKind::CampaignOverdue).is_none()
    {
        apply(
            &config.site,
            &mut st,
            Update {
                value: Some(hours),
                threshold: Some(schedule),
                ..Update::site(
                    AlertKind::CampaignOverdue,
                    Some(config.campaign_overdue_level),
                    None,
                    Some(last),
                    // Microseconds: a raise, a resolve and a raise again within one second (a
                    // backlog epoch that is still late) must not reuse the first alert's id.
                    format!("{}", now.timestamp_micros()),
                )
            },
            now,
            &mut events,
        );
        if let Some(a) = st.alerts.last_mut() {
            a.message = format!(
                "site {}: no epoch since {} ({hours:.1} h, schedule {schedule} h)",
                config.site,
                fmt_time(last)
            );
            events[0].alert.message = a.message.clone();
        }
    }
    (st, events)
}

/// An epoch observed at `observed_at` arrived by a path that does not evaluate the rules against it
/// alone (it joined a reference of several epochs, so the whole series was recomputed): resolves
/// an open `campaign_overdue`, as [`super::evaluate_alerts`] does for every other epoch.
pub fn campaign_arrived(
    config: &AlertConfig,
    state: &AlertState,
    epoch: i64,
    observed_at: DateTime<Utc>,
    now: DateTime<Utc>,
) -> (AlertState, Vec<AlertEvent>) {
    let mut st = state.clone();
    let mut events = vec![];
    apply(
        &config.site,
        &mut st,
        Update::site(
            AlertKind::CampaignOverdue,
            None,
            Some(epoch),
            Some(observed_at),
            epoch.to_string(),
        ),
        now,
        &mut events,
    );
    (st, events)
}
