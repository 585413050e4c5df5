//! The time-to-failure alarm on realistic kinematics ([`cliffwatch_sim::kinematics`]):
//! the goals of `docs/accuracy.md`'s time-to-failure benchmark on a few seeds per kind, and steady
//! creep that scatters far beyond its σ.

use cliffwatch_core::analysis::{analyse_series, AlertConfig, AlertKind};
use cliffwatch_sim::kinematics::{case, case_with_scatter, MotionKind, EPOCHS};
use cliffwatch_sim::ttf_benchmark::{
    config, not_earlier_than_baseline, oracle_in_window, rules, run_all, score, series_table,
    table, ALARM_BELOW_HOURS,
};
use cliffwatch_sim::ttf_bound::oracle_alarm_lead_hours;

/// Steady creep (0.2–2 mm/day) whose motion scatters 8 × the block's σ along it, 90 daily
/// epochs, 6 seeds: no time-to-failure alert at any level on any subject.
#[test]
fn steady_creep_scattering_eight_sigma_raises_no_time_to_failure_alert() {
    for seed in 0..6 {
        let c = case_with_scatter(MotionKind::Creep, 100 + seed, Some(8.0));
        assert_eq!(c.scenario.epochs, EPOCHS);
        let series = c.scenario.generate();
        let epochs: Vec<_> = series
            .epochs
            .iter()
            .map(|e| e.coordinates.clone())
            .collect();
        let alerts = AlertConfig::new("creep", rules());
        let out = analyse_series(
            &epochs[0],
            &epochs[1..],
            &series.points,
            &config(&c),
            &alerts,
        );
        assert_eq!(out.analysed.len(), EPOCHS - 1);
        let ttf: Vec<_> = out
            .events
            .iter()
            .filter(|(_, e)| e.alert.rule == AlertKind::TimeToFailureHours)
            .collect();
        assert!(
            ttf.is_empty(),
            "seed {seed} ({:.2} mm/day): {} time-to-failure events, first {:?}",
            c.creep_mm_per_day,
            ttf.len(),
            ttf.first()
        );
    }
}

/// The benchmark on 6 seeds per kind (30 series; the larger runs in `docs/accuracy.md`).
/// Asserted as goals: no time-to-failure alarm on a creep, step or cyclic series (cycles since
/// the law must fit better than creep plus a cycle, `FailureConfig::cycle_margin`; 2 of 6
/// before), none earlier than the plain inverse-velocity baseline's, none more than 8 days
/// before failure. Asserted at today's level so that they cannot slip (measured on these seeds,
/// 2026-12-07): burst series alarmed 0 of 6 (goal ≤ 10 %); failing series alarmed 5 of 6; in
/// 24–120 h 4 of the 5 where the oracle is (goal 90 %); the truth within ±2σ at 3 of 5 first
/// alarms (goal 90 %: not met).
#[test]
fn the_time_to_failure_benchmark_on_a_few_seeds_per_kind() {
    let outcomes = run_all(0, 6);
    println!("{}", table(&outcomes));
    println!("{}", series_table(&outcomes));
    let ours = score(&outcomes, |o| o.alarm, |o| o.false_alarms > 0);
    for (kind, with, of) in &ours.false_by_kind {
        assert!(*with == 0, "{}: {with} of {of} series alarmed", kind.name());
    }
    let (ok, n) = not_earlier_than_baseline(&outcomes);
    assert_eq!(ok, n, "{ok} of {n} no earlier than the baseline");
    assert_eq!(ours.failing, 6);
    assert!(
        ours.lead_earliest <= 192.0,
        "an alarm {} h before failure",
        ours.lead_earliest
    );
    assert!(ours.alarmed >= 5, "{} of 6 alarmed", ours.alarmed);
    let oracle = oracle_in_window(&outcomes);
    assert!(
        oracle.both + 1 >= oracle.oracle,
        "{} of the oracle's {} in 24–120 h",
        oracle.both,
        oracle.oracle
    );
    assert!(
        ours.covered >= 3,
        "{} of {} covered",
        ours.covered,
        ours.alarmed
    );
}

/// The oracle alarms on the same rule as cliffwatch, on the upper bound of a forecaster with the
/// true model, direction and noise (its Cramér–Rao σ): never 96 h or more before failure, never
/// later with less noise (the same seed at 1 × and 8 × the block's σ), and in the window 24–120 h
/// before failure on 38 of the 40 failing series of each set (measured; bounds 16–39).
#[test]
fn the_oracle_alarms_on_the_upper_bound() {
    for first in [0, 40] {
        let leads: Vec<Option<f64>> = (first..first + 40)
            .map(|s| oracle_alarm_lead_hours(&case(MotionKind::Failing, s), ALARM_BELOW_HOURS))
            .collect();
        assert!(leads
            .iter()
            .flatten()
            .all(|&h| h > 0.0 && h < ALARM_BELOW_HOURS));
        let in_window = leads
            .iter()
            .filter(|h| h.is_some_and(|h| h >= 24.0))
            .count();
        println!("seeds {first}–{}: {in_window} of 40", first + 39);
        assert!(
            (16..40).contains(&in_window),
            "seeds {first}…: {in_window} of 40"
        );
    }
    for seed in 0..10 {
        let lead = |scatter: f64| {
            let c = case_with_scatter(MotionKind::Failing, seed, Some(scatter));
            oracle_alarm_lead_hours(&c, ALARM_BELOW_HOURS).unwrap_or(0.0)
        };
        assert!(
            lead(1.0) >= lead(8.0),
            "seed {seed}: {} vs {}",
            lead(1.0),
            lead(8.0)
        );
    }
}
