//! The time-to-failure benchmark with the block **not declared**: the series of
//! [`super::ttf_benchmark`] analysed with no group and no direction of interest, as a site that
//! does not know its block in advance has it. Whether the block's targets still reach the alarm
//! is scored by the targets whose time-to-failure alarm is open in the last
//! [`LATE_EPOCHS`] epochs before the failure (issue 75's goal: at least 3 of the block's 6).
//!
//! `TTF_UNDECLARED=1 cargo run --release -p cliffwatch-sim --example ttf_benchmark [-- SEEDS]` prints its table.

use std::collections::{BTreeMap, BTreeSet};

use super::kinematics::{MotionCase, MotionKind};
use super::ttf_benchmark::GROUP;
use cliffwatch_core::analysis::{
    analyse_series, AlertConfig, AlertEventType, AlertKind, AlertLevel, AlertRule, AnalysisConfig,
    FailureConfig, PointConfig,
};

/// Epochs before the failure (the series' last ones) over which the block's targets are counted.
pub const LATE_EPOCHS: usize = 5;
/// Targets of the block that must alarm in the late epochs (of its 6).
pub const TARGETS_GOAL: usize = 3;

/// What one series gave with its block undeclared.
#[derive(Debug, Clone, PartialEq)]
pub struct UndeclaredOutcome {
    /// The series' kind.
    pub kind: MotionKind,
    /// Its seed.
    pub seed: u64,
    /// Its scatter (× the block's σ along its direction).
    pub scatter: f64,
    /// Targets of the block.
    pub block_targets: usize,
    /// Block targets whose time-to-failure alarm was open at one of the last [`LATE_EPOCHS`]
    /// epochs.
    pub alarmed_late: BTreeSet<String>,
    /// Hours before the failure of the first time-to-failure alarm on a block target (failing
    /// series; negative: after it).
    pub first_alarm_lead_hours: Option<f64>,
    /// Subjects with a time-to-failure alarm that never fail (every subject of a never-failing
    /// series; still and stable targets of a failing one).
    pub false_subjects: BTreeSet<String>,
}

/// The points of `points` with the block's group and direction removed.
fn undeclared(points: &[PointConfig]) -> Vec<PointConfig> {
    points
        .iter()
        .map(|p| {
            if p.group.as_deref() == Some(GROUP) {
                PointConfig {
                    group: None,
                    direction: None,
                    ..p.clone()
                }
            } else {
                p.clone()
            }
        })
        .collect()
}

/// Runs one series with its block undeclared, the time-to-failure settings `failure` and the
/// rules `rules`.
pub fn run_undeclared(
    c: &MotionCase,
    failure: &FailureConfig,
    rules: &[AlertRule],
) -> UndeclaredOutcome {
    run_undeclared_scaled(c, failure, rules, 1.0)
}

/// [`run_undeclared`] with each target's measurement σ scaled by `target_sigma` (the block's
/// shared motion and scatter unchanged): targets measured less well than the benchmark's.
pub fn run_undeclared_scaled(
    c: &MotionCase,
    failure: &FailureConfig,
    rules: &[AlertRule],
    target_sigma: f64,
) -> UndeclaredOutcome {
    let mut scenario = c.scenario.clone();
    scenario.sigma_mm *= target_sigma;
    let series = scenario.generate();
    let epochs: Vec<_> = series
        .epochs
        .iter()
        .map(|e| e.coordinates.clone())
        .collect();
    let points = undeclared(&series.points);
    let config = AnalysisConfig {
        failure: failure.clone(),
        ..AnalysisConfig::default()
    };
    let alerts = AlertConfig::new("ttf-undeclared", rules.to_vec());
    let out = analyse_series(&epochs[0], &epochs[1..], &points, &config, &alerts);
    let on_block = |who: &str| who.starts_with('B');
    let late_from = epochs
        .len()
        .checked_sub(LATE_EPOCHS)
        .map_or(i64::MIN, |k| epochs[k].epoch);
    let days_of = |epoch: i64| {
        epochs
            .iter()
            .find(|e| e.epoch == epoch)
            .map(|e| (e.observed_at - series.start).num_milliseconds() as f64 / 86_400_000.0)
    };
    // Open time-to-failure alarms by subject, epoch by epoch.
    let mut by_epoch: BTreeMap<i64, Vec<(String, bool)>> = BTreeMap::new();
    let mut first: Option<i64> = None;
    let mut false_subjects = BTreeSet::new();
    for (epoch, ev) in &out.events {
        let a = &ev.alert;
        if a.rule != AlertKind::TimeToFailureHours {
            continue;
        }
        let Some(who) = a.point.clone().or_else(|| a.group.clone()) else {
            continue;
        };
        let opens = matches!(
            ev.event_type,
            AlertEventType::Raised | AlertEventType::Escalated
        ) && a.level == AlertLevel::Alarm;
        let closes = ev.event_type == AlertEventType::Resolved
            || (ev.event_type == AlertEventType::Deescalated && a.level != AlertLevel::Alarm);
        if opens {
            if !c.kind.fails() || !on_block(&who) {
                false_subjects.insert(who.clone());
            } else if first.is_none_or(|f| *epoch < f) {
                first = Some(*epoch);
            }
        }
        if opens || closes {
            by_epoch.entry(*epoch).or_default().push((who, opens));
        }
    }
    let mut open: BTreeSet<String> = BTreeSet::new();
    let mut alarmed_late = BTreeSet::new();
    for e in &epochs {
        for (who, opens) in by_epoch.get(&e.epoch).into_iter().flatten() {
            if *opens {
                open.insert(who.clone());
            } else {
                open.remove(who);
            }
        }
        if e.epoch >= late_from {
            alarmed_late.extend(open.iter().filter(|w| on_block(w)).cloned());
        }
    }
    UndeclaredOutcome {
        kind: c.kind,
        seed: c.seed,
        scatter: c.scatter,
        block_targets: series.points.iter().filter(|p| on_block(&p.name)).count(),
        alarmed_late,
        first_alarm_lead_hours: first
            .and_then(days_of)
            .zip(c.failure_days)
            .map(|(at, tf)| (tf - at) * 24.0),
        false_subjects,
    }
}

/// Runs `seeds` series of each of `kinds` (from `first`) with the block undeclared and each
/// target's σ scaled by `target_sigma`, in parallel.
pub fn run_undeclared_kinds(
    first: u64,
    seeds: u64,
    kinds: &[MotionKind],
    failure: &FailureConfig,
    rules: &[AlertRule],
    target_sigma: f64,
) -> Vec<UndeclaredOutcome> {
    use rayon::prelude::*;
    let cases: Vec<MotionCase> = kinds
        .iter()
        .flat_map(|&k| (first..first + seeds).map(move |s| super::kinematics::case(k, s)))
        .collect();
    cases
        .par_iter()
        .map(|c| run_undeclared_scaled(c, failure, rules, target_sigma))
        .collect()
}

/// The table of `docs/accuracy.md`: failing series with at least [`TARGETS_GOAL`] block
/// targets alarmed late, first alarms, and never-failing series with an alarm, per kind.
pub fn undeclared_table(outcomes: &[UndeclaredOutcome]) -> String {
    let mut s = String::from(
        "| kind | series | ≥ 3 block targets alarmed in the last 5 epochs | block targets alarmed late: median | first alarm on a block target, h before failure: median (earliest) | series with an alarm off the block |\n|---|---|---|---|---|---|\n",
    );
    for kind in MotionKind::ALL {
        let of: Vec<&UndeclaredOutcome> = outcomes.iter().filter(|o| o.kind == kind).collect();
        if of.is_empty() {
            continue;
        }
        let goal = of
            .iter()
            .filter(|o| o.alarmed_late.len() >= TARGETS_GOAL)
            .count();
        let mut late: Vec<usize> = of.iter().map(|o| o.alarmed_late.len()).collect();
        late.sort_unstable();
        let mut leads: Vec<f64> = of.iter().filter_map(|o| o.first_alarm_lead_hours).collect();
        leads.sort_by(|a, b| a.total_cmp(b));
        let lead = if leads.is_empty() {
            "—".to_string()
        } else {
            format!(
                "{:.0} ({:.0})",
                leads[leads.len() / 2],
                leads[leads.len() - 1]
            )
        };
        let falses = of.iter().filter(|o| !o.false_subjects.is_empty()).count();
        let (goal, lead) = if kind.fails() {
            (format!("{goal}/{}", of.len()), lead)
        } else {
            ("—".into(), "—".into())
        };
        s.push_str(&format!(
            "| {} | {} | {goal} | {} | {lead} | {falses}/{} |\n",
            kind.name(),
            of.len(),
            late[late.len() / 2],
            of.len()
        ));
    }
    s
}
