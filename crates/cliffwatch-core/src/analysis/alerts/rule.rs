//! One alert rule (threshold, hysteresis, persistence, confidence) and a site's alert
//! configuration.

use serde::{Deserialize, Serialize};

use super::alert::AlertLevel;
use super::metric::{AlertKind, Metric, Source};
use super::readings::{Reading, Readings};
use crate::analysis::error::AnalysisError;
use crate::analysis::stats::normal_quantile;

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

/// Largest magnitude of a rule's thresholds (`above`, `below`, `clear_below`, `clear_above`) in
/// the metric's unit: 10⁹ mm is 1000 km, 10⁹ h over 100 000 years. A JSON number beyond f64's
/// range (1e400) cannot be read at all; the bound makes the documented range say so. (utoipa's
/// `minimum`/`maximum` take literals only: a test checks that the schema shows this value.)
pub const MAX_THRESHOLD: f64 = 1e9;

/// One alert rule (contract JSON, plus optional fields).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct AlertRule {
    /// Level raised when the rule triggers.
    pub level: AlertLevel,
    /// Metric thresholded.
    pub metric: Metric,
    /// Triggers when the value is above this (unit of the metric).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "openapi", schema(minimum = -1_000_000_000.0, maximum = 1_000_000_000.0))]
    pub above: Option<f64>,
    /// Triggers when the value is below this (unit of the metric).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "openapi", schema(minimum = -1_000_000_000.0, maximum = 1_000_000_000.0))]
    pub below: Option<f64>,
    /// Hysteresis of an `above` rule: once active, clears only below this value.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "openapi", schema(minimum = -1_000_000_000.0, maximum = 1_000_000_000.0))]
    pub clear_below: Option<f64>,
    /// Hysteresis of a `below` rule: once active, clears only above this value.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "openapi", schema(minimum = -1_000_000_000.0, maximum = 1_000_000_000.0))]
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
        deserialize_with = "crate::contract::json_integer::optional_u32"
    )]
    #[cfg_attr(feature = "openapi", schema(minimum = 1, maximum = 1000))]
    pub for_epochs: Option<u32>,
    /// Only significant values trigger (default true).
    #[serde(default = "yes")]
    pub require_significant: bool,
    /// Without a clear threshold: epochs without triggering before the rule clears (default: the config's).
    #[serde(
        default,
        skip_serializing_if = "Option::is_none",
        deserialize_with = "crate::contract::json_integer::optional_u32"
    )]
    #[cfg_attr(feature = "openapi", schema(maximum = 1000))]
    pub quiet_epochs: Option<u32>,
    /// One-sided confidence at which the value must exceed the threshold, in (0.5, 1) (default
    /// [`AlertRule::confidence`]: the site's, and for `time_to_failure_hours` at most
    /// [`FORECAST_CONFIDENCE`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "openapi", schema(minimum = 0.500_001, maximum = 0.999_999))]
    pub confidence: Option<f64>,
}

/// The JSON type of a value, for messages.
fn json_kind(v: &serde_json::Value) -> &'static str {
    match v {
        serde_json::Value::Null => "null",
        serde_json::Value::Bool(_) => "a boolean",
        serde_json::Value::Number(_) => "a number",
        serde_json::Value::String(_) => "a string",
        serde_json::Value::Array(_) => "an array",
        serde_json::Value::Object(_) => "an object",
    }
}

/// Why [`AlertRule::from_json`] refused a rule: the member at fault and what is wrong with it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RuleRefused {
    /// The member at fault (`metric`, a misspelt `clear_bellow`); None: the rule as a whole.
    pub member: Option<String>,
    /// What is wrong and what was expected.
    pub message: String,
}

impl RuleRefused {
    /// The message for a rule found at `path` (e.g. `alert_rules[2]`): `path.member: message`,
    /// or `path: message` for the rule as a whole.
    pub fn at(&self, path: &str) -> String {
        match &self.member {
            Some(m) => format!("{path}.{m}: {}", self.message),
            None => format!("{path}: {}", self.message),
        }
    }
}

impl std::fmt::Display for RuleRefused {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match &self.member {
            Some(m) => write!(f, "{m}: {}", self.message),
            None => f.write_str(&self.message),
        }
    }
}

/// Member `key` of a rule, a contract name of `T`: missing (when `required`), not a string, or
/// not one of the names is an error naming the member and the names known.
fn named<T>(
    members: &serde_json::Map<String, serde_json::Value>,
    key: &str,
    required: bool,
) -> Result<(), RuleRefused>
where
    T: std::str::FromStr<Err = crate::contract::names::UnknownName>,
{
    // The names known, from the refusal of a name no enum has.
    let expected = || {
        "\u{0}"
            .parse::<T>()
            .err()
            .map_or_else(String::new, |e| e.expected.to_string())
    };
    let refused = |message: String| RuleRefused {
        member: Some(key.to_string()),
        message,
    };
    match members.get(key) {
        None if required => Err(refused(format!("missing; one of {}", expected()))),
        None => Ok(()),
        Some(serde_json::Value::String(s)) => s
            .parse::<T>()
            .map(|_| ())
            .map_err(|e| refused(e.to_string())),
        Some(other) => Err(refused(format!(
            "{} given; one of {}",
            json_kind(other),
            expected()
        ))),
    }
}

/// Default confidence of a `time_to_failure_hours` rule, when the site's is higher: the rule
/// fires when the forecast's one-sided upper bound at this confidence (`hours + z·σ`) is below
/// its threshold. The forecast exists only once the onset test has shown an acceleration and the
/// forecasts of the last 48 h agree with it, so this confidence decides how early the alarm
/// comes, not whether the point moves (docs/accuracy.md, the time-to-failure benchmark).
pub const FORECAST_CONFIDENCE: f64 = crate::analysis::failure::BOUND_CONFIDENCE;

/// Fraction of a `velocity_mm_per_day` rule's threshold past which it clears when it names no
/// `clear_below` (`clear_above`): a velocity near its threshold wobbles with the noise of the
/// filter, and without hysteresis one epoch raised the level and the next resolved it (raised at
/// epochs 24, 26 and 30, resolved at 25 and 27). Displacement rules carry their own clear
/// threshold in the contract's examples; a velocity that has fallen by a fifth has slowed.
pub const VELOCITY_CLEAR_FRACTION: f64 = 0.8;

/// The members of an alert rule in the contract JSON; the API refuses others (a misspelt
/// `clear_bellow` would otherwise be stored and ignored).
pub const RULE_MEMBERS: [&str; 12] = [
    "level",
    "metric",
    "above",
    "below",
    "clear_below",
    "clear_above",
    "group",
    "source",
    "for_epochs",
    "require_significant",
    "quiet_epochs",
    "confidence",
];

impl AlertRule {
    /// Reads a rule of the contract JSON and [`validate`](Self::validate)s it; the error names
    /// the member at fault (`metric: unknown metric 'displacement_m' (one of …)`, `clear_bellow:
    /// unknown member; …`), so that a caller only prefixes where the rule stands.
    pub fn from_json(rule: &serde_json::Value) -> Result<AlertRule, RuleRefused> {
        let whole = |message: String| RuleRefused {
            member: None,
            message,
        };
        let Some(members) = rule.as_object() else {
            return Err(whole(format!(
                "a rule is a JSON object with level, metric and above or below, not {}",
                json_kind(rule)
            )));
        };
        if let Some(unknown) = members.keys().find(|k| !RULE_MEMBERS.contains(&k.as_str())) {
            return Err(RuleRefused {
                member: Some(crate::contract::truncate_for_message(unknown).into_owned()),
                message: format!("unknown member; a rule has {}", RULE_MEMBERS.join(", ")),
            });
        }
        named::<AlertLevel>(members, "level", true)?;
        named::<Metric>(members, "metric", true)?;
        named::<Source>(members, "source", false)?;
        if !["above", "below"]
            .iter()
            .any(|k| members.get(*k).is_some_and(serde_json::Value::is_number))
        {
            return Err(whole(
                "needs a numeric `above` or `below` (the threshold, in the metric's unit)".into(),
            ));
        }
        let parsed: AlertRule =
            serde_json::from_value(rule.clone()).map_err(|e| whole(e.to_string()))?;
        parsed.validate().map_err(|e| {
            whole(match e {
                AnalysisError::InvalidConfig(m) => m,
                other => other.to_string(),
            })
        })?;
        Ok(parsed)
    }

    /// Checks that exactly one of `above` / `below` is set, finite, and that the clear threshold
    /// lies on the right side; that no threshold exceeds ±`MAX_THRESHOLD`; that a
    /// `time_to_failure_hours` rule has a positive `below` and a `displacement_mm` rule a
    /// threshold of at least 0.
    pub fn validate(&self) -> Result<(), AnalysisError> {
        let bad = |m: &str| {
            Err(AnalysisError::InvalidConfig(format!(
                "{} rule: {m}",
                AlertKind::from(self.metric).as_str()
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
        if [self.above, self.below, self.clear_below, self.clear_above]
            .into_iter()
            .flatten()
            .any(|x| !(x.abs() <= MAX_THRESHOLD))
        {
            return bad(&format!(
                "above, below, clear_below and clear_above must lie within ±{MAX_THRESHOLD:e}"
            ));
        }
        if self.above.is_some() && self.clear_above.is_some() {
            return bad(
                "clear_above belongs to a `below` rule; an `above` rule clears below clear_below",
            );
        }
        if self.below.is_some() && self.clear_below.is_some() {
            return bad(
                "clear_below belongs to an `above` rule; a `below` rule clears above clear_above",
            );
        }
        // A rule must not fire on a point that has not moved (zero, at the reference epoch).
        match (self.metric, self.above, self.below) {
            (Metric::TimeToFailureHours, Some(_), _) => {
                return bad("takes `below`: the rule fires when failure is forecast sooner than that many hours")
            }
            (Metric::TimeToFailureHours, _, Some(b)) if !(b > 0.0) => {
                return bad("`below` must be a positive number of hours")
            }
            (Metric::DisplacementMm, _, Some(_)) => {
                return bad("d_mm is a length: the rule takes `above` (a `below` rule would fire on every still point)")
            }
            (Metric::DisplacementMm, Some(a), _)
                if a < 0.0 || self.clear_below.is_some_and(|c| c < 0.0) =>
            {
                return bad("d_mm is a length: `above` and clear_below must not be negative")
            }
            (Metric::DisplacementAlongMm | Metric::VelocityMmPerDay, Some(a), _) if a < 0.0 => {
                return bad("`above` must be at least 0 (a negative one fires on every still point); use `below` for motion against the direction")
            }
            (Metric::DisplacementAlongMm | Metric::VelocityMmPerDay, _, Some(b)) if b > 0.0 => {
                return bad("`below` must be at most 0 (a positive one fires on every still point); use `above` for motion along the direction")
            }
            _ => {}
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
    pub(super) fn z(&self, site: f64) -> f64 {
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

    pub(super) fn applies_to(&self, group: Option<&str>) -> bool {
        self.group.as_deref().is_none_or(|g| Some(g) == group)
    }

    pub(super) fn threshold(&self) -> Option<f64> {
        self.above.or(self.below)
    }

    /// Whether the value exceeds the threshold at one-sided confidence: `v − z·σ > above` or
    /// `v + z·σ < below`, σ the value's own σ (`z` the normal quantile of the rule's confidence).
    pub(super) fn triggers(&self, v: f64, sigma: f64, z: f64) -> bool {
        match (self.above, self.below) {
            (Some(a), None) => v - z * sigma > a,
            (None, Some(b)) => v + z * sigma < b,
            _ => false,
        }
    }

    /// The reading the rule judges: that of its source; for [`Source::Either`] the raw one if it
    /// triggers, else the filtered one if it triggers, else the one farther over the threshold's
    /// side (so the rule clears only when both have).
    pub(super) fn reading(&self, readings: &Readings, metric: Metric, z: f64) -> Reading {
        if self.source() != Source::Either {
            return readings.get(metric, self.source());
        }
        let raw = readings.get(metric, Source::Raw);
        let filtered = readings.get(metric, Source::Filtered);
        if self.fires(&raw, z) {
            return raw;
        }
        if self.fires(&filtered, z) {
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

    /// Whether `r` triggers the rule: significant when the rule asks for it, and over the
    /// threshold at the confidence's `z`.
    pub(super) fn fires(&self, r: &Reading, z: f64) -> bool {
        (!self.require_significant || r.significant)
            && r.value.is_some_and(|v| self.triggers(v, r.sigma, z))
    }

    /// Consecutive triggering epochs the rule needs before it becomes active: its `for_epochs`
    /// (at least 1), and at least 2 for an [`Source::Either`] rule whose filtered value does not
    /// trigger: a raw exceedance alone is confirmed by the next epoch (or by the filter) before
    /// it alerts, as a total station re-measures before it alarms, so one noisy epoch never
    /// raises an alert by itself.
    pub(super) fn epochs_needed(&self, readings: &Readings, metric: Metric, z: f64) -> u32 {
        let asked = self.for_epochs.unwrap_or(1).max(1);
        if self.source() == Source::Either
            && !self.fires(&readings.get(metric, Source::Filtered), z)
        {
            asked.max(2)
        } else {
            asked
        }
    }

    /// The value past which an active rule clears: its `clear_below` / `clear_above`, and for a
    /// `velocity_mm_per_day` rule that names none, [`VELOCITY_CLEAR_FRACTION`] of its threshold
    /// (unit of the metric). `None`: the rule clears after its quiet epochs.
    pub fn clear_threshold(&self) -> Option<f64> {
        let velocity = self.metric == Metric::VelocityMmPerDay;
        match (self.above, self.below) {
            (Some(a), None) => self
                .clear_below
                .or((velocity && a > 0.0).then_some(VELOCITY_CLEAR_FRACTION * a)),
            (None, Some(b)) => self
                .clear_above
                .or((velocity && b < 0.0).then_some(VELOCITY_CLEAR_FRACTION * b)),
            _ => None,
        }
    }

    /// Whether an active rule clears at this value (with a clear threshold,
    /// [`AlertRule::clear_threshold`]).
    pub(super) fn clears(&self, v: f64) -> Option<bool> {
        match (self.above, self.below) {
            (Some(_), None) => self.clear_threshold().map(|c| v < c),
            (None, Some(_)) => self.clear_threshold().map(|c| v > c),
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
fn default_reference_quiet() -> u32 {
    10
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
    /// Consecutive epochs a confirmed moved stable point must be kept in the datum by the
    /// congruence test before `reference_unstable` stops naming it (default 10; long, because a
    /// point moved by a few σ passes the test about every other epoch).
    #[serde(default = "default_reference_quiet")]
    pub reference_quiet_epochs: u32,
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
            reference_quiet_epochs: default_reference_quiet(),
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

#[cfg(test)]
mod tests {
    use super::*;

    /// [`RULE_MEMBERS`] names exactly the members of [`AlertRule`].
    #[test]
    fn the_member_list_matches_the_rule() {
        let every: AlertRule = serde_json::from_str(
            r#"{"level": "watch", "metric": "displacement_mm", "above": 5, "below": 1,
                "clear_below": 4, "clear_above": 2, "group": "B1", "source": "raw",
                "for_epochs": 2, "require_significant": true, "quiet_epochs": 3,
                "confidence": 0.9}"#,
        )
        .unwrap();
        let v = serde_json::to_value(&every).unwrap();
        let mut keys: Vec<&str> = v.as_object().unwrap().keys().map(String::as_str).collect();
        let mut want = RULE_MEMBERS.to_vec();
        keys.sort_unstable();
        want.sort_unstable();
        assert_eq!(keys, want);
    }

    /// Rules that would fire on a point that never moved are refused, naming the metric.
    #[test]
    fn rules_firing_on_still_points_are_refused() {
        let rule = |json: &str| serde_json::from_str::<AlertRule>(json).unwrap().validate();
        for bad in [
            r#"{"level": "watch", "metric": "displacement_mm", "below": 5}"#,
            r#"{"level": "watch", "metric": "displacement_mm", "above": 5, "clear_below": -1}"#,
            r#"{"level": "watch", "metric": "displacement_along_mm", "below": 1}"#,
            r#"{"level": "watch", "metric": "velocity_mm_per_day", "above": -0.5}"#,
            r#"{"level": "alarm", "metric": "time_to_failure_hours", "below": 48, "clear_below": 72}"#,
            r#"{"level": "watch", "metric": "displacement_mm", "above": 5, "clear_above": 9}"#,
        ] {
            let e = rule(bad).unwrap_err().to_string();
            assert!(e.contains(" rule: "), "{bad}: {e}");
        }
        for good in [
            r#"{"level": "watch", "metric": "displacement_mm", "above": 0}"#,
            r#"{"level": "watch", "metric": "displacement_along_mm", "below": -5, "clear_above": -4}"#,
            r#"{"level": "watch", "metric": "velocity_mm_per_day", "above": 1, "clear_below": 0.5}"#,
            r#"{"level": "alarm", "metric": "time_to_failure_hours", "below": 48, "clear_above": 72}"#,
        ] {
            assert_eq!(rule(good).map_err(|e| e.to_string()), Ok(()), "{good}");
        }
    }

    /// An unknown metric, level, source or member is named as such, with what is known.
    #[test]
    fn unknown_names_and_members_are_named() {
        let parse = |json: &str| {
            AlertRule::from_json(&serde_json::from_str(json).unwrap()).map_err(|e| e.to_string())
        };
        for (bad, want) in [
            (
                r#"{"level": "watch", "metric": "displacement_m", "above": 5}"#,
                "metric: unknown metric 'displacement_m' (one of displacement_mm, \
                 displacement_along_mm, velocity_mm_per_day, time_to_failure_hours)",
            ),
            (
                r#"{"level": "loud", "metric": "displacement_mm", "above": 5}"#,
                "level: unknown alert level 'loud' (one of watch, warning, alarm)",
            ),
            (
                r#"{"level": "watch", "metric": "displacement_mm", "above": 5, "source": "kalman"}"#,
                "source: unknown source 'kalman' (one of raw, filtered, either)",
            ),
            (
                r#"{"level": "watch", "metric": "displacement_mm", "above": 5, "clear_bellow": 4}"#,
                "clear_bellow: unknown member; a rule has level, metric",
            ),
            (
                r#"{"metric": "displacement_mm", "above": 5}"#,
                "level: missing; one of watch, warning, alarm",
            ),
            (
                r#"{"level": "watch", "metric": 3, "above": 5}"#,
                "metric: a number given; one of displacement_mm",
            ),
            (
                r#"{"level": "watch", "metric": "displacement_mm", "above": "5"}"#,
                "needs a numeric `above` or `below`",
            ),
            (r#"["watch"]"#, "a rule is a JSON object"),
            (
                r#"{"level": "watch", "metric": "displacement_mm", "below": 5}"#,
                "displacement_mm rule: d_mm is a length",
            ),
        ] {
            let e = parse(bad).unwrap_err();
            assert!(e.starts_with(want), "{bad}: {e}");
        }
        let good = parse(r#"{"level": "alarm", "metric": "velocity_mm_per_day", "above": 2}"#);
        assert_eq!(
            good.map(|r| (r.level, r.metric)),
            Ok((AlertLevel::Alarm, Metric::VelocityMmPerDay))
        );
    }

    /// The schema's bounds of the four thresholds are ±[`MAX_THRESHOLD`], the bound `validate`
    /// checks (with the feature `openapi`, which derives the schema).
    #[cfg(feature = "openapi")]
    #[test]
    fn the_schema_shows_the_threshold_bound() {
        use utoipa::PartialSchema;
        let schema = serde_json::to_value(AlertRule::schema()).unwrap();
        for member in ["above", "below", "clear_below", "clear_above"] {
            let p = &schema["properties"][member];
            assert_eq!(p["minimum"].as_f64(), Some(-MAX_THRESHOLD), "{member}: {p}");
            assert_eq!(p["maximum"].as_f64(), Some(MAX_THRESHOLD), "{member}: {p}");
        }
        let rule = AlertRule {
            above: Some(2.0 * MAX_THRESHOLD),
            ..serde_json::from_str(r#"{"level": "watch", "metric": "displacement_mm", "above": 1}"#)
                .unwrap()
        };
        let e = rule.validate().unwrap_err().to_string();
        assert!(e.ends_with("must lie within ±1e9"), "{e}");
    }
}
