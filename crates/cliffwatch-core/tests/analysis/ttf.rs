//! The time-to-failure alarm on realistic kinematics ([`cliffwatch_sim::kinematics`]):
//! the goals of `docs/accuracy.md`'s time-to-failure benchmark on a few seeds per kind, and steady
//! creep that scatters far beyond its σ.

use cliffwatch_core::analysis::failure::{upper_bound_hours, BOUND_CONFIDENCE};
use cliffwatch_core::analysis::tracking::{track, Observed};
use cliffwatch_core::analysis::{analyse_series, AlertConfig, AlertKind, AnalysisConfig};
use cliffwatch_sim::kinematics::{case, case_with_scatter, MotionKind, EPOCHS, HOURLY_DAYS};
use cliffwatch_sim::ttf_benchmark::{
    config, not_earlier_than_baseline, oracle_in_window, rules, run_all, score, series_table,
    table, ALARM_BELOW_HOURS,
};
use cliffwatch_sim::ttf_bound::{oracle_alarm_lead_hours, sigma_along_mm};
use nalgebra::{Matrix3, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

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

/// The first epoch (every 6 h from 10 days before the end) at which the block's forecast, the
/// hourly block of `kind` and `seed` tracked alone (its mean along its direction with the
/// measurement and the motion's scatter), has its upper bound below the rule's 96 h: hours
/// before the series' last epoch, with the forecast and its σ (h).
fn hourly_block_alarm(
    kind: MotionKind,
    seed: u64,
    config: &AnalysisConfig,
) -> Option<(f64, f64, f64)> {
    let c = case(kind, seed);
    let path = c.scenario.path.as_ref().expect("path");
    let u = Vector3::from(c.direction);
    let meas = sigma_along_mm(&c) / (1.0 + c.scatter * c.scatter).sqrt();
    let var = meas * meas;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let d: Vec<f64> = path
        .block_mm
        .iter()
        .map(|d| {
            let z: f64 = StandardNormal.sample(&mut rng);
            d + meas * z
        })
        .collect();
    let n = c.scenario.epochs;
    (n - 1 - 10 * 24..n).step_by(6).find_map(|end| {
        let now = end as f64 / 24.0;
        let series: Vec<Observed> = (0..=end)
            .map(|e| Observed {
                t_days: e as f64 / 24.0 - now,
                d_mm: u * d[e],
                cov_mm2: Matrix3::identity() * var,
            })
            .collect();
        let f = track(&series, Some(u), None, None, -now, config)?.failure?;
        let upper = upper_bound_hours(f.time_to_failure_hours, f.sigma_hours, BOUND_CONFIDENCE)?;
        (upper < ALARM_BELOW_HOURS)
            .then(|| ((n - 1 - end) as f64, f.time_to_failure_hours, f.sigma_hours))
    })
}

/// A block failing, or bursting, sampled hourly over 30 days (`MotionKind::FailingHourly`,
/// `BurstHourly`), its forecast alone (without the days of shared error), seeds 0–3 of each.
/// Every epoch on its own (`FailureConfig::forecast_bin_hours` 0, the default before) no
/// forecast ever forms: the windows and the filter's history count epochs (40 hours), and the
/// onset law asks the acceleration to have started 5 days back. At the defaults the hourly
/// epochs are fitted as daily means over the last 40 days, as `docs/accuracy.md` measures the
/// whole analysis: the failing blocks alarm 24–120 h before failure and the bursts do not.
/// Measured (2026-12-07): 4 of 4 in 24–120 h (85, 84, 25 and 31 h before failure), no burst
/// alarmed; asserted: ≥ 3 of 4 in the window (seed 2 lies an hour inside it), none more than
/// 8 days early, no burst. The defaults read the same as 1 000 epochs of history would.
#[test]
fn hourly_blocks_alarm_from_daily_means() {
    let mut unbinned = AnalysisConfig::default();
    unbinned.failure.forecast_bin_hours = 0.0;
    let hourly = AnalysisConfig::default();
    let longer = AnalysisConfig {
        filter_epochs: 1000,
        ..AnalysisConfig::default()
    };
    let mut in_window = 0;
    for seed in 0..4 {
        let tf = case(MotionKind::FailingHourly, seed)
            .failure_days
            .expect("fails");
        let last = (24.0 * HOURLY_DAYS).round() / 24.0;
        let to_failure = 24.0 * (tf - last);
        assert!(hourly_block_alarm(MotionKind::FailingHourly, seed, &unbinned).is_none());
        let alarm = hourly_block_alarm(MotionKind::FailingHourly, seed, &hourly);
        let with_longer = hourly_block_alarm(MotionKind::FailingHourly, seed, &longer);
        assert_eq!(
            alarm, with_longer,
            "seed {seed}: 40 daily bins hold the 30 days"
        );
        let lead = alarm.map(|a| a.0 + to_failure);
        println!("failing seed {seed}: {alarm:?}, {lead:?} h before failure");
        assert!(
            lead.is_none_or(|h| h <= 192.0),
            "seed {seed}: {lead:?} h early"
        );
        in_window += usize::from(lead.is_some_and(|h| (24.0..=120.0).contains(&h)));
        let burst = hourly_block_alarm(MotionKind::BurstHourly, seed, &hourly);
        assert!(burst.is_none(), "burst seed {seed}: {burst:?}");
    }
    assert!(in_window >= 3, "{in_window} of 4 in 24–120 h");
}
