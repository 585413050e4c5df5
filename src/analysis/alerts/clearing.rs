//! The test that decided a de-escalation or a resolution: which rule stopped being active, the
//! value it read with its σ, its threshold, its confidence and how it cleared. It travels with
//! the event ([`super::AlertEvent::cleared_by`]) into the webhook body and the alert's history.

use serde::{Deserialize, Serialize};

use super::alert::AlertLevel;
use super::readings::Reading;
use super::rule::AlertRule;

/// How an active rule stopped being active.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, utoipa::ToSchema)]
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
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
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

impl ClearingTest {
    /// The test of rule `r` (confidence `confidence`, quantile `z`) that cleared on `reading`
    /// after `quiet_epochs` quiet epochs, past its clear threshold when `past_clear`.
    pub(super) fn of(
        r: &AlertRule,
        reading: &Reading,
        confidence: f64,
        z: f64,
        past_clear: bool,
        quiet_epochs: u32,
    ) -> Self {
        let how = if past_clear {
            ClearedHow::PastClearThreshold
        } else {
            match reading.value {
                None => ClearedHow::NoValue,
                Some(v)
                    if r.require_significant
                        && !reading.significant
                        && r.triggers(v, reading.sigma, z) =>
                {
                    ClearedHow::NotSignificant
                }
                Some(_) => ClearedHow::NotExceeded,
            }
        };
        ClearingTest {
            level: r.level,
            value: reading.value,
            sigma: reading.sigma,
            threshold: r.threshold(),
            below: r.below.is_some(),
            clear_threshold: r.clear_below.or(r.clear_above),
            confidence,
            z,
            significant: reading.significant,
            how,
            quiet_epochs: if past_clear { 0 } else { quiet_epochs },
        }
    }
}
