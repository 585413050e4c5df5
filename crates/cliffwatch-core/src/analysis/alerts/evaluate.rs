//! An epoch's analysis through the site's rules: every point's and block's alerts, the
//! reference's stability, and the site-level alerts an epoch resolves.

use chrono::{DateTime, Utc};

use super::alert::{AlertEvent, AlertState, RuleMemory};
use super::alert::{ClearedHow, ClearingTest};
use super::metric::{AlertKind, Metric};
use super::readings::Reading;
use super::readings::Readings;
use super::rule::{AlertConfig, AlertRule};
use super::transition::{apply, fmt_time, Subject, Update};
use crate::analysis::datum::DatumMethod;
use crate::analysis::epoch_analysis::EpochAnalysis;

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
        // The highest rule of the metric that stopped being active this epoch, and its test.
        let mut cleared: Option<ClearingTest> = None;
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
                if mem.streak >= r.epochs_needed(&s.readings, m, z) {
                    mem.active = true;
                }
                mem.quiet_epochs = 0;
            } else {
                mem.streak = 0;
                if mem.active {
                    // With a clear threshold the value decides, significant or not (the
                    // hysteresis): past it the rule clears, short of it the rule stays active;
                    // a value that is not significant does not clear an alarm on a block that
                    // may still be moving. Without a clear threshold, or without a value, the
                    // epoch counts as quiet.
                    let confidence = r.confidence(config.confidence);
                    let test = match reading.value.and_then(|v| r.clears(v)) {
                        Some(true) => Some(clearing_test(r, &reading, confidence, z, true, 0)),
                        Some(false) => None,
                        None => {
                            mem.quiet_epochs += 1;
                            (mem.quiet_epochs
                                >= r.quiet_epochs.unwrap_or(config.quiet_epochs).max(1))
                            .then(|| {
                                clearing_test(r, &reading, confidence, z, false, mem.quiet_epochs)
                            })
                        }
                    };
                    if let Some(test) = test {
                        mem = RuleMemory::default();
                        if cleared.as_ref().is_none_or(|c| test.level > c.level) {
                            cleared = Some(test);
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
                cleared_by: cleared,
            },
            now,
            events,
        );
    }
}

/// The test of rule `r` (confidence `confidence`, quantile `z`) that cleared on `reading`
/// after `quiet_epochs` quiet epochs, past its clear threshold when `past_clear`.
fn clearing_test(
    r: &AlertRule,
    reading: &Reading,
    confidence: f64,
    z: f64,
    past_clear: bool,
    quiet_epochs: u32,
) -> ClearingTest {
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
        clear_threshold: r.clear_threshold(),
        confidence,
        z,
        significant: reading.significant,
        how,
        quiet_epochs: if past_clear { 0 } else { quiet_epochs },
    }
}

/// Evaluates the rules against one epoch's analysis: returns the new state and the events (in order).
///
/// Points absent from the analysis, and blocks without a motion, keep their state. An open `campaign_overdue` resolves (an epoch
/// arrived); `reference_unstable` names the stable points the congruence test excluded in 2 of
/// their last 3 tested epochs, until each has been kept in the datum for `reference_quiet_epochs`
/// epochs (see `reference_stability`). Invalid rules (see [`AlertRule::validate`]) never
/// trigger.
pub fn evaluate_alerts(
    config: &AlertConfig,
    state: &AlertState,
    analysis: &EpochAnalysis,
    now: DateTime<Utc>,
) -> (AlertState, Vec<AlertEvent>) {
    let mut st = state.clone();
    let mut events = vec![];
    let suffix = analysis.epoch.to_string();
    evaluate_rules(config, &mut st, analysis, &suffix, now, &mut events);
    reference_stability(config, &mut st, analysis, &suffix, now, &mut events);
    // This epoch was analysed: an earlier failure no longer stands; and an epoch arrived: the
    // campaign is no longer overdue.
    for kind in [AlertKind::AnalysisFailed, AlertKind::CampaignOverdue] {
        apply(
            &config.site,
            &mut st,
            Update::site(
                kind,
                None,
                Some(analysis.epoch),
                Some(analysis.observed_at),
                suffix.clone(),
            ),
            now,
            &mut events,
        );
    }
    (st, events)
}

/// The rules over every point and every declared block of the epoch. A rule naming a block group
/// applies to the block's motion, not to its single points; a rule without a group applies to
/// every point and every declared block.
fn evaluate_rules(
    config: &AlertConfig,
    st: &mut AlertState,
    analysis: &EpochAnalysis,
    suffix: &str,
    now: DateTime<Utc>,
    events: &mut Vec<AlertEvent>,
) {
    let rules: Vec<&AlertRule> = config
        .rules
        .iter()
        .filter(|r| r.validate().is_ok())
        .collect();
    let blocks: Vec<&str> = analysis.blocks.iter().map(|b| b.group.as_str()).collect();
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
            st,
            &subject,
            &applicable,
            analysis,
            suffix,
            now,
            events,
        );
    }
    // A block without a motion this epoch (too few members measured: fallen, or hidden by
    // dust) keeps its state, as an absent point does: its alarm must not resolve for want of
    // a reading.
    for b in analysis.blocks.iter().filter(|b| b.motion.is_some()) {
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
            st,
            &subject,
            &applicable,
            analysis,
            suffix,
            now,
            events,
        );
    }
}

/// Epochs, counting the current one, within which a stable point must be excluded twice before
/// `reference_unstable` names it: 2 of the last 3 epochs in which the point was tested. A single
/// exclusion is what the congruence test's α (1 %) produces by chance. Only exclusions that the
/// change test confirms count ([`DatumReport::moved`](crate::analysis::DatumReport::moved)): the
/// reference epoch's error of a point is common to every epoch, so its exclusions are not
/// independent and a point whose reference coordinates erred by 2–3 σ reached 2 of 3 although it
/// never moved (`docs/accuracy.md`, "Reference stability").
pub const REFERENCE_CONFIRM_EPOCHS: u32 = 3;

/// Key of a stable point's memory in [`AlertState::rules`] for `reference_unstable`.
fn reference_key(point: &str) -> String {
    format!(
        "{}{}:{point}",
        Subject::Site.memory_prefix(),
        AlertKind::ReferenceUnstable.as_str()
    )
}

/// The site-level `reference_unstable` alert: names the stable points the congruence test
/// excluded from the datum, with a change from their own earlier epochs (`datum.moved`), in 2 of
/// their last [`REFERENCE_CONFIRM_EPOCHS`] tested epochs (confirmed); an exclusion without that
/// change counts neither as an exclusion nor as an epoch kept. A confirmed point is cleared after `reference_quiet_epochs` consecutive epochs in
/// which it was tested and kept in the datum; an epoch that does not test it (the point not
/// measured, or an IWST datum) leaves it as it is. The alert is open while any point is confirmed;
/// its `points` and message name those points. Changing a point's role replays the series
/// without it as a stable point, so its alert resolves then.
///
/// A point's memory ([`RuleMemory`]): `quiet_epochs` counts its tested epochs since its last
/// exclusion; `active` says it is confirmed.
fn reference_stability(
    config: &AlertConfig,
    st: &mut AlertState,
    analysis: &EpochAnalysis,
    suffix: &str,
    now: DateTime<Utc>,
    events: &mut Vec<AlertEvent>,
) {
    let site = config.site.as_str();
    let datum = &analysis.datum;
    // Exclusions the change test did not confirm (the reference epoch's error of the point, not a
    // move) count neither way.
    for p in datum.moved.as_ref().unwrap_or(&datum.excluded) {
        let key = reference_key(p);
        let mem = match st.rules.get(&key) {
            Some(m) => RuleMemory {
                active: m.active || m.quiet_epochs + 2 <= REFERENCE_CONFIRM_EPOCHS,
                quiet_epochs: 0,
                streak: 0,
            },
            None => RuleMemory::default(),
        };
        st.rules.insert(key, mem);
    }
    if datum.method == DatumMethod::StablePoints {
        for p in &datum.points {
            let key = reference_key(p);
            let Some(mut mem) = st.rules.get(&key).copied() else {
                continue;
            };
            mem.quiet_epochs += 1;
            let expired = if mem.active {
                mem.quiet_epochs >= config.reference_quiet_epochs.max(1)
            } else {
                mem.quiet_epochs + 1 >= REFERENCE_CONFIRM_EPOCHS
            };
            if expired {
                st.rules.remove(&key);
            } else {
                st.rules.insert(key, mem);
            }
        }
    }
    let prefix = reference_key("");
    let confirmed: Vec<String> = st
        .rules
        .iter()
        .filter(|(k, m)| m.active && k.starts_with(&prefix))
        .map(|(k, _)| k[prefix.len()..].to_string())
        .collect();
    let first = datum.congruence.first();
    let before = events.len();
    apply(
        site,
        st,
        Update {
            points: confirmed.clone(),
            level: (!confirmed.is_empty()).then_some(config.reference_unstable_level),
            value: first.map(|t| t.statistic),
            threshold: first.map(|t| t.critical),
            ..Update::site(
                AlertKind::ReferenceUnstable,
                None,
                Some(analysis.epoch),
                Some(analysis.observed_at),
                suffix.to_string(),
            )
        },
        now,
        events,
    );
    if confirmed.is_empty() {
        return;
    }
    // The alert names the points confirmed now (a cleared point leaves it).
    if let Some(a) = st
        .alerts
        .iter_mut()
        .find(|a| a.rule == AlertKind::ReferenceUnstable && a.point.is_none())
    {
        a.points = confirmed;
        a.message = format!(
            "site {site}: stable point(s) {} moved; excluded from the datum",
            a.points.join(", ")
        );
        for e in events[before..].iter_mut().filter(|e| e.alert.id == a.id) {
            e.alert.points = a.points.clone();
            e.alert.message = a.message.clone();
        }
    }
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
        Update::site(
            AlertKind::AnalysisFailed,
            Some(config.analysis_failed_level),
            Some(epoch),
            Some(observed_at),
            epoch.to_string(),
        ),
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
    let (st, arrived) = super::overdue::campaign_arrived(config, &st, epoch, observed_at, now);
    events.extend(arrived);
    (st, events)
}
