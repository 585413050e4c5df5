//! An epoch's analysis through the site's rules: every point's and block's alerts, the
//! reference's stability, and the site-level alerts an epoch resolves.

use chrono::{DateTime, Utc};

use super::alert::{AlertEvent, AlertState, RuleMemory};
use super::metric::{AlertKind, Metric};
use super::readings::Readings;
use super::rule::{AlertConfig, AlertRule};
use super::transition::{apply, fmt_time, Subject, Update};
use crate::analysis::analyse::EpochAnalysis;

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
                    // With a clear threshold the value decides, significant or not (the
                    // hysteresis): past it the rule clears, short of it the rule stays active;
                    // a value that is not significant does not clear an alarm on a block that
                    // may still be moving. Without a clear threshold, or without a value, the
                    // epoch counts as quiet.
                    match reading.value.and_then(|v| r.clears(v)) {
                        Some(true) => mem = RuleMemory::default(),
                        Some(false) => {}
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
/// Points absent from the analysis, and blocks without a motion, keep their state. An open `campaign_overdue` resolves (an epoch
/// arrived); `reference_unstable` is raised when the congruence test excludes stable points (its `points`
/// grow with later exclusions) and stays open until resolved by hand ([`super::resolve`]). Invalid rules (see [`AlertRule::validate`]) never
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

/// The site-level `reference_unstable` alert: raised when the congruence test excluded stable
/// points from the datum. It does not resolve by itself (a moved reference point does not move
/// back, and the test's power near its threshold would make it flap): staff resolve it by hand
/// once the point's role was changed.
fn reference_stability(
    config: &AlertConfig,
    st: &mut AlertState,
    analysis: &EpochAnalysis,
    suffix: &str,
    now: DateTime<Utc>,
    events: &mut Vec<AlertEvent>,
) {
    let site = config.site.as_str();
    let excluded = &analysis.datum.excluded;
    let first = analysis.datum.congruence.first();
    let open_unstable = st.find(None, AlertKind::ReferenceUnstable).map(|a| a.level);
    let before = events.len();
    apply(
        site,
        st,
        Update {
            points: excluded.clone(),
            level: if excluded.is_empty() {
                open_unstable
            } else {
                Some(config.reference_unstable_level)
            },
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
    // The message names every stable point excluded since the alert was raised (its `points`).
    if excluded.is_empty() {
        return;
    }
    if let Some(a) = st
        .alerts
        .iter_mut()
        .find(|a| a.rule == AlertKind::ReferenceUnstable && a.point.is_none())
    {
        a.message = format!(
            "site {site}: stable point(s) {} moved; excluded from the datum",
            a.points.join(", ")
        );
        for e in events[before..].iter_mut().filter(|e| e.alert.id == a.id) {
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
