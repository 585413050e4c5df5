//! The analysis on simulated monitoring series (`simulate::monitoring`): covariance consistency,
//! alert escalation, failure-time forecast, false alarms under noise, a moving stable point.

use crate::support;
use support::analysis as common;

use cliffwatch_core::analysis::stats::beta_inc;
use cliffwatch_core::analysis::{
    analyse_epoch, AlertConfig, AlertEventType, AlertKind, AlertLevel, AlertRule, AnalysisConfig,
    DatumMethod, History, Metric, PointRole,
};
use cliffwatch_sim::monitoring::MonitoringScenario;

fn rule(
    level: AlertLevel,
    metric: Metric,
    above: Option<f64>,
    below: Option<f64>,
    clear_below: Option<f64>,
) -> AlertRule {
    AlertRule {
        level,
        metric,
        above,
        below,
        clear_below,
        clear_above: None,
        group: None,
        source: None,
        for_epochs: None,
        require_significant: true,
        quiet_epochs: None,
        confidence: None,
    }
}

fn contract_rules() -> Vec<AlertRule> {
    vec![
        rule(
            AlertLevel::Watch,
            Metric::DisplacementMm,
            Some(5.0),
            None,
            Some(4.0),
        ),
        rule(
            AlertLevel::Warning,
            Metric::DisplacementMm,
            Some(10.0),
            None,
            None,
        ),
        rule(
            AlertLevel::Alarm,
            Metric::VelocityMmPerDay,
            Some(5.0),
            None,
            None,
        ),
        rule(
            AlertLevel::Alarm,
            Metric::TimeToFailureHours,
            None,
            Some(48.0),
            None,
        ),
    ]
}

/// eᵀΣ⁻¹e of the displacement errors follows χ²(3): ≥ 97 % below χ²(3; 0.99) = 11.34 on every seed.
#[test]
fn displacement_errors_are_consistent_with_their_covariances() {
    let crit = cliffwatch_core::analysis::stats::chi2_quantile(0.99, 3.0);
    let mut total = (0usize, 0usize);
    for seed in 1..=5 {
        let sc = MonitoringScenario {
            seed,
            ..Default::default()
        };
        let series = sc.generate();
        let steps = common::run(
            &series,
            &series.points,
            &AnalysisConfig::default(),
            &AlertConfig::new("s", vec![]),
        );
        let (mut below, mut n) = (0, 0);
        for (k, step) in steps.iter().enumerate() {
            let truth = &series.epochs[k + 1].true_displacement_mm;
            for (i, p) in step.analysis.points.iter().enumerate() {
                let r = &p.record;
                let t = truth[i];
                let e = [r.dx_mm - t[0], r.dy_mm - t[1], r.dz_mm - t[2]];
                let q = common::mahalanobis(e, p.covariance_mm2).expect("regular covariance");
                n += 1;
                if q < crit {
                    below += 1;
                }
            }
        }
        let share = below as f64 / n as f64;
        println!(
            "seed {seed}: {below}/{n} = {:.2} % of point-epochs below {crit:.2}",
            100.0 * share
        );
        assert!(
            share >= 0.97,
            "seed {seed}: only {:.2} % below",
            100.0 * share
        );
        total.0 += below;
        total.1 += n;
    }
    println!(
        "all seeds: {:.2} %",
        100.0 * total.0 as f64 / total.1 as f64
    );
}

/// Alerts of the block rise level by level near the epochs where the truth crosses the thresholds, and the
/// inverse-velocity forecast converges on the true failure time.
#[test]
fn alerts_escalate_and_failure_forecast_converges() {
    let mut errors = vec![];
    for seed in 1..=5 {
        let sc = MonitoringScenario {
            seed,
            ..Default::default()
        };
        let series = sc.generate();
        let alerts = AlertConfig::new("kamo", contract_rules());
        let steps = common::run(&series, &series.points, &AnalysisConfig::default(), &alerts);
        let dt = sc.interval_hours / 24.0;
        let first_true = |f: &dyn Fn(f64) -> bool| {
            (1..sc.epochs)
                .find(|&e| f(e as f64 * dt))
                .expect("crossing")
        };
        // A rule fires when the estimate exceeds its threshold at 99 % (d − z·σ > threshold), so
        // the truth is expected to cross threshold + z·σ(d) then.
        let z = alerts.z();
        let sigma_at = |t: f64| {
            let k = ((t / dt).round() as usize).min(steps.len()) - 1;
            steps[k]
                .analysis
                .point("B1")
                .map_or(0.0, |p| p.record.sigma_mm)
        };
        let e_watch = first_true(&|t| sc.block_displacement_mm(t) > 5.0 + z * sigma_at(t));
        let e_warn = first_true(&|t| sc.block_displacement_mm(t) > 10.0 + z * sigma_at(t));
        let e_alarm = first_true(&|t| sc.block_velocity(t) > 5.0);
        // Epoch index (0-based in the series) where B1's alert reached each level.
        let mut reached: Vec<(AlertLevel, usize)> = vec![];
        for (k, s) in steps.iter().enumerate() {
            for ev in &s.events {
                if ev.alert.point.as_deref() == Some("B1")
                    && matches!(
                        ev.event_type,
                        AlertEventType::Raised | AlertEventType::Escalated
                    )
                    && !reached.iter().any(|(l, _)| *l >= ev.alert.level)
                {
                    reached.push((ev.alert.level, k + 1));
                }
            }
        }
        println!("seed {seed}: truth crosses watch/warning/alarm at epochs {e_watch}/{e_warn}/{e_alarm}; B1 reached {reached:?}");
        let at = |l: AlertLevel| {
            reached
                .iter()
                .find(|(x, _)| *x == l)
                .map(|x| x.1)
                .expect("level reached")
        };
        // Exactly where either estimate (the default source of displacement rules) first
        // exceeds the threshold at the rules' confidence (d − z·σ > threshold, z = 2.326): the
        // Kalman filter's at once, the raw one alone when the epoch before also exceeded …
        let z = alerts.z();
        let exceeds = |k: usize, th: f64| {
            steps[k].analysis.point("B1").map_or((false, false), |p| {
                let raw = p.record.significant && p.record.d_mm - z * p.record.sigma_mm > th;
                let filtered = p
                    .record
                    .filtered
                    .is_some_and(|f| f.f_d_mm - z * f.sigma_f_d_mm > th);
                (raw, filtered)
            })
        };
        let est = |th: f64| {
            (0..steps.len())
                .position(|k| {
                    let (raw, filtered) = exceeds(k, th);
                    let before = k > 0 && exceeds(k - 1, th) != (false, false);
                    filtered || (raw && before)
                })
                .map(|k| k + 1)
        };
        assert_eq!(Some(at(AlertLevel::Watch)), est(5.0));
        assert_eq!(Some(at(AlertLevel::Warning)), est(10.0));
        // … and near the truth: σ(d) ≈ 1 mm against 0.25–0.5 mm of creep per epoch makes ±6 epochs (3 days)
        // about 2σ of the crossing time.
        assert!(at(AlertLevel::Watch).abs_diff(e_watch) <= 6);
        assert!(at(AlertLevel::Warning).abs_diff(e_warn) <= 6);
        assert!(at(AlertLevel::Alarm).abs_diff(e_alarm) <= 4);
        assert!(
            at(AlertLevel::Watch) < at(AlertLevel::Warning)
                && at(AlertLevel::Warning) < at(AlertLevel::Alarm)
        );
        // No stable or other point alerts.
        for s in &steps {
            for ev in &s.events {
                let p = ev.alert.point.as_deref().unwrap_or("");
                assert!(
                    p.starts_with('B'),
                    "unexpected alert {:?}",
                    ev.alert.message
                );
            }
        }
        // Forecast at 24 h before failure.
        let failure = series.failure_at.expect("failure");
        let mut last_err = None;
        for (k, s) in steps.iter().enumerate() {
            let p = s.analysis.point("B1").expect("B1");
            let hours_left = (failure - series.epochs[k + 1].coordinates.observed_at).num_minutes()
                as f64
                / 60.0;
            if let Some(ttf) = p.record.time_to_failure_hours {
                if [72.0, 48.0, 24.0, 12.0]
                    .iter()
                    .any(|h| (hours_left - h).abs() < 1e-6)
                {
                    println!(
                        "seed {seed}: {hours_left:.0} h before failure: forecast {ttf:.1} h ± {:.1} (error {:+.1} h, R² {:.3})",
                        p.failure.map_or(0.0, |f| f.sigma_hours),
                        ttf - hours_left,
                        p.failure.map_or(0.0, |f| f.r2)
                    );
                }
                if (hours_left - 24.0).abs() < 1e-6 {
                    last_err = Some(ttf - hours_left);
                }
            }
            // No forecast during the creep phase.
            let t_days = (k + 1) as f64 * dt;
            if t_days < sc.acceleration_start_days.unwrap_or(0.0) {
                assert!(
                    p.record.time_to_failure_hours.is_none(),
                    "forecast while creeping at day {t_days}"
                );
            }
        }
        let err = last_err.expect("forecast 24 h before failure");
        errors.push(err);
        assert!(
            err.abs() < 18.0,
            "forecast error {err} h at 24 h before failure"
        );
    }
    let rms = (errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt();
    println!(
        "forecast error 24 h before failure over {} seeds: {errors:.1?}, RMS {rms:.1} h",
        errors.len()
    );
}

/// Exact binomial interval [lo, hi] holding ≥ 99.9 % of the probability (0.05 % in each tail).
fn binomial_interval(n: usize, p: f64) -> (usize, usize) {
    // P(X ≤ k) = I_{1−p}(n − k, k + 1).
    let cdf = |k: usize| {
        if k >= n {
            1.0
        } else {
            beta_inc((n - k) as f64, (k + 1) as f64, 1.0 - p)
        }
    };
    let lo = (0..=n).find(|&k| cdf(k) > 0.0005).unwrap_or(0);
    let hi = (0..=n).find(|&k| cdf(k) >= 0.9995).unwrap_or(n);
    (lo, hi)
}

/// 200 epochs of noise only: no displacement alert with thresholds at 5σ; the share of point-epochs
/// flagged significant lies in the binomial 99.9 % interval around 1 − confidence.
#[test]
fn noise_only_gives_no_alerts_and_the_nominal_false_positive_rate() {
    let mut all = (0usize, 0usize);
    for seed in [11, 12, 13] {
        let sc = MonitoringScenario {
            seed,
            epochs: 201,
            creep_mm_per_day: 0.0,
            acceleration_start_days: None,
            ..Default::default()
        };
        let series = sc.generate();
        // 5σ with σ the largest standard deviation of any displacement (the depth direction).
        let probe = common::run(
            &MonitoringScenario {
                epochs: 2,
                ..sc.clone()
            }
            .generate(),
            &series.points,
            &AnalysisConfig::default(),
            &AlertConfig::new("s", vec![]),
        );
        let sigma_max = probe[0]
            .analysis
            .points
            .iter()
            .map(|p| {
                let m = nalgebra::Matrix3::from_fn(|r, c| p.covariance_mm2[r][c]);
                m.symmetric_eigenvalues().max().sqrt()
            })
            .fold(0.0, f64::max);
        let th = 5.0 * sigma_max;
        let rules = vec![
            rule(
                AlertLevel::Watch,
                Metric::DisplacementMm,
                Some(th),
                None,
                None,
            ),
            rule(
                AlertLevel::Warning,
                Metric::DisplacementMm,
                Some(2.0 * th),
                None,
                None,
            ),
        ];
        let steps = common::run(
            &series,
            &series.points,
            &AnalysisConfig::default(),
            &AlertConfig::new("s", rules),
        );
        let alerts: usize = steps
            .iter()
            .map(|s| s.events.iter().filter(|e| e.alert.point.is_some()).count())
            .sum();
        let (mut sig, mut n) = (0, 0);
        for s in &steps {
            for p in &s.analysis.points {
                n += 1;
                sig += usize::from(p.record.significant);
            }
        }
        let (lo, hi) = binomial_interval(n, 0.01);
        println!(
            "seed {seed}: threshold 5σ = {th:.2} mm, {alerts} displacement alerts; significant {sig}/{n} = {:.3} % (99.9 % interval {lo}..={hi}, {:.3}–{:.3} %)",
            100.0 * sig as f64 / n as f64,
            100.0 * lo as f64 / n as f64,
            100.0 * hi as f64 / n as f64
        );
        assert_eq!(alerts, 0);
        all.0 += sig;
        all.1 += n;
    }
    let (lo, hi) = binomial_interval(all.1, 0.01);
    println!(
        "all seeds: significant {}/{} (99.9 % interval {lo}..={hi})",
        all.0, all.1
    );
    assert!(all.0 >= lo && all.0 <= hi, "{} outside {lo}..={hi}", all.0);
}

/// One stable point moved by 5σ or 10σ: the congruence test finds it, it is excluded,
/// `reference_unstable` is raised naming it once it is excluded in 2 of 3 epochs, and stays open,
/// and the other displacements equal those of a datum without it. At 5σ the test's power is
/// about one half per epoch, less on a seed whose reference epoch erred against the move: the
/// alert may then stay silent (at most 2 of 5 seeds); at 10σ it is raised on every seed.
#[test]
fn a_moved_stable_point_is_found_excluded_and_reported() {
    for (n_sigma, min_rate, max_not_raised) in [(5.0, 0.3, 2), (10.0, 0.9, 0)] {
        moved_stable_point(n_sigma, min_rate, max_not_raised);
    }
}

/// [`a_moved_stable_point_is_found_excluded_and_reported`] for a move of `n_sigma` σ along X:
/// R3 excluded in at least `min_rate` of the epochs after the move, the alert missing on at most
/// `max_not_raised` of the seeds.
fn moved_stable_point(n_sigma: f64, min_rate: f64, max_not_raised: usize) {
    let mut found = (0usize, 0usize);
    let mut not_raised = vec![];
    for seed in 21..=25 {
        let base = MonitoringScenario {
            seed,
            creep_mm_per_day: 0.0,
            acceleration_start_days: None,
            epochs: 20,
            ..Default::default()
        };
        let s0 = base.generate();
        let k = 2; // R3
        let c = &s0.epochs[0].coordinates.points[k].covariance_m2;
        let c1 = &s0.epochs[1].coordinates.points[k].covariance_m2;
        let sigma_x_mm = ((c[0][0] + c1[0][0]) * 1e6).sqrt();
        let sc = MonitoringScenario {
            moved_stable: Some((k, 5, [n_sigma * sigma_x_mm, 0.0, 0.0])),
            ..base
        };
        let series = sc.generate();
        let alerts = AlertConfig::new("kamo", contract_rules());
        let steps = common::run(&series, &series.points, &AnalysisConfig::default(), &alerts);
        // Same series with R3 monitored: the datum the exclusion should reproduce.
        let mut without = series.points.clone();
        without[k].role = PointRole::Monitored;
        let ref_steps = common::run(
            &series,
            &without,
            &AnalysisConfig::default(),
            &AlertConfig::new("kamo", vec![]),
        );
        let excluded: Vec<String> = steps
            .iter()
            .map(|s| s.analysis.datum.excluded.join("+"))
            .collect();
        println!("{n_sigma}σ, seed {seed}: excluded per epoch {excluded:?}");
        // The first raising (a false alarm before the move is possible, if rare).
        let raised = steps.iter().flat_map(|s| &s.events).find(|e| {
            e.alert.rule == AlertKind::ReferenceUnstable && e.event_type == AlertEventType::Raised
        });
        for (i, (s, r)) in steps.iter().zip(&ref_steps).enumerate() {
            let epoch = i + 1;
            assert_eq!(s.analysis.datum.method, DatumMethod::StablePoints);
            if epoch < 5 {
                continue;
            }
            found.1 += 1;
            // Whenever something is excluded after the move, it is R3 and nothing else.
            assert!(
                s.analysis.datum.excluded.is_empty()
                    || s.analysis.datum.excluded == vec!["R3".to_string()]
            );
            if s.analysis.datum.excluded == vec!["R3".to_string()] {
                found.0 += 1;
                let mut max_diff: f64 = 0.0;
                for (p, q) in s.analysis.points.iter().zip(&r.analysis.points) {
                    if p.record.point != "R3" {
                        max_diff = max_diff
                            .max((p.record.dx_mm - q.record.dx_mm).abs())
                            .max((p.record.dz_mm - q.record.dz_mm).abs());
                    }
                }
                assert!(
                    max_diff < 1e-9,
                    "other displacements changed by {max_diff} mm"
                );
            }
        }
        let Some(raised) = raised else {
            // Not confirmed: then R3 was never excluded in 2 of 3 consecutive epochs.
            let flags: Vec<bool> = steps
                .iter()
                .map(|s| !s.analysis.datum.excluded.is_empty())
                .collect();
            assert!(
                flags
                    .windows(3)
                    .all(|w| w.iter().filter(|&&f| f).count() < 2),
                "seed {seed}: confirmed but not raised: {flags:?}"
            );
            not_raised.push(seed);
            continue;
        };
        if raised.alert.epoch >= Some(6) {
            assert_eq!(raised.alert.points, vec!["R3".to_string()]);
        } else {
            println!(
                "seed {seed}: false alarm before the move (α = 1 %): {:?}",
                raised.alert.points
            );
        }
        assert_eq!(raised.alert.level, AlertLevel::Warning);
        // Raised, it stays open to the end: R3 is still moved, and passing the test about every
        // other epoch must not resolve it.
        let resolved: Vec<_> = steps
            .iter()
            .flat_map(|s| &s.events)
            .filter(|e| {
                e.alert.rule == AlertKind::ReferenceUnstable
                    && e.event_type == AlertEventType::Resolved
                    && e.alert.epoch > raised.alert.epoch
            })
            .map(|e| e.alert.epoch)
            .collect();
        assert!(resolved.is_empty(), "seed {seed}: resolved at {resolved:?}");
        println!(
            "{n_sigma}σ, seed {seed}: reference_unstable raised at epoch {:?}: {}",
            raised.alert.epoch, raised.alert.message
        );
    }
    let rate = found.0 as f64 / found.1 as f64;
    println!(
        "R3 (moved {n_sigma}σ along X) excluded in {}/{} epochs after the move ({:.0} %); not raised: seeds {not_raised:?}",
        found.0,
        found.1,
        100.0 * rate
    );
    assert!(
        rate >= min_rate,
        "{n_sigma}σ: excluded in {rate:.2} of the epochs"
    );
    assert!(
        not_raised.len() <= max_not_raised,
        "{n_sigma}σ: not raised on seeds {not_raised:?}"
    );
}

/// Stable points that do not move: the congruence test excludes one now and then (its α is 1 %
/// per epoch, and the reference epoch's errors, common to every epoch, make exclusions of one
/// point cluster), but `reference_unstable`, which needs a point excluded in 2 of 3 epochs, is
/// raised at most once in 1000 epochs (20 seeds × 200 epochs).
#[test]
fn still_stable_points_rarely_raise_reference_unstable() {
    let (mut epochs, mut excluding, mut raised) = (0usize, 0usize, 0usize);
    for seed in 31..=50 {
        let series = MonitoringScenario {
            seed,
            epochs: 201,
            creep_mm_per_day: 0.0,
            acceleration_start_days: None,
            ..Default::default()
        }
        .generate();
        let steps = common::run(
            &series,
            &series.points,
            &AnalysisConfig::default(),
            &AlertConfig::new("s", vec![]),
        );
        let ex = steps
            .iter()
            .filter(|s| !s.analysis.datum.excluded.is_empty())
            .count();
        let r = steps
            .iter()
            .flat_map(|s| &s.events)
            .filter(|e| {
                e.alert.rule == AlertKind::ReferenceUnstable
                    && e.event_type == AlertEventType::Raised
            })
            .count();
        println!("seed {seed}: {ex} epochs with an exclusion, {r} raised");
        epochs += steps.len();
        excluding += ex;
        raised += r;
    }
    println!(
        "all seeds: {excluding}/{epochs} epochs with an exclusion ({:.2} %), reference_unstable raised {raised} times",
        100.0 * excluding as f64 / epochs as f64
    );
    // The exclusions happen (the test is not blind); the alert stays rare.
    assert!(excluding > 0);
    assert!(
        raised * 1000 <= epochs,
        "{raised} raised in {epochs} epochs"
    );
}

/// Velocity and time to failure are properties of the motion, not of the reference: with the
/// reference moved to the last epoch (as staff may do after re-installing targets), the last
/// epoch's filtered velocity and forecast of the accelerating block, and of its points, agree
/// with those against the first epoch, and its velocity and time-to-failure alarms hold.
#[test]
fn velocity_and_forecast_do_not_depend_on_where_the_reference_lies() {
    use cliffwatch_core::analysis::{analyse_series, GroupConfig, GroupKind, SeriesAnalysis};
    for seed in 1..=3 {
        let sc = MonitoringScenario {
            seed,
            ..Default::default()
        };
        let series = sc.generate();
        let coords: Vec<_> = series
            .epochs
            .iter()
            .map(|e| e.coordinates.clone())
            .collect();
        let block: Vec<String> = (1..=sc.block_points).map(|k| format!("B{k}")).collect();
        let config = AnalysisConfig {
            groups: vec![GroupConfig {
                name: "B".into(),
                kind: GroupKind::Block,
                direction: None,
                points: block.clone(),
                process_noise: None,
            }],
            ..Default::default()
        };
        let mut rules = contract_rules();
        for r in contract_rules() {
            rules.push(AlertRule {
                group: Some("B".into()),
                ..r
            });
        }
        let alerts = AlertConfig::new("kamo", rules);
        let run = |reference| analyse_series(reference, &coords, &series.points, &config, &alerts);
        let first = run(&coords[0]);
        let last_epoch = coords.last().unwrap().epoch;
        let filtered_at_end = |a: &SeriesAnalysis, subject: &str| {
            a.records
                .iter()
                .chain(&a.block_records)
                .find(|r| r.epoch == last_epoch && r.point == subject)
                .and_then(|r| r.filtered)
                .unwrap_or_else(|| panic!("seed {seed}: no filtered values of {subject}"))
        };
        // The reference at the last epoch itself, and three epochs before it.
        for back in [1, 4] {
            let moved = run(&coords[coords.len() - back]);
            for subject in block.iter().map(String::as_str).chain(["B"]) {
                let (a, b) = (
                    filtered_at_end(&first, subject),
                    filtered_at_end(&moved, subject),
                );
                let (va, sa) = (a.f_velocity_mm_per_day, a.sigma_f_velocity_mm_per_day);
                let (vb, sb) = (b.f_velocity_mm_per_day, b.sigma_f_velocity_mm_per_day);
                println!("seed {seed} {subject}: velocity {va:.2} ± {sa:.2} against the first epoch, {vb:.2} ± {sb:.2} against the {back}. from the end; time to failure {:?} / {:?} h",
                    a.f_time_to_failure_hours, b.f_time_to_failure_hours);
                // The same data filtered, only the reference's share of the covariances differs.
                assert!(va > 5.0 && vb > 5.0, "seed {seed} {subject} {back}");
                assert!((va - vb).abs() < 0.1 * va, "seed {seed} {subject} {back}");
                assert!((sa / sb - 1.0).abs() < 0.5, "seed {seed} {subject} {back}");
                if subject == "B" {
                    // Both references give the same forecast, or neither gives one.
                    let (ta, tb) = (a.f_time_to_failure_hours, b.f_time_to_failure_hours);
                    let same = ta.zip(tb).map_or(ta.is_none() && tb.is_none(), |(x, y)| {
                        (x - y).abs() < 0.25 * x.max(12.0)
                    });
                    assert!(same, "seed {seed} {back}: {ta:?} h / {tb:?} h");
                }
            }
            // The block's velocity and time-to-failure alarms hold.
            for analysis in [&first, &moved] {
                for kind in [AlertKind::VelocityMmPerDay, AlertKind::TimeToFailureHours] {
                    let alert = analysis.replayed.find_subject(None, Some("B"), kind);
                    assert_eq!(
                        alert.map(|a| a.level),
                        Some(AlertLevel::Alarm),
                        "seed {seed} {back}: {kind:?}"
                    );
                }
            }
            // Its displacement alert, measured from a reference at the last epoch, is gone.
            let displacement = |a: &SeriesAnalysis| {
                a.replayed
                    .find_subject(None, Some("B"), AlertKind::DisplacementMm)
                    .is_some()
            };
            assert!(displacement(&first));
            if back == 1 {
                assert!(!displacement(&moved));
            }
        }
    }
}

/// The reference epoch analysed against itself enters the history as 0 ± 0 (the service stores
/// that row). The first epoch after it still gets a raw velocity, the line through the
/// reference's zero: d / Δt. (A σ of 0 once made every raw fit singular until the row left the
/// window.)
#[test]
fn the_reference_row_leaves_raw_velocities_defined() {
    let config = AnalysisConfig::default();
    for seed in 1..=3 {
        let series = MonitoringScenario {
            seed,
            ..Default::default()
        }
        .generate();
        let reference = &series.epochs[0].coordinates;
        let mut history = History::new();
        let own = analyse_epoch(reference, reference, &series.points, &history, &config)
            .expect("the reference against itself");
        for r in own.records() {
            assert_eq!(r.d_mm, 0.0, "{}", r.point);
            history.entry(r.point.clone()).or_default().push(r);
        }
        let first = &series.epochs[1].coordinates;
        let a =
            analyse_epoch(reference, first, &series.points, &history, &config).expect("analysis");
        let dt_days = (a.observed_at - reference.observed_at).num_seconds() as f64 / 86_400.0;
        assert!(!a.points.is_empty());
        for p in &a.points {
            let r = &p.record;
            let v = r
                .velocity_mm_per_day
                .unwrap_or_else(|| panic!("seed {seed} {}: no raw velocity", r.point));
            let want = r.d_mm / dt_days;
            assert!(
                (v - want).abs() <= 1e-3 * want.abs() + 1e-9,
                "seed {seed} {}: velocity {v} against d/Δt {want}",
                r.point
            );
        }
    }
}
