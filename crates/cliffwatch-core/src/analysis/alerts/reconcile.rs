//! A recomputed series against the stored alert state: only the net difference is announced.

use chrono::{DateTime, Utc};

use super::alert::{Alert, AlertEvent, AlertEventType, AlertState, AlertStatus};
use super::metric::AlertKind;

/// After the derived series was recomputed (reference changed, an epoch arrived out of order):
/// brings the stored alert state to `replayed` — the state the rules reach when replayed from
/// scratch over the recomputed series — without re-sending history staff already received.
///
/// Only the net difference is announced, stamped `now`: an alert open in both keeps its id,
/// raising time and acknowledgement, and gets `alert.escalated` / `alert.deescalated` when its
/// level differs (an escalation clears the acknowledgement and needs a new one); an alert only in `replayed` is
/// raised; an alert only in `current` is resolved. Intermediate transitions of the replay are
/// not sent. `campaign_overdue` is not part of a replay (it depends on the clock, not on the
/// series) and is kept as it is. The rules' memory is the replay's. `cause` says what made the
/// series change (e.g. "the reference was set to epoch 7"); a resolved alert's message ends with
/// it.
///
/// `kept`: the kinds the change cannot lower (velocity and time to failure do not depend on the
/// reference epoch: [`REFERENCE_INDEPENDENT`]). An open alert of such a kind is neither resolved
/// nor de-escalated by the replay, and keeps its rules' memory (hysteresis, quiet epochs): the
/// next epoch's data decides. A replay that finds it higher still escalates it, and one that
/// finds a new one raises it.
pub fn reconcile(
    current: &AlertState,
    replayed: &AlertState,
    now: DateTime<Utc>,
    cause: &str,
    kept: &[AlertKind],
) -> (AlertState, Vec<AlertEvent>) {
    let mut out = AlertState {
        alerts: vec![],
        rules: replayed.rules.clone(),
    };
    let mut events = vec![];
    for r in &replayed.alerts {
        if r.rule == AlertKind::CampaignOverdue {
            continue;
        }
        match current.find_subject(r.point.as_deref(), r.group.as_deref(), r.rule) {
            Some(c) if kept.contains(&c.rule) && r.level < c.level => {
                keep(&mut out, current, c);
            }
            Some(c) => {
                let mut a = r.clone();
                a.id = c.id.clone();
                a.raised_at = c.raised_at;
                a.raised_epoch = c.raised_epoch.or(r.raised_epoch);
                a.raised_observed_at = c.raised_observed_at.or(r.raised_observed_at);
                a.peak_level = c.peak_level.max(r.level);
                a.acknowledged_by = c.acknowledged_by.clone();
                a.comment = c.comment.clone();
                a.status = c.status;
                a.updated_at = c.updated_at;
                if a.level != c.level {
                    let ty = if a.level > c.level {
                        a.status = AlertStatus::Open;
                        a.acknowledged_by = None;
                        a.comment = None;
                        AlertEventType::Escalated
                    } else {
                        AlertEventType::Deescalated
                    };
                    a.updated_at = now;
                    events.push(AlertEvent {
                        event_type: ty,
                        timestamp: now,
                        alert: a.clone(),
                        cleared_by: None,
                    });
                }
                out.alerts.push(a);
            }
            None => {
                let mut a = r.clone();
                a.raised_at = now;
                a.updated_at = now;
                a.status = AlertStatus::Open;
                events.push(AlertEvent {
                    event_type: AlertEventType::Raised,
                    timestamp: now,
                    alert: a.clone(),
                    cleared_by: None,
                });
                out.alerts.push(a);
            }
        }
    }
    for c in &current.alerts {
        if c.rule == AlertKind::CampaignOverdue {
            out.alerts.push(c.clone());
            continue;
        }
        if replayed
            .find_subject(c.point.as_deref(), c.group.as_deref(), c.rule)
            .is_some()
        {
            continue;
        }
        if kept.contains(&c.rule) {
            keep(&mut out, current, c);
        } else {
            let mut a = c.clone();
            a.status = AlertStatus::Resolved;
            a.updated_at = now;
            a.message = format!("{} — resolved: {cause}", c.message);
            events.push(AlertEvent {
                event_type: AlertEventType::Resolved,
                timestamp: now,
                alert: a,
                cleared_by: None,
            });
        }
    }
    (out, events)
}

/// The kinds a new reference epoch cannot change: velocity and time to failure are rates of the
/// motion, the same whichever epoch the displacements count from.
pub const REFERENCE_INDEPENDENT: [AlertKind; 2] =
    [AlertKind::VelocityMmPerDay, AlertKind::TimeToFailureHours];

/// Keeps `c` as it is in `out`, with the current memories of its subject's rules of its kind in
/// place of the replay's.
fn keep(out: &mut AlertState, current: &AlertState, c: &Alert) {
    let subject = match (&c.point, &c.group) {
        (Some(p), _) => format!("{p}|"),
        (None, Some(g)) => format!("group:{g}|"),
        (None, None) => "-|".to_string(),
    };
    let prefix = format!("{subject}{}:", c.rule.as_str());
    out.rules.retain(|k, _| !k.starts_with(&prefix));
    for (k, m) in current.rules.iter().filter(|(k, _)| k.starts_with(&prefix)) {
        out.rules.insert(k.clone(), *m);
    }
    out.alerts.push(c.clone());
}
