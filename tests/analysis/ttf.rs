//! The time-to-failure alarm on realistic kinematics ([`cliffwatch::simulate::kinematics`]):
//! the goals of `docs/accuracy.md`'s time-to-failure benchmark on a few seeds per kind, and steady
//! creep that scatters far beyond its σ.

use cliffwatch::analysis::{analyse_series, AlertConfig, AlertKind};
use cliffwatch::simulate::kinematics::{case, case_with_scatter, MotionKind, EPOCHS};
use cliffwatch::simulate::ttf_benchmark::{
    config, not_earlier_than_baseline, reliable_possible, rules, run_all, score, table,
};
use cliffwatch::simulate::ttf_bound::first_reliable_in_window;

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

/// The benchmark on 6 seeds per kind (30 series; the full benchmark, 40 seeds per kind, in
/// `docs/accuracy.md`). Goals that hold, asserted as goals: no time-to-failure alarm on any
/// series that never fails (burst, step, cyclic, creep), none either had the rule read the
/// point estimate, and no first alarm earlier than the plain inverse-velocity baseline's. Goals
/// not met (see [`the_window_goal_is_out_of_reach_of_any_reliable_forecast`]), asserted at
/// today's level so that they cannot slip (measured on these seeds: 2 of 6 failing series
/// alarmed 24–120 h before failure, goal 80 %; the truth within ±2σ at 4 of 5 alarms, goal
/// 90 %): at least 2 of 6 in the window, at least 5 of 6 alarmed, at most one alarm whose ±2σ
/// misses the truth, and no more in the window than the bound allows plus one.
#[test]
fn the_time_to_failure_benchmark_on_a_few_seeds_per_kind() {
    let outcomes = run_all(0, 6);
    println!("{}", table(&outcomes));
    let ours = score(&outcomes, |o| o.alarm, |o| o.false_alarms > 0);
    for (kind, with, of) in &ours.false_by_kind {
        assert_eq!(*with, 0, "{}: {with} of {of} series alarmed", kind.name());
    }
    let point = score(
        &outcomes,
        |o| o.point_estimate.0,
        |o| o.point_estimate.1 > 0,
    );
    for (kind, with, of) in &point.false_by_kind {
        assert_eq!(*with, 0, "point estimate, {}: {with} of {of}", kind.name());
    }
    let (ok, n) = not_earlier_than_baseline(&outcomes);
    assert_eq!(ok, n, "{ok} of {n} no earlier than the baseline");
    assert_eq!(ours.failing, 6);
    assert!(ours.alarmed >= 5, "{} of 6 alarmed", ours.alarmed);
    assert!(ours.in_window >= 2, "{} of 6 in 24–120 h", ours.in_window);
    assert!(
        ours.covered + 1 >= ours.alarmed,
        "{} of {} covered",
        ours.covered,
        ours.alarmed
    );
    let (possible, _) = reliable_possible(&outcomes);
    assert!(
        ours.in_window <= possible + 1,
        "{} in the window, the bound allows {possible}",
        ours.in_window
    );
}

/// Why the window goal (first alarm 24–120 h before failure in ≥ 80 % of failing series) is not
/// met: a forecast is reliable only when its 90 % interval is no wider than its horizon, and even
/// a forecaster with every advantage (the true model and direction, the noise known, no burst,
/// no shared error: the Cramér–Rao bound of [`cliffwatch::simulate::ttf_bound`]) has one at some
/// epoch 24–120 h before failure in fewer than 80 % of the 40 failing series of the benchmark
/// (26 of seeds 0–39, 27 of seeds 40–79, measured). Bounds: fewer than 32 of 40 in each set,
/// and at least 16 (the bound is not vacuous: slowly scattering blocks do have one).
#[test]
fn the_window_goal_is_out_of_reach_of_any_reliable_forecast() {
    for first in [0, 40] {
        let possible = (first..first + 40)
            .filter(|&s| first_reliable_in_window(&case(MotionKind::Failing, s)).is_some())
            .count();
        println!("seeds {first}–{}: {possible} of 40", first + 39);
        assert!(
            (16..32).contains(&possible),
            "seeds {first}…: {possible} of 40"
        );
    }
}
