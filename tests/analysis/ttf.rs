//! The time-to-failure alarm on realistic kinematics ([`cliffwatch::simulate::kinematics`]):
//! the goals of `docs/accuracy.md`'s time-to-failure benchmark on a few seeds per kind, and steady
//! creep that scatters far beyond its σ.

use cliffwatch::analysis::{analyse_series, AlertConfig, AlertKind};
use cliffwatch::simulate::kinematics::{case_with_scatter, MotionKind, EPOCHS};
use cliffwatch::simulate::ttf_benchmark::{
    config, not_earlier_than_baseline, rules, run_all, score, table,
};

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
/// series that never fails (burst, step, cyclic, creep), and no first alarm earlier than the
/// plain inverse-velocity baseline's. Goals not met yet, asserted at today's level so that they
/// cannot slip (measured on these seeds: 2 of 6 failing series alarmed 24–120 h before failure,
/// goal 80 %; the truth within ±2σ at 4 of 5 alarms, goal 90 %): at least 2 of 6 in the window,
/// at least 5 of 6 alarmed, and at most one alarm whose ±2σ misses the truth.
#[test]
fn the_time_to_failure_benchmark_on_a_few_seeds_per_kind() {
    let outcomes = run_all(0, 6);
    println!("{}", table(&outcomes));
    let ours = score(&outcomes, |o| o.alarm, true);
    for (kind, with, of) in &ours.false_by_kind {
        assert_eq!(*with, 0, "{}: {with} of {of} series alarmed", kind.name());
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
}
