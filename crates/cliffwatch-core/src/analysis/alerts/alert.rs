//! An alert, its level and status, the events it goes through (with the rule test that decided a
//! de-escalation or a resolution, [`ClearingTest`]), and the alert state of a site.

use std::collections::BTreeMap;

use chrono::{DateTime, Utc};
use serde::{Deserialize, Serialize};

use super::metric::AlertKind;

/// Alert level; ordered `watch` < `warning` < `alarm` (the default is the lowest).
#[derive(
    Debug, Clone, Copy, Default, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize,
)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(rename_all = "snake_case")]
pub enum AlertLevel {
    /// Lowest level.
    #[default]
    Watch,
    /// Middle level.
    Warning,
    /// Highest level.
    Alarm,
}

crate::contract_names!(AlertLevel, "alert level" {
    Watch => "watch",
    Warning => "warning",
    Alarm => "alarm",
});

/// Lifecycle of an alert.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(rename_all = "snake_case")]
pub enum AlertStatus {
    /// Open, not acknowledged.
    #[default]
    Open,
    /// Open and acknowledged.
    Acknowledged,
    /// Resolved (no longer in the state).
    Resolved,
}

crate::contract_names!(AlertStatus, "alert state" {
    Open => "open",
    Acknowledged => "acknowledged",
    Resolved => "resolved",
});

/// One alert (stored; its snapshot travels in every event).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Alert {
    /// Deterministic id: `{site}:{point or -}:{rule}:{epoch or timestamp}` of the raising (no `/`, so it
    /// fits one URL path segment).
    pub id: String,
    /// Site id.
    pub site: String,
    /// Point, None for site-level and group alerts.
    pub point: Option<String>,
    /// Block group of a group alert (None otherwise).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub group: Option<String>,
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
    /// The epoch id whose evaluation raised it (a replay's: the epoch of the series at which the
    /// replayed rules raised it, not the epoch that caused the replay); absent from states stored
    /// before it was kept.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub raised_epoch: Option<i64>,
    /// Its observation time.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub raised_observed_at: Option<DateTime<Utc>>,
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
    /// Consecutive triggering epochs (counts towards the rule's `for_epochs`).
    #[serde(default)]
    pub streak: u32,
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
        self.find_subject(point, None, kind)
    }

    /// The open alert of a point, or of a block group, or of the site (both None), and kind.
    pub fn find_subject(
        &self,
        point: Option<&str>,
        group: Option<&str>,
        kind: AlertKind,
    ) -> Option<&Alert> {
        self.alerts
            .iter()
            .find(|a| a.point.as_deref() == point && a.group.as_deref() == group && a.rule == kind)
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

crate::contract_names!(AlertEventType, "alert event type" {
    Raised => "alert.raised",
    Escalated => "alert.escalated",
    Deescalated => "alert.deescalated",
    Acknowledged => "alert.acknowledged",
    Resolved => "alert.resolved",
});

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
    /// For a de-escalation or a resolution by the rules: the test that decided it (absent for
    /// other events, for changes by hand or by a replay, and in events stored before it existed).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cleared_by: Option<ClearingTest>,
}

/// How an active rule stopped being active.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(rename_all = "snake_case")]
pub enum ClearedHow {
    /// The value passed the rule's clear threshold (`clear_below` / `clear_above`, the
    /// hysteresis), significant or not.
    PastClearThreshold,
    /// Without a clear threshold: the value no longer exceeded the threshold at the rule's
    /// confidence (`v − z·σ ≤ above`, or `v + z·σ ≥ below`) for `quiet_epochs` epochs.
    NotExceeded,
    /// The value exceeded the threshold but was not significant, and the rule asks for
    /// significance, for `quiet_epochs` epochs.
    NotSignificant,
    /// The epoch had no value of the metric (e.g. no forecast), for `quiet_epochs` epochs.
    NoValue,
}

/// The rule test that made an alert leave a level (`alert.deescalated`, `alert.resolved`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct ClearingTest {
    /// Level of the rule that stopped being active.
    pub level: AlertLevel,
    /// The value the rule read at the deciding epoch (unit of the alert), null without one.
    pub value: Option<f64>,
    /// Its σ (unit of the alert; 0 when unknown).
    pub sigma: f64,
    /// The rule's threshold (`above` or `below`, unit of the alert).
    pub threshold: Option<f64>,
    /// Whether the rule fires below its threshold (`below`, e.g. a time to failure) rather
    /// than above it.
    pub below: bool,
    /// The rule's clear threshold, when it has one (unit of the alert).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub clear_threshold: Option<f64>,
    /// One-sided confidence of the test, in (0.5, 1).
    pub confidence: f64,
    /// The normal quantile of the confidence (the test is `v − z·σ > above`).
    pub z: f64,
    /// Whether the value was significant (the displacement test).
    pub significant: bool,
    /// How the rule cleared.
    pub how: ClearedHow,
    /// Consecutive epochs without triggering that cleared it (0 for a clear threshold).
    pub quiet_epochs: u32,
}
