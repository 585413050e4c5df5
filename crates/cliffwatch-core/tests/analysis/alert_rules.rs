//! Rules' readings: threshold exceedance at the confidence (σ = 0.5 mm), time-to-failure rules
//! at 95 %, persistence (`for_epochs`), the filtered and either sources, and block rules.

use cliffwatch_core::analysis::{
    evaluate_alerts, resolve, AlertConfig, AlertEventType, AlertLevel, AlertRule, AlertState,
};

use super::alert_fixtures::*;

/// A value significantly different from zero is not enough: it must exceed the threshold at the
/// site's one-sided confidence, `d − z·σ > above` (z = 2.326 at 99 %, 1.645 at 95 %).
#[test]
fn threshold_exceedance_is_tested_at_the_confidence() {
    use AlertEventType::*;
    use AlertLevel::*;
    let cfg = contract_config();
    assert!((cfg.z() - 2.326).abs() < 1e-3);
    // 5.9 mm ± 0.5: 5.9 − 1.16 < 5, no watch; 6.2: 6.2 − 1.16 > 5, watch.
    let ev = feed_sigma(&cfg, &[(5.9, 0.5), (6.2, 0.5)]);
    assert_eq!(ev[0], vec![]);
    assert_eq!(ev[1], vec![(Raised, Watch)]);
    // At 95 % the margin is 0.82 mm: 5.9 raises.
    let cfg95 = AlertConfig {
        confidence: 0.95,
        ..contract_config()
    };
    let ev = feed_sigma(&cfg95, &[(5.9, 0.5)]);
    assert_eq!(ev[0], vec![(Raised, Watch)]);
    // A `below` rule: the value plus z·σ must lie below the threshold.
    let ttf: AlertRule = serde_json::from_str(
        r#"{"level": "alarm", "metric": "time_to_failure_hours", "below": 96, "source": "raw"}"#,
    )
    .expect("rule");
    let cfg = AlertConfig::new("kamo", vec![ttf]);
    let mut a = analysis_sigma(2, 30.0, 0.5, true, None, &[]);
    let f = |h: f64, s: f64| -> cliffwatch_core::analysis::FailureForecast {
        serde_json::from_value(serde_json::json!({
            "time_to_failure_hours": h, "sigma_hours": s, "r2": 0.9, "velocities": 8
        }))
        .expect("forecast")
    };
    a.points[0].failure = Some(f(80.0, 10.0));
    let (_, ev) = evaluate_alerts(&cfg, &AlertState::default(), &a, a.observed_at);
    assert!(ev.is_empty(), "80 + 2.33·10 > 96: not yet");
    a.points[0].failure = Some(f(60.0, 10.0));
    let (_, ev) = evaluate_alerts(&cfg, &AlertState::default(), &a, a.observed_at);
    assert_eq!(ev.len(), 1);
    assert_eq!(ev[0].alert.level, Alarm);
    // Out-of-range confidences are refused.
    for c in [0.5, 1.0, 0.3, f64::NAN] {
        let bad = AlertConfig {
            confidence: c,
            ..contract_config()
        };
        assert!(bad.validate().is_err(), "confidence {c}");
    }
}

/// A time-to-failure rule reads the forecast at 95 % unless the rule sets its own confidence or the
/// site's is lower; other rules read the site's.
#[test]
fn time_to_failure_rules_default_to_95_percent() {
    use AlertLevel::*;
    let rule = |extra: &str| -> AlertRule {
        serde_json::from_str(&format!(
            r#"{{"level": "alarm", "metric": "time_to_failure_hours", "below": 96, "source": "raw"{extra}}}"#
        ))
        .expect("rule")
    };
    let f = |h: f64, s: f64| -> cliffwatch_core::analysis::FailureForecast {
        serde_json::from_value(serde_json::json!({
            "time_to_failure_hours": h, "sigma_hours": s, "r2": 0.9, "velocities": 8
        }))
        .expect("forecast")
    };
    let alarm = |cfg: &AlertConfig, h: f64, s: f64| {
        let mut a = analysis_sigma(2, 30.0, 0.5, true, None, &[]);
        a.points[0].failure = Some(f(h, s));
        let (_, ev) = evaluate_alerts(cfg, &AlertState::default(), &a, a.observed_at);
        ev.iter().any(|e| e.alert.level == Alarm)
    };
    // 78 ± 10 h: 78 + 1.645·10 = 94.4 < 96 (alarm at 95 %); 78 + 2.326·10 = 101 (none at 99 %).
    let site99 = AlertConfig::new("kamo", vec![rule("")]);
    assert_eq!(site99.rules[0].confidence(site99.confidence), 0.95);
    assert!(alarm(&site99, 78.0, 10.0));
    assert!(!alarm(&site99, 81.0, 10.0), "81 + 16.4 > 96");
    let strict = AlertConfig::new("kamo", vec![rule(r#", "confidence": 0.99"#)]);
    assert!(!alarm(&strict, 78.0, 10.0));
    assert!(alarm(&strict, 72.0, 10.0), "72 + 23.3 < 96");
    // A site more sensitive than 95 % keeps its own: 84 + 1.28·10 = 96.8 at 90 % fires only below.
    let site90 = AlertConfig {
        confidence: 0.9,
        ..AlertConfig::new("kamo", vec![rule("")])
    };
    assert!(alarm(&site90, 83.0, 10.0));
    assert!(!alarm(
        &AlertConfig::new("kamo", vec![rule("")]),
        83.0,
        10.0
    ));
    // A displacement rule's own confidence overrides the site's: 5.9 ± 0.5 mm at 95 % watches.
    let watch: AlertRule = serde_json::from_str(
        r#"{"level": "watch", "metric": "displacement_mm", "above": 5, "confidence": 0.95}"#,
    )
    .expect("rule");
    let ev = feed_sigma(&AlertConfig::new("kamo", vec![watch]), &[(5.9, 0.5)]);
    assert_eq!(ev[0], vec![(AlertEventType::Raised, Watch)]);
    // Out-of-range rule confidences are refused.
    for c in ["0.5", "1.0", "0.3", "0.9999999"] {
        assert!(
            rule(&format!(r#", "confidence": {c}"#)).validate().is_err(),
            "{c}"
        );
    }
}

/// `for_epochs: N` needs N consecutive triggering epochs; one quiet epoch starts the count anew.
#[test]
fn for_epochs_asks_for_consecutive_triggering_epochs() {
    use AlertEventType::*;
    use AlertLevel::*;
    let mut cfg = contract_config();
    cfg.rules[0].for_epochs = Some(3);
    let ev = feed_sigma(
        &cfg,
        &[
            (7.0, 0.1),
            (7.0, 0.1),
            (3.0, 0.1),
            (7.0, 0.1),
            (7.0, 0.1),
            (7.0, 0.1),
        ],
    );
    assert!(ev[..5].iter().all(Vec::is_empty), "{ev:?}");
    assert_eq!(ev[5], vec![(Raised, Watch)]);
    let bad: AlertRule = serde_json::from_str(
        r#"{"level": "watch", "metric": "displacement_mm", "above": 5, "for_epochs": 0}"#,
    )
    .expect("parses");
    assert!(bad.validate().is_err());
}

/// Rules read the filtered state when they say so (and velocity and time to failure by default).
#[test]
fn filtered_source_reads_the_filtered_state() {
    use cliffwatch_core::analysis::{Metric, Source};
    let rule: AlertRule = serde_json::from_str(
        r#"{"level": "warning", "metric": "displacement_mm", "above": 10, "source": "filtered"}"#,
    )
    .expect("rule");
    assert_eq!(rule.source(), Source::Filtered);
    let v: AlertRule =
        serde_json::from_str(r#"{"level": "alarm", "metric": "velocity_mm_per_day", "above": 5}"#)
            .expect("rule");
    assert_eq!(v.source(), Metric::VelocityMmPerDay.default_source());
    assert_eq!(v.source(), Source::Filtered);
    let cfg = AlertConfig::new("kamo", vec![rule]);
    // Raw 12 mm, but no filtered state: nothing.
    let mut a = analysis_sigma(2, 12.0, 0.1, true, None, &[]);
    a.points[0].record.filtered = None;
    let (_, ev) = evaluate_alerts(&cfg, &AlertState::default(), &a, a.observed_at);
    assert!(ev.is_empty());
    let filtered = |d: f64| filtered_along_x(d, 0.3);
    a.points[0].record.filtered = Some(filtered(10.5));
    let (_, ev) = evaluate_alerts(&cfg, &AlertState::default(), &a, a.observed_at);
    assert!(ev.is_empty(), "10.5 − 2.33·0.3 < 10");
    a.points[0].record.filtered = Some(filtered(11.0));
    let (_, ev) = evaluate_alerts(&cfg, &AlertState::default(), &a, a.observed_at);
    assert_eq!(ev.len(), 1);
    assert_eq!(ev[0].alert.value, Some(11.0));
}

/// Displacement rules read either estimate by default: the filtered one raises on a steady creep
/// whose raw epochs are too noisy, a raw exceedance the filter does not share raises only when
/// the next epoch confirms it (one noisy epoch never alerts alone), and the rule clears only
/// when both are under the clear threshold.
#[test]
fn either_source_fires_on_raw_or_filtered_and_clears_on_both() {
    use cliffwatch_core::analysis::{Metric, Source};
    use AlertEventType::*;
    use AlertLevel::*;
    let watch: AlertRule = serde_json::from_str(
        r#"{"level": "watch", "metric": "displacement_mm", "above": 5, "clear_below": 4}"#,
    )
    .expect("rule");
    assert_eq!(watch.source(), Source::Either);
    assert_eq!(Metric::DisplacementMm.default_source(), Source::Either);
    let cfg = AlertConfig::new("kamo", vec![watch]);
    // (raw d ± σ, filtered d ± σ) per epoch, and what the watch does.
    type Epoch = ((f64, f64), (f64, f64), Vec<(AlertEventType, AlertLevel)>);
    let epochs: [Epoch; 10] = [
        // neither exceeds at 99 %: 6 − 2.33 < 5 and 5.5 − 2.33·0.4 < 5
        ((6.0, 1.0), (5.5, 0.4), vec![]),
        // the filter does: 6.2 − 0.93 > 5, while the raw 6.5 ± 1 does not
        ((6.5, 1.0), (6.2, 0.4), vec![(Raised, Watch)]),
        // raw below the clear threshold, filtered not: stays open
        ((3.5, 1.0), (4.5, 0.4), vec![]),
        // both below 4: clears
        ((3.0, 1.0), (3.9, 0.4), vec![(Resolved, Watch)]),
        // one noisy epoch: the raw 12 ± 1 exceeds, the filter (5.5 − 0.93 < 5) does not: no alert
        ((12.0, 1.0), (5.5, 0.4), vec![]),
        // and it was noise: the next epoch does not confirm it
        ((3.0, 1.0), (3.9, 0.4), vec![]),
        // a step: raw over the threshold, the filter lagging (5.8 − 0.93 < 5) ...
        ((12.0, 1.0), (5.8, 0.4), vec![]),
        // ... confirmed by the next raw epoch: raised
        ((12.2, 1.0), (5.9, 0.4), vec![(Raised, Watch)]),
        // both back below 4: clears
        ((3.0, 1.0), (3.0, 0.4), vec![(Resolved, Watch)]),
        // a step the filter shares (7 − 0.93 > 5) raises at once
        ((12.0, 1.0), (7.0, 0.4), vec![(Raised, Watch)]),
    ];
    let mut st = AlertState::default();
    for (k, ((d, s), (fd, fs), want)) in epochs.into_iter().enumerate() {
        let mut a = analysis_sigma(k as i64 + 2, d, s, true, None, &[]);
        a.points[0].record.filtered = Some(filtered_along_x(fd, fs));
        let (next, ev) = evaluate_alerts(&cfg, &st, &a, a.observed_at);
        st = next;
        let got: Vec<_> = ev.iter().map(|e| (e.event_type, e.alert.level)).collect();
        assert_eq!(got, want, "epoch {k}");
    }
}

/// A rule naming a declared block applies to the block's motion: one alert for the group, with
/// `point` null, the group and its points; the block's own points are not alerted by it.
#[test]
fn block_rules_raise_group_alerts() {
    use cliffwatch_core::analysis::rigid_body::{BlockModel, BlockMotion};
    use cliffwatch_core::analysis::{BlockAnalysis, Metric, Reading, Readings, Source};
    let rule: AlertRule = serde_json::from_str(
        r#"{"level": "warning", "metric": "displacement_mm", "above": 10, "group": "B1"}"#,
    )
    .expect("rule");
    let cfg = AlertConfig::new("kamo", vec![rule]);
    let mut a = analysis_sigma(2, 20.0, 0.1, true, Some("B1"), &[]);
    let mut readings = Readings::default();
    for source in [Source::Raw, Source::Filtered] {
        readings.set(
            Metric::DisplacementMm,
            source,
            Reading {
                value: Some(12.0),
                sigma: 0.2,
                significant: true,
            },
        );
    }
    let motion = BlockMotion {
        model: BlockModel::Translation,
        points: vec!["T1".into(), "T2".into()],
        translation_mm: [12.0, 0.0, 0.0],
        covariance_mm2: [[0.04, 0.0, 0.0], [0.0, 0.04, 0.0], [0.0, 0.0, 0.04]],
        rotation_mrad: None,
        sigma_rotation_mrad: None,
        test_statistic: 1.0,
        redundancy: 3,
        rigid: true,
    };
    a.blocks.push(BlockAnalysis {
        group: "B1".into(),
        points: vec!["T1".into(), "T2".into()],
        readings,
        motion: Some(motion),
        failure: None,
        filtered: None,
        filtered_failure: None,
    });
    let (st, ev) = evaluate_alerts(&cfg, &AlertState::default(), &a, a.observed_at);
    assert_eq!(ev.len(), 1, "{ev:?}");
    let al = &ev[0].alert;
    assert_eq!(al.point, None);
    assert_eq!(al.group.as_deref(), Some("B1"));
    assert_eq!(al.points, vec!["T1".to_string(), "T2".to_string()]);
    assert_eq!(al.value, Some(12.0));
    assert!(al.id.contains("group-B1"), "{}", al.id);
    // Next epoch the block has no motion (too few members measured: fallen or hidden): its
    // alert stays as it was, nothing resolves.
    let mut b = analysis_sigma(3, 20.0, 0.1, true, Some("B1"), &[]);
    b.blocks.push(BlockAnalysis {
        group: "B1".into(),
        points: vec!["T1".into(), "T2".into()],
        readings: Readings::default(),
        motion: None,
        failure: None,
        filtered: None,
        filtered_failure: None,
    });
    let (kept, ev) = evaluate_alerts(&cfg, &st, &b, b.observed_at);
    assert!(
        ev.is_empty(),
        "a block without a motion changed its alert: {ev:?}"
    );
    assert_eq!(kept, st);
    // Resolving it by hand resets the group's rule memory.
    let (st, _) = resolve(&st, &al.id, "ops", t0()).expect("resolve");
    assert!(st.rules.is_empty(), "{:?}", st.rules);
}

/// A filtered velocity that wobbles around a velocity rule's threshold (1 mm/day; the true
/// velocity 1.05 mm/day with a ±0.15 mm/day sine and the filter's noise, σ 0.03 mm/day) raises
/// the rule at most once and never flips it back: without a `clear_below` a velocity rule clears
/// only below 0.8 of its threshold. Over 10 seeds of 40 epochs each. A velocity that truly falls
/// to 0.5 mm/day still clears it.
#[test]
fn a_velocity_wobbling_around_its_threshold_changes_level_at_most_once() {
    use cliffwatch_core::analysis::VELOCITY_CLEAR_FRACTION;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};
    let rule: AlertRule = serde_json::from_str(
        r#"{"level": "warning", "metric": "velocity_mm_per_day", "above": 1}"#,
    )
    .expect("rule");
    assert_eq!(rule.clear_threshold(), Some(VELOCITY_CLEAR_FRACTION));
    let cfg = AlertConfig::new("kamo", vec![rule]);
    let epoch = |k: i64, v: f64| {
        let mut a = analysis_sigma(k + 2, 20.0 + k as f64, 0.3, true, None, &[]);
        let mut f = filtered_along_x(20.0 + k as f64, 0.3);
        f.f_velocity_mm_per_day = v;
        f.sigma_f_velocity_mm_per_day = 0.03;
        a.points[0].record.filtered = Some(f);
        a
    };
    let mut flips_without_hysteresis = 0;
    for seed in 0..10u64 {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let noise = Normal::new(0.0, 0.03).expect("normal");
        let mut st = AlertState::default();
        let mut changes = vec![];
        let mut above_then_below = 0;
        let mut was_over = false;
        for k in 0..40i64 {
            let v = 1.05 + 0.15 * (k as f64 * 0.9).sin() + noise.sample(&mut rng);
            let a = epoch(k, v);
            let (next, ev) = evaluate_alerts(&cfg, &st, &a, a.observed_at);
            st = next;
            changes.extend(ev.iter().map(|e| (k, e.event_type)));
            // What a rule without hysteresis would have done: raise over, resolve under.
            let over = v - 2.326 * 0.03 > 1.0;
            if was_over && !over {
                above_then_below += 1;
            }
            was_over = over;
        }
        flips_without_hysteresis += above_then_below;
        assert_eq!(
            changes.len(),
            1,
            "seed {seed}: one raise and nothing after it: {changes:?}"
        );
        assert_eq!(changes[0].1, AlertEventType::Raised, "seed {seed}");
        // Slowing down to half the threshold clears it.
        let a = epoch(40, 0.5);
        let (_, ev) = evaluate_alerts(&cfg, &st, &a, a.observed_at);
        assert_eq!(ev.len(), 1, "seed {seed}: {ev:?}");
        assert_eq!(ev[0].event_type, AlertEventType::Resolved, "seed {seed}");
    }
    // The series does wobble: a rule clearing at its threshold would have flipped many times.
    assert!(flips_without_hysteresis >= 20, "{flips_without_hysteresis}");
}

/// An explicit `clear_below` wins over the velocity default, and other metrics get none.
#[test]
fn only_velocity_rules_without_a_clear_threshold_get_the_default() {
    let parse = |s: &str| serde_json::from_str::<AlertRule>(s).expect("rule");
    let v = parse(
        r#"{"level": "warning", "metric": "velocity_mm_per_day", "above": 2, "clear_below": 0.5}"#,
    );
    assert_eq!(v.clear_threshold(), Some(0.5));
    let v = parse(r#"{"level": "warning", "metric": "velocity_mm_per_day", "below": -2}"#);
    assert_eq!(v.clear_threshold(), Some(-1.6));
    let d = parse(r#"{"level": "warning", "metric": "displacement_mm", "above": 10}"#);
    assert_eq!(d.clear_threshold(), None);
    let t = parse(r#"{"level": "alarm", "metric": "time_to_failure_hours", "below": 96}"#);
    assert_eq!(t.clear_threshold(), None);
}
