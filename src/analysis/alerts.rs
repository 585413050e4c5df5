//! Alert rules and the per-point alert state machine.
//!
//! Rules (contract JSON `{"level": "watch", "metric": "displacement_mm", "above": 5.0, "clear_below": 4.0}`)
//! apply per site and optionally per point group. For every point and metric there is at most one open
//! alert; its level is the highest level whose rule is active, so it is raised, escalates, de-escalates and
//! resolves as the rules switch. A rule becomes active when its threshold is crossed by a significant value
//! (significance required by default); an active rule clears (hysteresis) only when the value falls below
//! `clear_below` (above `clear_above` for `below` rules) or, without such a threshold, after
//! `quiet_epochs` consecutive epochs without triggering. Site-level alerts: `reference_unstable` (the
//! congruence test excluded stable points) and `campaign_overdue` (no epoch within the schedule).
//! Everything here is pure: the state goes in, the new state and the events come out.

use std::collections::BTreeMap;

use chrono::{DateTime, SecondsFormat, Utc};
use serde::{Deserialize, Serialize};

use super::analyse::EpochAnalysis;
use super::displacement::PointAnalysis;
use super::error::AnalysisError;

/// Alert level; ordered `watch` < `warning` < `alarm`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AlertLevel {
    /// Lowest level.
    Watch,
    /// Middle level.
    Warning,
    /// Highest level.
    Alarm,
}

impl AlertLevel {
    /// Contract name.
    pub fn as_str(self) -> &'static str {
        match self {
            AlertLevel::Watch => "watch",
            AlertLevel::Warning => "warning",
            AlertLevel::Alarm => "alarm",
        }
    }
}

/// A point metric rules can threshold.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Metric {
    /// 3-D displacement `d_mm`, mm.
    DisplacementMm,
    /// Displacement along the direction of interest `d_along_mm`, mm (signed).
    DisplacementAlongMm,
    /// `velocity_mm_per_day`, mm/day.
    VelocityMmPerDay,
    /// `time_to_failure_hours`, hours (use `below`).
    TimeToFailureHours,
}

impl Metric {
    /// Unit of the metric.
    pub fn unit(self) -> &'static str {
        match self {
            Metric::DisplacementMm | Metric::DisplacementAlongMm => "mm",
            Metric::VelocityMmPerDay => "mm/day",
            Metric::TimeToFailureHours => "hours",
        }
    }

    /// Value of the metric for a point and whether it is significant.
    pub fn value(self, p: &PointAnalysis) -> (Option<f64>, bool) {
        let r = &p.record;
        match self {
            Metric::DisplacementMm => (Some(r.d_mm), r.significant),
            Metric::DisplacementAlongMm => (r.d_along_mm, r.significant),
            Metric::VelocityMmPerDay => (
                r.velocity_mm_per_day,
                r.significant && p.kinematics.is_some_and(|k| k.velocity_significant),
            ),
            // A forecast exists only for a significant, accelerating point.
            Metric::TimeToFailureHours => {
                (r.time_to_failure_hours, r.time_to_failure_hours.is_some())
            }
        }
    }
}

/// What an alert is about: a point metric or a site-level kind (the webhook's `rule`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AlertKind {
    /// See [`Metric::DisplacementMm`].
    DisplacementMm,
    /// See [`Metric::DisplacementAlongMm`].
    DisplacementAlongMm,
    /// See [`Metric::VelocityMmPerDay`].
    VelocityMmPerDay,
    /// See [`Metric::TimeToFailureHours`].
    TimeToFailureHours,
    /// A site with a schedule has no new epoch in time.
    CampaignOverdue,
    /// The congruence test found moving stable points.
    ReferenceUnstable,
    /// An epoch was stored without displacements because its analysis failed (e.g. too few
    /// points in common with the reference).
    AnalysisFailed,
}

impl AlertKind {
    /// Contract name.
    pub fn as_str(self) -> &'static str {
        match self {
            AlertKind::DisplacementMm => "displacement_mm",
            AlertKind::DisplacementAlongMm => "displacement_along_mm",
            AlertKind::VelocityMmPerDay => "velocity_mm_per_day",
            AlertKind::TimeToFailureHours => "time_to_failure_hours",
            AlertKind::CampaignOverdue => "campaign_overdue",
            AlertKind::ReferenceUnstable => "reference_unstable",
            AlertKind::AnalysisFailed => "analysis_failed",
        }
    }
}

impl From<Metric> for AlertKind {
    fn from(m: Metric) -> Self {
        match m {
            Metric::DisplacementMm => AlertKind::DisplacementMm,
            Metric::DisplacementAlongMm => AlertKind::DisplacementAlongMm,
            Metric::VelocityMmPerDay => AlertKind::VelocityMmPerDay,
            Metric::TimeToFailureHours => AlertKind::TimeToFailureHours,
        }
    }
}

fn yes() -> bool {
    true
}

/// One alert rule (contract JSON, plus optional fields).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AlertRule {
    /// Level raised when the rule triggers.
    pub level: AlertLevel,
    /// Metric thresholded.
    pub metric: Metric,
    /// Triggers when the value is above this (unit of the metric).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub above: Option<f64>,
    /// Triggers when the value is below this (unit of the metric).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub below: Option<f64>,
    /// Hysteresis of an `above` rule: once active, clears only below this value.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub clear_below: Option<f64>,
    /// Hysteresis of a `below` rule: once active, clears only above this value.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub clear_above: Option<f64>,
    /// Restricts the rule to points of this group (all points when absent).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub group: Option<String>,
    /// Only significant values trigger (default true).
    #[serde(default = "yes")]
    pub require_significant: bool,
    /// Without a clear threshold: epochs without triggering before the rule clears (default: the config's).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub quiet_epochs: Option<u32>,
}

impl AlertRule {
    /// Checks that exactly one of `above` / `below` is set, finite, and that the clear threshold lies on the
    /// right side.
    pub fn validate(&self) -> Result<(), AnalysisError> {
        let bad = |m: &str| {
            Err(AnalysisError::InvalidConfig(format!(
                "alert rule {:?}: {m}",
                self.metric
            )))
        };
        match (self.above, self.below) {
            (Some(a), None) if a.is_finite() => {
                if self.clear_below.is_some_and(|c| !(c <= a)) {
                    return bad("clear_below must be ≤ above");
                }
            }
            (None, Some(b)) if b.is_finite() => {
                if self.clear_above.is_some_and(|c| !(c >= b)) {
                    return bad("clear_above must be ≥ below");
                }
            }
            _ => return bad("exactly one finite `above` or `below` is needed"),
        }
        Ok(())
    }

    fn applies_to(&self, group: Option<&str>) -> bool {
        self.group.as_deref().is_none_or(|g| Some(g) == group)
    }

    fn threshold(&self) -> Option<f64> {
        self.above.or(self.below)
    }

    fn triggers(&self, v: f64) -> bool {
        match (self.above, self.below) {
            (Some(a), None) => v > a,
            (None, Some(b)) => v < b,
            _ => false,
        }
    }

    /// Whether an active rule clears at this value (with a clear threshold).
    fn clears(&self, v: f64) -> Option<bool> {
        match (self.above, self.below) {
            (Some(_), None) => self.clear_below.map(|c| v < c),
            (None, Some(_)) => self.clear_above.map(|c| v > c),
            _ => Some(true),
        }
    }

    /// Stable key of the rule in the state.
    pub fn key(&self) -> String {
        format!(
            "{}:{}:{}:{}:{}",
            AlertKind::from(self.metric).as_str(),
            self.level.as_str(),
            self.above.map_or("-".into(), |a| format!("above{a}")),
            self.below.map_or("-".into(), |b| format!("below{b}")),
            self.group.as_deref().unwrap_or("*")
        )
    }
}

fn default_quiet() -> u32 {
    1
}
fn default_unstable() -> AlertLevel {
    AlertLevel::Warning
}
fn default_overdue() -> AlertLevel {
    AlertLevel::Watch
}
fn default_failed() -> AlertLevel {
    AlertLevel::Warning
}
fn default_grace() -> f64 {
    0.25
}

/// Alert configuration of a site.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AlertConfig {
    /// Site id (goes into alert ids and payloads).
    pub site: String,
    /// The rules.
    #[serde(default)]
    pub rules: Vec<AlertRule>,
    /// Default epochs without triggering before a rule without clear threshold clears (default 1).
    #[serde(default = "default_quiet")]
    pub quiet_epochs: u32,
    /// Level of `reference_unstable` (default warning).
    #[serde(default = "default_unstable")]
    pub reference_unstable_level: AlertLevel,
    /// Level of `campaign_overdue` (default watch).
    #[serde(default = "default_overdue")]
    pub campaign_overdue_level: AlertLevel,
    /// Level of `analysis_failed` (default warning).
    #[serde(default = "default_failed")]
    pub analysis_failed_level: AlertLevel,
    /// Campaign schedule in hours (`schedule_hours` of the site); no overdue alerts without it.
    #[serde(default)]
    pub schedule_hours: Option<f64>,
    /// Grace as a fraction of the schedule before `campaign_overdue` (default 0.25).
    #[serde(default = "default_grace")]
    pub overdue_grace: f64,
}

impl AlertConfig {
    /// A configuration with the given rules and defaults otherwise.
    pub fn new(site: impl Into<String>, rules: Vec<AlertRule>) -> Self {
        AlertConfig {
            site: site.into(),
            rules,
            quiet_epochs: 1,
            reference_unstable_level: AlertLevel::Warning,
            campaign_overdue_level: AlertLevel::Watch,
            analysis_failed_level: AlertLevel::Warning,
            schedule_hours: None,
            overdue_grace: 0.25,
        }
    }

    /// Validates every rule.
    pub fn validate(&self) -> Result<(), AnalysisError> {
        self.rules.iter().try_for_each(AlertRule::validate)
    }
}

/// Lifecycle of an alert.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AlertStatus {
    /// Open, not acknowledged.
    Open,
    /// Open and acknowledged.
    Acknowledged,
    /// Resolved (no longer in the state).
    Resolved,
}

/// One alert (stored; its snapshot travels in every event).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Alert {
    /// Deterministic id: `{site}:{point or -}:{rule}:{epoch or timestamp}` of the raising (no `/`, so it
    /// fits one URL path segment).
    pub id: String,
    /// Site id.
    pub site: String,
    /// Point, None for site-level alerts.
    pub point: Option<String>,
    /// Points concerned by a site-level alert (empty for point alerts).
    pub points: Vec<String>,
    /// Metric or site-level kind.
    pub rule: AlertKind,
    /// Current level.
    pub level: AlertLevel,
    /// Highest level reached (for endpoint filtering of later events).
    pub peak_level: AlertLevel,
    /// Latest value of the metric (unit in `unit`).
    pub value: Option<f64>,
    /// Threshold of the rule behind the current level.
    pub threshold: Option<f64>,
    /// Unit of value and threshold.
    pub unit: String,
    /// Latest epoch id that evaluated the alert.
    pub epoch: Option<i64>,
    /// Its observation time.
    pub observed_at: Option<DateTime<Utc>>,
    /// When raised.
    pub raised_at: DateTime<Utc>,
    /// Last change.
    pub updated_at: DateTime<Utc>,
    /// Status.
    pub status: AlertStatus,
    /// Who acknowledged (or resolved by hand).
    pub acknowledged_by: Option<String>,
    /// Comment of the acknowledgement.
    pub comment: Option<String>,
    /// Human-readable summary.
    pub message: String,
}

/// Memory of one rule for one point.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct RuleMemory {
    /// Whether the rule is active (contributes its level).
    pub active: bool,
    /// Consecutive epochs without triggering while active.
    pub quiet_epochs: u32,
}

/// The alert state of a site (serialize it to store).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct AlertState {
    /// Open and acknowledged alerts.
    pub alerts: Vec<Alert>,
    /// Rule memories keyed `{point}|{rule key}`.
    pub rules: BTreeMap<String, RuleMemory>,
}

impl AlertState {
    /// The open alert of a point (None for site level) and kind.
    pub fn find(&self, point: Option<&str>, kind: AlertKind) -> Option<&Alert> {
        self.alerts
            .iter()
            .find(|a| a.point.as_deref() == point && a.rule == kind)
    }

    /// Highest open level of a point (for `GET .../points`).
    pub fn level_of(&self, point: &str) -> Option<AlertLevel> {
        self.alerts
            .iter()
            .filter(|a| a.point.as_deref() == Some(point))
            .map(|a| a.level)
            .max()
    }
}

/// Event type (contract names).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum AlertEventType {
    /// A new alert.
    #[serde(rename = "alert.raised")]
    Raised,
    /// Its level rose.
    #[serde(rename = "alert.escalated")]
    Escalated,
    /// Its level fell (still open).
    #[serde(rename = "alert.deescalated")]
    Deescalated,
    /// Acknowledged by a person.
    #[serde(rename = "alert.acknowledged")]
    Acknowledged,
    /// Conditions cleared (or resolved by hand).
    #[serde(rename = "alert.resolved")]
    Resolved,
}

impl AlertEventType {
    /// Contract name, e.g. `alert.raised`.
    pub fn as_str(self) -> &'static str {
        match self {
            AlertEventType::Raised => "alert.raised",
            AlertEventType::Escalated => "alert.escalated",
            AlertEventType::Deescalated => "alert.deescalated",
            AlertEventType::Acknowledged => "alert.acknowledged",
            AlertEventType::Resolved => "alert.resolved",
        }
    }
}

/// One event for the outbox: its type, when, and the alert after the change.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AlertEvent {
    /// Type.
    #[serde(rename = "type")]
    pub event_type: AlertEventType,
    /// When it happened.
    pub timestamp: DateTime<Utc>,
    /// The alert after the change.
    pub alert: Alert,
}

fn fmt_time(t: DateTime<Utc>) -> String {
    t.to_rfc3339_opts(SecondsFormat::Secs, true)
}

fn message(
    site: &str,
    point: Option<&str>,
    kind: AlertKind,
    level: AlertLevel,
    value: Option<f64>,
    rule: Option<&AlertRule>,
    unit: &str,
) -> String {
    let who = point.map_or_else(|| format!("site {site}"), |p| format!("{site}/{p}"));
    let cmp = match rule {
        Some(r) if r.above.is_some() => format!(" above {} {unit}", r.above.unwrap_or_default()),
        Some(r) if r.below.is_some() => format!(" below {} {unit}", r.below.unwrap_or_default()),
        _ => String::new(),
    };
    let v = value.map_or(String::new(), |v| format!(" {v:.2} {unit}"));
    format!("{}: {}{v}{cmp} ({})", who, kind.as_str(), level.as_str())
}

struct Update<'a> {
    point: Option<&'a str>,
    points: Vec<String>,
    kind: AlertKind,
    level: Option<AlertLevel>,
    value: Option<f64>,
    threshold: Option<f64>,
    unit: &'a str,
    rule: Option<&'a AlertRule>,
    epoch: Option<i64>,
    observed_at: Option<DateTime<Utc>>,
    id_suffix: String,
}

fn apply(
    site: &str,
    state: &mut AlertState,
    up: Update<'_>,
    now: DateTime<Utc>,
    events: &mut Vec<AlertEvent>,
) {
    let pos = state
        .alerts
        .iter()
        .position(|a| a.point.as_deref() == up.point && a.rule == up.kind);
    match (pos, up.level) {
        (None, None) => {}
        (None, Some(level)) => {
            let alert = Alert {
                id: format!(
                    "{site}:{}:{}:{}",
                    up.point.unwrap_or("-"),
                    up.kind.as_str(),
                    up.id_suffix
                ),
                site: site.to_string(),
                point: up.point.map(str::to_string),
                points: up.points,
                rule: up.kind,
                level,
                peak_level: level,
                value: up.value,
                threshold: up.threshold,
                unit: up.unit.to_string(),
                epoch: up.epoch,
                observed_at: up.observed_at,
                raised_at: now,
                updated_at: now,
                status: AlertStatus::Open,
                acknowledged_by: None,
                comment: None,
                message: message(site, up.point, up.kind, level, up.value, up.rule, up.unit),
            };
            state.alerts.push(alert.clone());
            events.push(AlertEvent {
                event_type: AlertEventType::Raised,
                timestamp: now,
                alert,
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
                        message(site, up.point, up.kind, a.level, a.value, None, up.unit)
                    );
                    let alert = state.alerts.remove(i);
                    events.push(AlertEvent {
                        event_type: AlertEventType::Resolved,
                        timestamp: now,
                        alert,
                    });
                }
                Some(l) if l != a.level => {
                    let ty = if l > a.level {
                        AlertEventType::Escalated
                    } else {
                        AlertEventType::Deescalated
                    };
                    if l > a.level {
                        // A higher level needs a new acknowledgement.
                        a.status = AlertStatus::Open;
                    }
                    a.level = l;
                    a.peak_level = a.peak_level.max(l);
                    a.threshold = up.threshold;
                    a.updated_at = now;
                    a.message = message(site, up.point, up.kind, l, a.value, up.rule, up.unit);
                    events.push(AlertEvent {
                        event_type: ty,
                        timestamp: now,
                        alert: a.clone(),
                    });
                }
                Some(_) => {}
            }
        }
    }
}

/// Evaluates the rules against one epoch's analysis: returns the new state and the events (in order).
///
/// Points absent from the analysis keep their state. An open `campaign_overdue` resolves (an epoch
/// arrived); `reference_unstable` is raised when the congruence test excludes stable points (its `points`
/// grow with later exclusions) and stays open until resolved by hand ([`resolve`]). Invalid rules (see [`AlertRule::validate`]) never
/// trigger.
pub fn evaluate_alerts(
    config: &AlertConfig,
    state: &AlertState,
    analysis: &EpochAnalysis,
    now: DateTime<Utc>,
) -> (AlertState, Vec<AlertEvent>) {
    let mut st = state.clone();
    let mut events = vec![];
    let site = config.site.as_str();
    let rules: Vec<&AlertRule> = config
        .rules
        .iter()
        .filter(|r| r.validate().is_ok())
        .collect();
    let suffix = analysis.epoch.to_string();
    for p in &analysis.points {
        let name = p.record.point.as_str();
        let mut metrics: Vec<Metric> = vec![];
        for r in &rules {
            if r.applies_to(p.group.as_deref()) && !metrics.contains(&r.metric) {
                metrics.push(r.metric);
            }
        }
        for m in metrics {
            let (value, significant) = m.value(p);
            let mut top: Option<&AlertRule> = None;
            for r in rules
                .iter()
                .filter(|r| r.metric == m && r.applies_to(p.group.as_deref()))
            {
                let key = format!("{name}|{}", r.key());
                let mut mem = st.rules.get(&key).copied().unwrap_or_default();
                let ok = !r.require_significant || significant;
                let triggered = value.is_some_and(|v| ok && r.triggers(v));
                if triggered {
                    mem = RuleMemory {
                        active: true,
                        quiet_epochs: 0,
                    };
                } else if mem.active {
                    let cleared = match value {
                        Some(v) if ok => r.clears(v),
                        _ => r.clears(f64::NAN).map(|_| true),
                    };
                    match cleared {
                        Some(c) => {
                            if c {
                                mem = RuleMemory::default();
                            }
                        }
                        None => {
                            mem.quiet_epochs += 1;
                            if mem.quiet_epochs
                                >= r.quiet_epochs.unwrap_or(config.quiet_epochs).max(1)
                            {
                                mem = RuleMemory::default();
                            }
                        }
                    }
                }
                if mem == RuleMemory::default() {
                    st.rules.remove(&key);
                } else {
                    st.rules.insert(key, mem);
                }
                if mem.active && top.is_none_or(|t| r.level > t.level) {
                    top = Some(*r);
                }
            }
            apply(
                site,
                &mut st,
                Update {
                    point: Some(name),
                    points: vec![],
                    kind: m.into(),
                    level: top.map(|r| r.level),
                    value,
                    threshold: top.and_then(|r| r.threshold()),
                    unit: m.unit(),
                    rule: top,
                    epoch: Some(analysis.epoch),
                    observed_at: Some(analysis.observed_at),
                    id_suffix: suffix.clone(),
                },
                now,
                &mut events,
            );
        }
    }
    // Site level: reference stability.
    let excluded = &analysis.datum.excluded;
    let first = analysis.datum.congruence.first();
    let open_unstable = st.find(None, AlertKind::ReferenceUnstable).map(|a| a.level);
    apply(
        site,
        &mut st,
        Update {
            point: None,
            points: excluded.clone(),
            kind: AlertKind::ReferenceUnstable,
            // Raised when stable points are excluded; it does not resolve by itself (a moved reference point
            // does not move back, and the test's power near its threshold would make it flap): resolve it by
            // hand once the point's role was changed.
            level: if excluded.is_empty() {
                open_unstable
            } else {
                Some(config.reference_unstable_level)
            },
            value: first.map(|t| t.statistic),
            threshold: first.map(|t| t.critical),
            unit: "",
            rule: None,
            epoch: Some(analysis.epoch),
            observed_at: Some(analysis.observed_at),
            id_suffix: suffix.clone(),
        },
        now,
        &mut events,
    );
    if let Some(e) = events
        .last_mut()
        .filter(|e| e.alert.rule == AlertKind::ReferenceUnstable)
    {
        if e.event_type == AlertEventType::Raised {
            e.alert.message = format!(
                "site {site}: stable point(s) {} moved; excluded from the datum",
                excluded.join(", ")
            );
            if let Some(a) = st.alerts.iter_mut().find(|a| a.id == e.alert.id) {
                a.message = e.alert.message.clone();
            }
        }
    }
    // This epoch was analysed: an earlier failure no longer stands.
    apply(
        site,
        &mut st,
        Update {
            point: None,
            points: vec![],
            kind: AlertKind::AnalysisFailed,
            level: None,
            value: None,
            threshold: None,
            unit: "",
            rule: None,
            epoch: Some(analysis.epoch),
            observed_at: Some(analysis.observed_at),
            id_suffix: suffix.clone(),
        },
        now,
        &mut events,
    );
    // An epoch arrived: the campaign is no longer overdue.
    apply(
        site,
        &mut st,
        Update {
            point: None,
            points: vec![],
            kind: AlertKind::CampaignOverdue,
            level: None,
            value: None,
            threshold: None,
            unit: "hours",
            rule: None,
            epoch: Some(analysis.epoch),
            observed_at: Some(analysis.observed_at),
            id_suffix: suffix,
        },
        now,
        &mut events,
    );
    (st, events)
}

/// An epoch whose analysis failed (`reason`, e.g. too few points in common with the reference):
/// raises the site-level `analysis_failed` alert, or keeps the open one up to date (its message
/// names the latest failed epoch; no new event). The next epoch that is analysed resolves it
/// ([`evaluate_alerts`]). A campaign arrived, so an open `campaign_overdue` resolves as well.
pub fn analysis_failed(
    config: &AlertConfig,
    state: &AlertState,
    epoch: i64,
    observed_at: DateTime<Utc>,
    reason: &str,
    now: DateTime<Utc>,
) -> (AlertState, Vec<AlertEvent>) {
    let mut st = state.clone();
    let mut events = vec![];
    let site = config.site.as_str();
    apply(
        site,
        &mut st,
        Update {
            point: None,
            points: vec![],
            kind: AlertKind::AnalysisFailed,
            level: Some(config.analysis_failed_level),
            value: None,
            threshold: None,
            unit: "",
            rule: None,
            epoch: Some(epoch),
            observed_at: Some(observed_at),
            id_suffix: epoch.to_string(),
        },
        now,
        &mut events,
    );
    let text = format!(
        "site {site}: epoch {epoch} ({}) stored without displacements: {reason}",
        fmt_time(observed_at)
    );
    if let Some(a) = st
        .alerts
        .iter_mut()
        .find(|a| a.rule == AlertKind::AnalysisFailed)
    {
        a.message = text.clone();
    }
    for e in &mut events {
        e.alert.message = text.clone();
    }
    apply(
        site,
        &mut st,
        Update {
            point: None,
            points: vec![],
            kind: AlertKind::CampaignOverdue,
            level: None,
            value: None,
            threshold: None,
            unit: "hours",
            rule: None,
            epoch: Some(epoch),
            observed_at: Some(observed_at),
            id_suffix: epoch.to_string(),
        },
        now,
        &mut events,
    );
    (st, events)
}

/// After the derived series was recomputed (reference changed, an epoch arrived out of order):
/// brings the stored alert state to `replayed` — the state the rules reach when replayed from
/// scratch over the recomputed series — without re-sending history staff already received.
///
/// Only the net difference is announced, stamped `now`: an alert open in both keeps its id,
/// raising time and acknowledgement, and gets `alert.escalated` / `alert.deescalated` when its
/// level differs (an escalation needs a new acknowledgement); an alert only in `replayed` is
/// raised; an alert only in `current` is resolved. Intermediate transitions of the replay are
/// not sent. `campaign_overdue` is not part of a replay (it depends on the clock, not on the
/// series) and is kept as it is. The rules' memory is the replay's.
pub fn reconcile(
    current: &AlertState,
    replayed: &AlertState,
    now: DateTime<Utc>,
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
        match current.find(r.point.as_deref(), r.rule) {
            Some(c) => {
                let mut a = r.clone();
                a.id = c.id.clone();
                a.raised_at = c.raised_at;
                a.peak_level = c.peak_level.max(r.level);
                a.acknowledged_by = c.acknowledged_by.clone();
                a.comment = c.comment.clone();
                a.status = c.status;
                a.updated_at = c.updated_at;
                if a.level != c.level {
                    let ty = if a.level > c.level {
                        a.status = AlertStatus::Open;
                        AlertEventType::Escalated
                    } else {
                        AlertEventType::Deescalated
                    };
                    a.updated_at = now;
                    events.push(AlertEvent {
                        event_type: ty,
                        timestamp: now,
                        alert: a.clone(),
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
        if replayed.find(c.point.as_deref(), c.rule).is_none() {
            let mut a = c.clone();
            a.status = AlertStatus::Resolved;
            a.updated_at = now;
            a.message = format!("{} — resolved after the series was recomputed", c.message);
            events.push(AlertEvent {
                event_type: AlertEventType::Resolved,
                timestamp: now,
                alert: a,
            });
        }
    }
    (out, events)
}

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
                point: None,
                points: vec![],
                kind: AlertKind::CampaignOverdue,
                level: Some(config.campaign_overdue_level),
                value: Some(hours),
                threshold: Some(schedule),
                unit: "hours",
                rule: None,
                epoch: None,
                observed_at: Some(last),
                id_suffix: format!("{}", now.timestamp()),
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

/// Acknowledges an open alert: it stays open (until resolved or escalated) but is marked acknowledged.
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
    if let Some(p) = &alert.point {
        let prefix = format!("{p}|{}:", alert.rule.as_str());
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
