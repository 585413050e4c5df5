//! Alert rules and the per-point alert state machine.
//!
//! Rules (contract JSON `{"level": "watch", "metric": "displacement_mm", "above": 5.0, "clear_below": 4.0}`)
//! apply per site and optionally per point group. For every point and metric there is at most one open
//! alert; its level is the highest level whose rule is active, so it is raised, escalates, de-escalates and
//! resolves as the rules switch. A rule becomes active when its threshold is crossed by a significant value
//! (significance required by default); an active rule clears (hysteresis) only when the value, significant
//! or not, falls below `clear_below` (above `clear_above` for `below` rules; a velocity rule without one
//! clears at [`VELOCITY_CLEAR_FRACTION`] of its threshold) or, without such a threshold
//! or without a value, after `quiet_epochs` consecutive epochs without triggering. Site-level alerts: `reference_unstable` (the
//! congruence test excluded a stable point, which also changed from its own earlier epochs, in 2 of 3 epochs; it clears after the point has been kept
//! in the datum for `reference_quiet_epochs` epochs) and `campaign_overdue` (no epoch within the schedule).
//! Everything here is pure: the state goes in, the new state and the events come out.
//!
//! One file per concept: `alert` (an alert, its level, status, events and the site's state),
//! `metric` (what a rule thresholds), `readings` (the values a subject offers the rules),
//! `rule` (a rule and a site's configuration), `transition` (how one subject's alert is raised,
//! escalated or resolved), `evaluate` (an epoch's analysis through the rules), [`reconcile`]
//! (a recomputed series against the stored state), `overdue` (the campaign schedule) and
//! `by_hand` (acknowledgement and resolution by a person).

pub(crate) mod alert;
pub(crate) mod by_hand;
pub(crate) mod evaluate;
pub(crate) mod metric;
pub(crate) mod overdue;
pub(crate) mod readings;
pub(crate) mod reconcile;
pub(crate) mod rule;
mod transition;

pub use alert::{
    Alert, AlertEvent, AlertEventType, AlertLevel, AlertState, AlertStatus, ClearedHow,
    ClearingTest, RuleMemory,
};
pub use by_hand::{acknowledge, may_acknowledge, resolve};
pub use evaluate::{analysis_failed, evaluate_alerts};
pub use metric::{AlertKind, Metric, Source};
pub use overdue::{campaign_arrived, check_overdue};
pub use readings::{Reading, Readings};
pub use reconcile::{reconcile, REFERENCE_INDEPENDENT};
pub use rule::{
    AlertConfig, AlertRule, RuleRefused, FORECAST_CONFIDENCE, MAX_CONFIDENCE, MAX_EPOCHS,
    MIN_CONFIDENCE, RULE_MEMBERS, VELOCITY_CLEAR_FRACTION,
};
