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
use super::failure::FailureForecast;
use super::stats::normal_quantile;

/// Alert level; ordered `watch` < `warning` < `alarm` (the default is the lowest).
#[derive(
    Debug,
    Clone,
    Copy,
    Default,
    PartialEq,
    Eq,
    PartialOrd,
    Ord,
    Hash,
    Serialize,
    Deserialize,
    utoipa::ToSchema,
)]
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

/// A point metric rules can threshold.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, utoipa::ToSchema)]
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

    /// Where the metric is read by default: either estimate for displacements (the filter sees a
    /// steady creep over the threshold a few epochs earlier, the raw value a sudden step at once;
    /// `docs/accuracy.md` measures both), the Kalman-filtered state for velocity and time to
    /// failure (a raw velocity of noisy epochs flickers).
    pub fn default_source(self) -> Source {
        match self {
            Metric::DisplacementMm | Metric::DisplacementAlongMm => Source::Either,
            Metric::VelocityMmPerDay | Metric::TimeToFailureHours => Source::Filtered,
        }
    }

    fn index(self) -> usize {
        match self {
            Metric::DisplacementMm => 0,
            Metric::DisplacementAlongMm => 1,
            Metric::VelocityMmPerDay => 2,
            Metric::TimeToFailureHours => 3,
        }
    }
}

/// Which estimate of a metric a rule reads (contract: `"source": "raw" | "filtered"`, and
/// `"either"`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, utoipa::ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum Source {
    /// The epoch's own value (displacement against the reference; velocity and time to failure
    /// from least-squares fits over the last epochs).
    Raw,
    /// The Kalman filter's estimate at the epoch (see [`super::kalman`]).
    Filtered,
    /// Both: the rule triggers when either estimate exceeds the threshold at the confidence, and
    /// clears when both do.
    Either,
}

/// One value of a metric with its σ (unit of the metric) and whether it is significant.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Reading {
    /// The value (None when not available, e.g. no forecast).
    pub value: Option<f64>,
    /// Its σ (0 when unknown).
    pub sigma: f64,
    /// Whether the value differs significantly from zero (the raw displacement test; filtered
    /// values carry their own σ and count as significant).
    pub significant: bool,
}

impl Reading {
    /// A value with σ, significant.
    pub fn new(value: Option<f64>, sigma: Option<f64>) -> Self {
        Reading {
            value,
            sigma: sigma.filter(|s| s.is_finite() && *s >= 0.0).unwrap_or(0.0),
            significant: value.is_some(),
        }
    }

    /// The time to failure (hours) of a forecast with its σ; no value without one.
    pub fn forecast(f: Option<FailureForecast>) -> Self {
        Reading::new(f.map(|f| f.time_to_failure_hours), f.map(|f| f.sigma_hours))
    }
}

/// The values the rules can read for one subject (a point or a block): per [`Source`], one
/// [`Reading`] per [`Metric`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Readings {
    /// Raw readings, indexed like [`Metric`] (displacement, along, velocity, time to failure).
    pub raw: [Reading; 4],
    /// Filtered readings, same order.
    pub filtered: [Reading; 4],
}

impl Readings {
    /// The reading of `metric` from `source` ([`Source::Either`]: the raw one, as shown).
    pub fn get(&self, metric: Metric, source: Source) -> Reading {
        match source {
            Source::Raw | Source::Either => self.raw[metric.index()],
            Source::Filtered => self.filtered[metric.index()],
        }
    }

    /// Sets the reading of `metric` from `source`.
    pub fn set(&mut self, metric: Metric, source: Source, reading: Reading) {
        match source {
            Source::Raw | Source::Either => self.raw[metric.index()] = reading,
            Source::Filtered => self.filtered[metric.index()] = reading,
        }
    }

    /// The readings of a point's analysis.
    pub fn of_point(p: &PointAnalysis) -> Self {
        let r = &p.record;
        let mut out = Readings::default();
        out.set(
            Metric::DisplacementMm,
            Source::Raw,
            Reading {
                value: Some(r.d_mm),
                sigma: r.sigma_mm,
                significant: r.significant,
            },
        );
        out.set(
            Metric::DisplacementAlongMm,
            Source::Raw,
            Reading {
                value: r.d_along_mm,
                sigma: p.sigma_along_mm.unwrap_or(0.0),
                significant: r.significant,
            },
        );
        out.set(
            Metric::VelocityMmPerDay,
            Source::Raw,
            Reading {
                value: r.velocity_mm_per_day,
                sigma: p.kinematics.map_or(0.0, |k| k.sigma_velocity_mm_per_day),
                significant: r.significant && p.kinematics.is_some_and(|k| k.velocity_significant),
            },
        );
        // A forecast exists only for a significant, accelerating point.
        out.set(
            Metric::TimeToFailureHours,
            Source::Raw,
            Reading::forecast(p.failure),
        );
        if let Some(f) = &r.filtered {
            out.set(
                Metric::DisplacementMm,
                Source::Filtered,
                Reading::new(Some(f.f_d_mm), Some(f.sigma_f_d_mm)),
            );
            out.set(
                Metric::VelocityMmPerDay,
                Source::Filtered,
                Reading::new(
                    Some(f.f_velocity_mm_per_day),
                    Some(f.sigma_f_velocity_mm_per_day),
                ),
            );
        }
        if let Some((d, s)) = p.filtered_along_mm {
            out.set(
                Metric::DisplacementAlongMm,
                Source::Filtered,
                Reading::new(Some(d), Some(s)),
            );
        }
        if let Some(f) = &p.filtered_failure {
            out.set(
                Metric::TimeToFailureHours,
                Source::Filtered,
                Reading::new(Some(f.time_to_failure_hours), Some(f.sigma_hours)),
            );
        }
        out
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

/// Bounds of a site's or a rule's `confidence`: the open interval (0.5, 1) as numbers that stay
/// inside it once parsed (a JSON 0.99999999999999999 reads as 1.0).
pub const MIN_CONFIDENCE: f64 = 0.500_001;
/// See [`MIN_CONFIDENCE`].
pub const MAX_CONFIDENCE: f64 = 0.999_999;

/// Largest `for_epochs` and `quiet_epochs` of a rule.
pub const MAX_EPOCHS: u32 = 1000;

/// One alert rule (contract JSON, plus optional fields).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
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
    /// Restricts the rule to points of this group (all points and all declared blocks when
    /// absent); when the group is declared a block, the rule applies to the block's motion
    /// instead of its single points.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub group: Option<String>,
    /// Which estimate the rule reads (default: [`Metric::default_source`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub source: Option<Source>,
    /// Consecutive triggering epochs needed before the rule becomes active (default 1).
    #[serde(
        default,
        skip_serializing_if = "Option::is_none",
        deserialize_with = "crate::json_integer::optional_u32"
    )]
    #[schema(minimum = 1, maximum = 1000)]
    pub for_epochs: Option<u32>,
    /// Only significant values trigger (default true).
    #[serde(default = "yes")]
    pub require_significant: bool,
    /// Without a clear threshold: epochs without triggering before the rule clears (default: the config's).
    #[serde(
        default,
        skip_serializing_if = "Option::is_none",
        deserialize_with = "crate::json_integer::optional_u32"
    )]
    #[schema(maximum = 1000)]
    pub quiet_epochs: Option<u32>,
    /// One-sided confidence at which the value must exceed the threshold, in (0.5, 1) (default
    /// [`AlertRule::confidence`]: the site's, and for `time_to_failure_hours` at most
    /// [`FORECAST_CONFIDENCE`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(minimum = 0.500_001, maximum = 0.999_999)]
    pub confidence: Option<f64>,
}

/// Default confidence of a `time_to_failure_hours` rule, when the site's is higher: the forecast
/// exists only once the onset test has shown an acceleration (Δχ² > 13.82), so this confidence
/// decides how early the alarm comes, not whether the point moves. On 130 simulated failing
/// series (docs/accuracy.md) the alarm came 24–120 h before failure in 92 % of them at 0.95 and
/// in 88 % at 0.99; at 0.95, 4 of 129 alarms came more than 96 h before failure.
pub const FORECAST_CONFIDENCE: f64 = 0.95;

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
        if self
            .for_epochs
            .is_some_and(|n| !(1..=MAX_EPOCHS).contains(&n))
        {
            return bad("for_epochs must be 1 to 1000");
        }
        if self.quiet_epochs.is_some_and(|n| n > MAX_EPOCHS) {
            return bad("quiet_epochs must be at most 1000");
        }
        if self
            .confidence
            .is_some_and(|c| !(MIN_CONFIDENCE..=MAX_CONFIDENCE).contains(&c))
        {
            return bad("confidence must lie in (0.5, 1): 0.500001 to 0.999999");
        }
        Ok(())
    }

    /// The rule's one-sided confidence given the site's: its own `confidence` when set, else the
    /// site's, lowered to [`FORECAST_CONFIDENCE`] for `time_to_failure_hours` rules.
    pub fn confidence(&self, site: f64) -> f64 {
        self.confidence.unwrap_or(match self.metric {
            Metric::TimeToFailureHours => site.min(FORECAST_CONFIDENCE),
            _ => site,
        })
    }

    /// The normal quantile `z` of [`AlertRule::confidence`] (0 when it is out of range).
    fn z(&self, site: f64) -> f64 {
        let c = self.confidence(site);
        if c > 0.5 && c < 1.0 {
            normal_quantile(c)
        } else {
            0.0
        }
    }

    /// The estimate the rule reads.
    pub fn source(&self) -> Source {
        self.source.unwrap_or(self.metric.default_source())
    }

    fn applies_to(&self, group: Option<&str>) -> bool {
        self.group.as_deref().is_none_or(|g| Some(g) == group)
    }

    fn threshold(&self) -> Option<f64> {
        self.above.or(self.below)
    }

    /// Whether the value exceeds the threshold at one-sided confidence: `v − z·σ > above` or
    /// `v + z·σ < below`, σ the value's own σ (`z` the normal quantile of the rule's confidence).
    fn triggers(&self, v: f64, sigma: f64, z: f64) -> bool {
        match (self.above, self.below) {
            (Some(a), None) => v - z * sigma > a,
            (None, Some(b)) => v + z * sigma < b,
            _ => false,
        }
    }

    /// The reading the rule judges: that of its source; for [`Source::Either`] the raw one if it
    /// triggers, else the filtered one if it triggers, else the one farther over the threshold's
    /// side (so the rule clears only when both have).
    fn reading(&self, readings: &Readings, metric: Metric, z: f64) -> Reading {
        if self.source() != Source::Either {
            return readings.get(metric, self.source());
        }
        let raw = readings.get(metric, Source::Raw);
        let filtered = readings.get(metric, Source::Filtered);
        let fires = |r: &Reading| {
            (!self.require_significant || r.significant)
                && r.value.is_some_and(|v| self.triggers(v, r.sigma, z))
        };
        if fires(&raw) {
            return raw;
        }
        if fires(&filtered) {
            return filtered;
        }
        match (raw.value, filtered.value) {
            (Some(a), Some(b)) => {
                let filtered_worse = if self.below.is_some() { b < a } else { b > a };
                if filtered_worse {
                    filtered
                } else {
                    raw
                }
            }
            (None, Some(_)) => filtered,
            _ => raw,
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
        let mut k = format!(
            "{}:{}:{}:{}:{}",
            AlertKind::from(self.metric).as_str(),
            self.level.as_str(),
            self.above.map_or("-".into(), |a| format!("above{a}")),
            self.below.map_or("-".into(), |b| format!("below{b}")),
            self.group.as_deref().unwrap_or("*")
        );
        if self.source.is_some() || self.for_epochs.is_some() {
            let src = match self.source() {
                Source::Raw => "raw",
                Source::Filtered => "filtered",
                Source::Either => "either",
            };
            k.push_str(&format!(":{src}:{}", self.for_epochs.unwrap_or(1)));
        }
        if let Some(c) = self.confidence {
            k.push_str(&format!(":c{c}"));
        }
        k
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
fn default_confidence() -> f64 {
    0.99
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
    /// One-sided confidence at which a value must exceed a rule's threshold (the site's
    /// `confidence`, in (0.5, 1); default 0.99).
    #[serde(default = "default_confidence")]
    pub confidence: f64,
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
            confidence: 0.99,
        }
    }

    /// Validates the confidence and every rule.
    pub fn validate(&self) -> Result<(), AnalysisError> {
        if !(self.confidence > 0.5 && self.confidence < 1.0) {
            return Err(AnalysisError::InvalidConfig(
                "confidence must lie in (0.5, 1)".into(),
            ));
        }
        self.rules.iter().try_for_each(AlertRule::validate)
    }

    /// The one-sided normal quantile of [`AlertConfig::confidence`] (0 when it is out of range).
    pub fn z(&self) -> f64 {
        if self.confidence > 0.5 && self.confidence < 1.0 {
            normal_quantile(self.confidence)
        } else {
            0.0
        }
    }
}

/// Lifecycle of an alert.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, utoipa::ToSchema)]
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
}

fn fmt_time(t: DateTime<Utc>) -> String {
    t.to_rfc3339_opts(SecondsFormat::Secs, true)
}

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
enum Subject<'a> {
    Point(&'a str),
    Group(&'a str),
    Site,
}

impl<'a> Subject<'a> {
    fn point(self) -> Option<&'a str> {
        match self {
            Subject::Point(p) => Some(p),
            _ => None,
        }
    }

    fn group(self) -> Option<&'a str> {
        match self {
            Subject::Group(g) => Some(g),
            _ => None,
        }
    }

    /// Prefix of the subject's rule memories in [`AlertState::rules`].
    fn memory_prefix(self) -> String {
        match self {
            Subject::Point(p) => format!("{p}|"),
            Subject::Group(g) => format!("group:{g}|"),
            Subject::Site => "-|".into(),
        }
    }
}

struct Update<'a> {
    subject: Subject<'a>,
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
                    a.message = message(site, up.subject, up.kind, l, a.value, up.rule, up.unit);
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

/// A point or block with the values its rules read.
struct SubjectReadings<'a> {
    subject: Subject<'a>,
    points: Vec<String>,
    readings: Readings,
}

/// Runs `rules` (those applying to the subject) over its readings: updates their memories
/// (hysteresis, persistence) and the subject's alert per metric.
#[allow(clippy::too_many_arguments)]
fn evaluate_subject(
    config: &AlertConfig,
    st: &mut AlertState,
    s: &SubjectReadings<'_>,
    rules: &[&AlertRule],
    analysis: &EpochAnalysis,
    suffix: &str,
    now: DateTime<Utc>,
    events: &mut Vec<AlertEvent>,
) {
    let mut metrics: Vec<Metric> = vec![];
    for r in rules {
        if !metrics.contains(&r.metric) {
            metrics.push(r.metric);
        }
    }
    let prefix = s.subject.memory_prefix();
    for m in metrics {
        let mut top: Option<&AlertRule> = None;
        let mut shown = s.readings.get(m, m.default_source()).value;
        for r in rules.iter().filter(|r| r.metric == m) {
            let z = r.z(config.confidence);
            let reading = r.reading(&s.readings, m, z);
            let key = format!("{prefix}{}", r.key());
            let mut mem = st.rules.get(&key).copied().unwrap_or_default();
            let ok = !r.require_significant || reading.significant;
            let triggered = reading
                .value
                .is_some_and(|v| ok && r.triggers(v, reading.sigma, z));
            if triggered {
                mem.streak = mem.streak.saturating_add(1);
                if mem.streak >= r.for_epochs.unwrap_or(1).max(1) {
                    mem.active = true;
                }
                mem.quiet_epochs = 0;
            } else {
                mem.streak = 0;
                if mem.active {
                    let cleared = match reading.value {
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
            }
            if mem == RuleMemory::default() {
                st.rules.remove(&key);
            } else {
                st.rules.insert(key, mem);
            }
            if mem.active && top.is_none_or(|t| r.level > t.level) {
                top = Some(*r);
                shown = reading.value;
            }
        }
        apply(
            &config.site,
            st,
            Update {
                subject: s.subject,
                points: s.points.clone(),
                kind: m.into(),
                level: top.map(|r| r.level),
                value: shown,
                threshold: top.and_then(|r| r.threshold()),
                unit: m.unit(),
                rule: top,
                epoch: Some(analysis.epoch),
                observed_at: Some(analysis.observed_at),
                id_suffix: suffix.to_string(),
            },
            now,
            events,
        );
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
    let blocks: Vec<&str> = analysis.blocks.iter().map(|b| b.group.as_str()).collect();
    // A rule naming a block group applies to the block's motion, not to its single points; a
    // rule without a group applies to every point and every declared block.
    let (block_rules, point_rules): (Vec<&AlertRule>, Vec<&AlertRule>) = rules
        .iter()
        .partition(|r| r.group.as_deref().is_some_and(|g| blocks.contains(&g)));
    for p in &analysis.points {
        let applicable: Vec<&AlertRule> = point_rules
            .iter()
            .copied()
            .filter(|r| r.applies_to(p.group.as_deref()))
            .collect();
        let subject = SubjectReadings {
            subject: Subject::Point(p.record.point.as_str()),
            points: vec![],
            readings: Readings::of_point(p),
        };
        evaluate_subject(
            config,
            &mut st,
            &subject,
            &applicable,
            analysis,
            &suffix,
            now,
            &mut events,
        );
    }
    for b in &analysis.blocks {
        let applicable: Vec<&AlertRule> = block_rules
            .iter()
            .chain(point_rules.iter())
            .copied()
            .filter(|r| r.group.as_deref().is_none_or(|g| g == b.group.as_str()))
            .collect();
        let subject = SubjectReadings {
            subject: Subject::Group(b.group.as_str()),
            points: b.points.clone(),
            readings: b.readings,
        };
        evaluate_subject(
            config,
            &mut st,
            &subject,
            &applicable,
            analysis,
            &suffix,
            now,
            &mut events,
        );
    }
    // Site level: reference stability.
    let excluded = &analysis.datum.excluded;
    let first = analysis.datum.congruence.first();
    let open_unstable = st.find(None, AlertKind::ReferenceUnstable).map(|a| a.level);
    apply(
        site,
        &mut st,
        Update {
            subject: Subject::Site,
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
            subject: Subject::Site,
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
            subject: Subject::Site,
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
            subject: Subject::Site,
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
            subject: Subject::Site,
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
        match current.find_subject(r.point.as_deref(), r.group.as_deref(), r.rule) {
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
        if replayed
            .find_subject(c.point.as_deref(), c.group.as_deref(), c.rule)
            .is_none()
        {
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
                subject: Subject::Site,
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
