//! `reference_unstable` and the reference epoch's own errors (issue 60): a stable point whose
//! reference coordinates erred is not reported moved; a stable point that moves still is.
//!
//! Every epoch's displacement of a point carries the reference epoch's error of that point, so a
//! point whose reference coordinates erred by a few σ is excluded by the congruence test far more
//! often than α, in runs. "Excluded in 2 of 3 epochs" alone then names it although it never
//! moved; counting only the exclusions in which it also changed from its own earlier epochs
//! (`DatumReport::moved`, where that error cancels) does not.

use crate::support;
use support::analysis as common;

use cliffwatch_core::analysis::{
    evaluate_alerts, AlertConfig, AlertEventType, AlertKind, AlertState, AnalysisConfig,
    EpochAnalysis,
};
use cliffwatch_sim::monitoring::{MonitoringScenario, MonitoringSeries};

/// Replays the `reference_unstable` rule over `analyses`: (epochs in which it was raised, stable
/// point-epochs it named). `old_rule` forgets `datum.moved`, which makes every exclusion count,
/// as the rule did before the change test.
fn replay(analyses: &[EpochAnalysis], old_rule: bool) -> (Vec<i64>, usize) {
    let cfg = AlertConfig::new("s", vec![]);
    let mut st = AlertState::default();
    let (mut raised, mut named) = (vec![], 0);
    for a in analyses {
        let mut a = a.clone();
        if old_rule {
            a.datum.moved = None;
        }
        let (next, events) = evaluate_alerts(&cfg, &st, &a, a.observed_at);
        st = next;
        raised.extend(
            events
                .iter()
                .filter(|e| {
                    e.alert.rule == AlertKind::ReferenceUnstable
                        && e.event_type == AlertEventType::Raised
                })
                .map(|_| a.epoch),
        );
        named += st
            .find(None, AlertKind::ReferenceUnstable)
            .map_or(0, |x| x.points.len());
    }
    (raised, named)
}

fn still(seed: u64, epochs: usize) -> MonitoringSeries {
    MonitoringScenario {
        seed,
        epochs,
        creep_mm_per_day: 0.0,
        acceleration_start_days: None,
        ..Default::default()
    }
    .generate()
}

fn analyses(series: &MonitoringSeries) -> Vec<EpochAnalysis> {
    common::run(
        series,
        &series.points,
        &AnalysisConfig::default(),
        &AlertConfig::new("s", vec![]),
    )
    .into_iter()
    .map(|s| s.analysis)
    .collect()
}

/// R3 never moves, but the reference epoch measured it 3.5 σ off along X (σ of the reference
/// epoch's coordinate; the point was measured as well as in every other epoch), as T101 of the
/// issue erred: over 20 seeds × 40 epochs the old rule (every exclusion counts) names it on at
/// least 3 seeds (the fault, reproduced: 4 when this was written), the rule with the change test
/// on none, and names no point in more than 1 of 1000 stable point-epochs.
#[test]
fn a_stable_point_whose_reference_coordinates_erred_is_not_reported_moved() {
    let (mut old_seeds, mut new_seeds, mut named, mut point_epochs) = (0, 0, 0, 0);
    for seed in 61..=80 {
        let mut series = still(seed, 41);
        let k = 2; // R3
        let p = &mut series.epochs[0].coordinates.points[k];
        p.xyz_m[0] += 3.5 * p.covariance_m2[0][0].sqrt();
        let a = analyses(&series);
        let excluded: Vec<i64> = a
            .iter()
            .filter(|x| x.datum.excluded.contains(&"R3".to_string()))
            .map(|x| x.epoch)
            .collect();
        let (old, _) = replay(&a, true);
        let (new, n) = replay(&a, false);
        println!(
            "seed {seed}: R3 excluded at epochs {excluded:?}; old rule raised at {old:?}, new at {new:?}"
        );
        old_seeds += usize::from(!old.is_empty());
        new_seeds += usize::from(!new.is_empty());
        named += n;
        point_epochs += a
            .iter()
            .map(|x| x.datum.points.len() + x.datum.excluded.len())
            .sum::<usize>();
    }
    println!(
        "R3 off by 3.5 σ at the reference: old rule raised on {old_seeds}/20 seeds, new on {new_seeds}/20; named {named} of {point_epochs} stable point-epochs"
    );
    assert!(old_seeds >= 3, "the scenario no longer shows the fault");
    assert_eq!(new_seeds, 0);
    assert!(named * 1000 <= point_epochs, "{named} / {point_epochs}");
}

/// The power that must stay: R3 moved by 10 σ (σ of its displacement along X) after the
/// reference, either at once (from the first epoch after it: no earlier epoch to compare with)
/// or at the 6th epoch; `reference_unstable` names R3 on every one of 5 seeds, by the 3rd epoch
/// of the move.
#[test]
fn a_moved_stable_point_is_still_reported_moved() {
    for from in [1, 6] {
        for seed in 71..=75 {
            let base = MonitoringScenario {
                seed,
                epochs: 20,
                creep_mm_per_day: 0.0,
                acceleration_start_days: None,
                ..Default::default()
            };
            let s0 = base.generate();
            let k = 2;
            let c0 = &s0.epochs[0].coordinates.points[k].covariance_m2;
            let c1 = &s0.epochs[1].coordinates.points[k].covariance_m2;
            let sigma_x_mm = ((c0[0][0] + c1[0][0]) * 1e6).sqrt();
            let series = MonitoringScenario {
                moved_stable: Some((k, from, [10.0 * sigma_x_mm, 0.0, 0.0])),
                ..base
            }
            .generate();
            let a = analyses(&series);
            let (raised, _) = replay(&a, false);
            let moved_at = series.epochs[from].coordinates.epoch;
            println!("moved at epoch {moved_at}, seed {seed}: raised at {raised:?}");
            let first = *raised.first().unwrap_or(&i64::MAX);
            assert!(
                (moved_at..=moved_at + 2).contains(&first),
                "seed {seed}, moved at {moved_at}: raised at {raised:?}"
            );
        }
    }
}
