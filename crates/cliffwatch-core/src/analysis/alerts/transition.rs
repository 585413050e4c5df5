//! How one subject's alert of one kind moves: raised, escalated, de-escalated or resolved, with
//! the event that announces it.

use chrono::{DateTime, SecondsFormat, Utc};

use super::alert::{
    Alert, AlertEvent, AlertEventType, AlertLevel, AlertState, AlertStatus, ClearingTest,
};
use super::metric::AlertKind;
use super::rule::AlertRule;

/// A time as the messages show it: RFC 3339, whole seconds, UTC.
pub(super) fn fmt_time(t: DateTime<Utc>) -> String {
    t.to_rfc3339_opts(SecondsFormat::Secs, true)
}

/// The alert's human-readable summary: who, what, the value and the rule's threshold, the level.
fn message(
    site: &str,
    subject: Subject<'_>,
    kind: AlertKind,
    level: AlertLevel,
    value: Option<f64>,
    rule: Option<&AlertRule>,
    unit: &str,
) -> String {
    let who = match subject {
        Subject::Point(p) => format!("{site}/{p}"),
        Subject::Group(g) => format!("{site}/block {g}"),
        Subject::Site => format!("site {site}"),
    };
    let cmp = match rule {
        Some(r) if r.above.is_some() => format!(" above {} {unit}", r.above.unwrap_or_default()),
        Some(r) if r.below.is_some() => format!(" below {} {unit}", r.below.unwrap_or_default()),
        _ => String::new(),
    };
    let v = value.map_or(String::new(), |v| format!(" {v:.2} {unit}"));
    format!("{}: {}{v}{cmp} ({})", who, kind.as_str(), level.as_str())
}

/// What an alert is about.
#[derive(Clone, Copy)]
pub(super) enum Subject<'a> {
    Point(&'a str),
    Group(&'a str),
    Site,
}

impl<'a> Subject<'a> {
    pub(super) fn point(self) -> Option<&'a str> {
        match self {
            Subject::Point(p) => Some(p),
            _ => None,
        }
    }

    pub(super) fn group(self) -> Option<&'a str> {
        match self {
            Subject::Group(g) => Some(g),
            _ => None,
        }
    }

    /// Prefix of the subject's rule memories in [`AlertState::rules`].
    pub(super) fn memory_prefix(self) -> String {
        match self {
            Subject::Point(p) => format!("{p}|"),
            Subject::Group(g) => format!("group:{g}|"),
            Subject::Site => "-|".into(),
        }
    }
}

/// One subject's alert of one kind after an evaluation: the level it should have now (None: no
/// rule active, so an open alert resolves) and what the alert shows.
pub(super) struct Update<'a> {
    /// Whose alert.
    pub(super) subject: Subject<'a>,
    /// Points concerned (a block's points, or the stable points a site-level alert names).
    pub(super) points: Vec<String>,
    /// Which alert of the subject.
    pub(super) kind: AlertKind,
    /// The level the alert should have; None resolves an open one.
    pub(super) level: Option<AlertLevel>,
    /// Latest value of the metric (unit in `unit`).
    pub(super) value: Option<f64>,
    /// Threshold of the rule behind the level.
    pub(super) threshold: Option<f64>,
    /// Unit of value and threshold.
    pub(super) unit: &'a str,
    /// The rule behind the level (for the message).
    pub(super) rule: Option<&'a AlertRule>,
    /// Epoch that evaluated the alert.
    pub(super) epoch: Option<i64>,
    /// Its observation time.
    pub(super) observed_at: Option<DateTime<Utc>>,
    /// Last part of a new alert's id (the epoch, or a timestamp).
    pub(super) id_suffix: String,
    /// The test of the highest rule that stopped being active, when one did: it decides a
    /// de-escalation or a resolution.
    pub(super) cleared_by: Option<ClearingTest>,
}

impl<'a> Update<'a> {
    /// The site-level alert of `kind` brought to `level` by an epoch (or, without one, by the
    /// clock): no value, threshold, rule or points; hours as the unit of `campaign_overdue`.
    pub(super) fn site(
        kind: AlertKind,
        level: Option<AlertLevel>,
        epoch: Option<i64>,
        observed_at: Option<DateTime<Utc>>,
        id_suffix: String,
    ) -> Self {
        Update {
            subject: Subject::Site,
            points: vec![],
            kind,
            level,
            value: None,
            threshold: None,
            unit: if kind == AlertKind::CampaignOverdue {
                "hours"
            } else {
                ""
            },
            rule: None,
            epoch,
            observed_at,
            id_suffix,
            cleared_by: None,
        }
    }
}

/// Brings the subject's alert of `up.kind` to `up.level` in `state`: raises, escalates,
/// de-escalates or resolves it, and pushes the event that announces the change (none when the
/// level stays; an escalation needs a new acknowledgement).
pub(super) fn apply(
    site: &str,
    state: &mut AlertState,
    up: Update<'_>,
    now: DateTime<Utc>,
    events: &mut Vec<AlertEvent>,
) {
    let (point, group) = (up.subject.point(), up.subject.group());
    let pos = state.alerts.iter().position(|a| {
        a.point.as_deref() == point && a.group.as_deref() == group && a.rule == up.kind
    });
    match (pos, up.level) {
        (None, None) => {}
        (None, Some(level)) => {
            let alert = Alert {
                id: match up.subject {
                    Subject::Group(g) => {
                        format!("{site}:group-{g}:{}:{}", up.kind.as_str(), up.id_suffix)
                    }
                    _ => format!(
                        "{site}:{}:{}:{}",
                        point.unwrap_or("-"),
                        up.kind.as_str(),
                        up.id_suffix
                    ),
                },
                site: site.to_string(),
                point: point.map(str::to_string),
                group: group.map(str::to_string),
                points: up.points,
                rule: up.kind,
                level,
                peak_level: level,
                value: up.value,
                threshold: up.threshold,
                unit: up.unit.to_string(),
                epoch: up.epoch,
                observed_at: up.observed_at,
                raised_epoch: up.epoch,
                raised_observed_at: up.observed_at,
                raised_at: now,
                updated_at: now,
                status: AlertStatus::Open,
                acknowledged_by: None,
                comment: None,
                message: message(site, up.subject, up.kind, level, up.value, up.rule, up.unit),
            };
            state.alerts.push(alert.clone());
            events.push(AlertEvent {
                event_type: AlertEventType::Raised,
                timestamp: now,
                alert,
                cleared_by: None,
            });
        }
        (Some(i), level) => {
            let a = &mut state.alerts[i];
            a.value = up.value.or(a.value);
            a.epoch = up.epoch.or(a.epoch);
            a.observed_at = up.observed_at.or(a.observed_at);
            for p in up.points {
                if !a.points.contains(&p) {
                    a.points.push(p);
                }
            }
            match level {
                None => {
                    a.status = AlertStatus::Resolved;
                    a.updated_at = now;
                    a.message = format!(
                        "{} — resolved",
                        message(site, up.subject, up.kind, a.level, a.value, None, up.unit)
                    );
                    let alert = state.alerts.remove(i);
                    events.push(AlertEvent {
                        event_type: AlertEventType::Resolved,
                        timestamp: now,
                        alert,
                        cleared_by: up.cleared_by,
                    });
                }
                Some(l) if l != a.level => {
                    let ty = if l > a.level {
                        AlertEventType::Escalated
                    } else {
                        AlertEventType::Deescalated
                    };
                    if l > a.level {
                        // A higher level needs a new acknowledgement; the one given for the lower
                        // level stays in the alert's history (its `alert.acknowledged` event).
                        a.status = AlertStatus::Open;
                        a.acknowledged_by = None;
                        a.comment = None;
                    }
                    a.level = l;
                    a.peak_level = a.peak_level.max(l);
                    a.threshold = up.threshold;
                    a.updated_at = now;
                    a.message = message(site, up.subject, up.kind, l, a.value, up.rule, up.unit);
                    events.push(AlertEvent {
                        event_type: ty,
                        timestamp: now,
                        alert: a.clone(),
                        cleared_by: up.cleared_by.filter(|_| ty == AlertEventType::Deescalated),
                    });
                }
                // The same level: a metric alert's summary follows the latest value, as `value`
                // does (site-level alerts keep their own wording).
                Some(_) if !matches!(up.subject, Subject::Site) => {
                    a.message = message(
                        site, up.subject, up.kind, a.level, a.value, up.rule, up.unit,
                    );
                }
                Some(_) => {}
            }
        }
    }
}
