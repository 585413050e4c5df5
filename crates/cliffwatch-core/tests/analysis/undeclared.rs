//! A failing block that nobody declared: image series of the long-range cliff
//! ([`cliffwatch_sim::series`]: cameras set up again each epoch, c drifting, 0.25 px image
//! noise) whose 6-target block accelerates to failure, adjusted epoch by epoch as the service
//! adjusts them and analysed with no group and no direction of interest. The block's targets
//! must reach the time-to-failure alarm before the failure with their forecasts pooled
//! (`analysis::pooling`), and no still target may. The same on the time-to-failure
//! benchmark's series ([`cliffwatch_sim::ttf_undeclared`]) with targets measured less well.

use std::collections::BTreeSet;

use cliffwatch_core::analysis::{
    analyse_series, AlertConfig, AlertEventType, AlertKind, AlertLevel, AnalysisConfig,
    EpochCoordinates, FailureConfig, PointRole,
};
use cliffwatch_core::photogrammetry::{adjust, AdjustOptions};
use cliffwatch_sim::kinematics::MotionKind;
use cliffwatch_sim::series::{image_series, ImageSeriesScenario};
use cliffwatch_sim::ttf_benchmark::rules;
use cliffwatch_sim::ttf_undeclared::{run_undeclared_kinds, TARGETS_GOAL};

/// Targets on the block.
const BLOCK_TARGETS: usize = 6;
/// Epochs before the failure over which the block's alarmed targets are counted.
const LATE_EPOCHS: usize = 5;

/// What one series gave: block targets whose time-to-failure alarm was open in the last
/// [`LATE_EPOCHS`] epochs, and the other targets that alarmed at all.
fn undeclared_series(seed: u64, pool_radius_m: f64) -> (BTreeSet<String>, BTreeSet<String>) {
    let sc = ImageSeriesScenario {
        seed,
        block_points: BLOCK_TARGETS,
        ..ImageSeriesScenario::default()
    };
    let series = image_series(&sc).expect("series");
    let points = series.truth.point_configs(None, None);
    let block: BTreeSet<String> = series
        .truth
        .points
        .iter()
        .filter(|p| p.group.is_some())
        .map(|p| p.name.clone())
        .collect();
    assert_eq!(block.len(), BLOCK_TARGETS);
    let mut options = AdjustOptions {
        joint_covariance_of: points
            .iter()
            .filter(|p| p.role == PointRole::Stable)
            .map(|p| p.name.clone())
            .collect(),
        ..AdjustOptions::default()
    };
    let mut epochs = vec![];
    for (k, epoch) in series.epochs.iter().enumerate() {
        let adj = adjust(epoch, &options).expect("adjustment");
        options.prior = adj.points.iter().map(|p| (p.name.clone(), p.xyz)).collect();
        let at = series.truth.epochs[k].observed_at;
        epochs.push(EpochCoordinates::from_adjustment(k as i64 + 1, at, &adj));
    }
    let config = AnalysisConfig {
        failure: FailureConfig {
            pool_radius_m,
            ..FailureConfig::default()
        },
        ..AnalysisConfig::default()
    };
    let alerts = AlertConfig::new("undeclared", rules());
    let out = analyse_series(&epochs[0], &epochs[1..], &points, &config, &alerts);
    assert!(out.failures.is_empty(), "{:?}", out.failures);
    let late_from = epochs[epochs.len() - LATE_EPOCHS].epoch;
    let mut open = BTreeSet::new();
    let mut late = BTreeSet::new();
    let mut others = BTreeSet::new();
    let mut events = out.events.iter().peekable();
    for e in &epochs[1..] {
        while let Some((_, ev)) = events.next_if(|(at, _)| *at == e.epoch) {
            let a = &ev.alert;
            let Some(p) = a.point.clone() else { continue };
            if a.rule != AlertKind::TimeToFailureHours {
                continue;
            }
            let alarm = a.level == AlertLevel::Alarm;
            match ev.event_type {
                AlertEventType::Raised | AlertEventType::Escalated if alarm => {
                    if !block.contains(&p) {
                        others.insert(p.clone());
                    }
                    open.insert(p);
                }
                AlertEventType::Resolved | AlertEventType::Deescalated => {
                    open.remove(&p);
                }
                _ => {}
            }
        }
        if e.epoch >= late_from {
            late.extend(open.iter().filter(|p| block.contains(*p)).cloned());
        }
    }
    (late, others)
}

/// Seeds 1–3 of the 40-epoch series (failure 12 h after the last epoch), the rule "alarm when
/// time to failure < 96 h", the default settings: at least 3 of the 6 block targets are at
/// alarm in the last 5 epochs in every series (issue 75's goal: 80 %), and no other target
/// alarms. (Measured 2026-12-07 on seeds 1–4: all 6 targets, with the forecasts pooled or not.)
#[test]
fn an_undeclared_failing_block_reaches_the_alarm_on_most_of_its_targets() {
    let mut reached = 0;
    let seeds = 1..=3u64;
    for seed in seeds.clone() {
        let (late, others) = undeclared_series(seed, FailureConfig::default().pool_radius_m);
        println!(
            "seed {seed}: {} of {BLOCK_TARGETS} at alarm late ({late:?}), off the block {others:?}",
            late.len(),
        );
        assert!(others.is_empty(), "seed {seed}: {others:?} alarmed");
        reached += usize::from(late.len() >= 3);
    }
    assert_eq!(reached, seeds.count(), "series with ≥ 3 targets at alarm");
}

/// The benchmark's failing series (seeds 0–5) with the block undeclared and every target
/// measured 3 × less well than the benchmark's (lateral σ 1.5 mm, depth 3 mm): a target's own
/// forecast is then often too uncertain to alarm, the pool's is not. Pooling never loses a
/// target, and it brings at least 3 of the 6 to the alarm in the last 5 epochs in at least 4 of
/// the 6 series (measured 2026-12-07: 4 with pooling, 16 → 24 targets; 3 without), with no alarm
/// off the block.
#[test]
fn pooling_brings_targets_measured_less_well_to_the_alarm() {
    let rules = rules();
    let pooled = FailureConfig::default();
    let own = FailureConfig {
        pool_radius_m: 0.0,
        ..FailureConfig::default()
    };
    let failing = [MotionKind::Failing];
    let with_pool = run_undeclared_kinds(0, 6, &failing, &pooled, &rules, 3.0);
    let without = run_undeclared_kinds(0, 6, &failing, &own, &rules, 3.0);
    let mut reached = 0;
    for (with, without) in with_pool.iter().zip(&without) {
        let seed = with.seed;
        assert_eq!(seed, without.seed);
        println!(
            "seed {seed}: pooled {:?}, own {:?}",
            with.alarmed_late, without.alarmed_late
        );
        assert!(
            with.alarmed_late.is_superset(&without.alarmed_late),
            "seed {seed}: pooled {:?} lost some of {:?}",
            with.alarmed_late,
            without.alarmed_late
        );
        assert!(
            with.false_subjects.is_empty(),
            "seed {seed}: {:?}",
            with.false_subjects
        );
        reached += usize::from(with.alarmed_late.len() >= TARGETS_GOAL);
    }
    assert!(
        reached >= 4,
        "{reached} of 6 series with ≥ 3 targets at alarm"
    );
}
