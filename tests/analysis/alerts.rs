//! The alert state machine: contract rule JSON, raise/escalate/de-escalate/resolve, hysteresis, quiet
//! epochs, significance, groups, acknowledgement, manual resolution, site-level alerts; threshold
//! exceedance at confidence, persistence (`for_epochs`), the filtered source and block groups.
//!
//! The state-machine tests use σ = 0.1 mm, so that a value 0.25 mm past a threshold exceeds it at
//! 99 % (z = 2.33); the confidence tests use σ = 0.5 mm.

use chrono::{DateTime, Duration, TimeZone, Utc};

use cliffwatch::analysis::{
    acknowledge, analysis_failed, check_overdue, evaluate_alerts, reconcile, resolve, AlertConfig,
    AlertEventType, AlertKind, AlertLevel, AlertRule, AlertState, AlertStatus, AnalysisError,
    DatumMethod, DatumReport, DisplacementRecord, EpochAnalysis, PointAnalysis, PointRole,
};

fn t0() -> DateTime<Utc> {
    Utc.with_ymd_and_hms(2026, 11, 1, 9, 0, 0)
        .single()
        .expect("time")
}

fn analysis(
    epoch: i64,
    d_mm: f64,
    significant: bool,
    group: Option<&str>,
    excluded: &[&str],
) -> EpochAnalysis {
    analysis_sigma(epoch, d_mm, 0.1, significant, group, excluded)
}

fn analysis_sigma(
    epoch: i64,
    d_mm: f64,
    sigma_mm: f64,
    significant: bool,
    group: Option<&str>,
    excluded: &[&str],
) -> EpochAnalysis {
    let at = t0() + Duration::days(epoch);
    let record = DisplacementRecord {
        point: "T1".into(),
        epoch,
        observed_at: at,
        dx_mm: d_mm,
        dy_mm: 0.0,
        dz_mm: 0.0,
        d_mm,
        sigma_dx_mm: sigma_mm,
        sigma_dy_mm: sigma_mm,
        sigma_dz_mm: sigma_mm,
        sigma_mm,
        cov_dxdy_mm2: None,
        cov_dxdz_mm2: None,
        cov_dydz_mm2: None,
        d_along_mm: None,
        significant,
        velocity_mm_per_day: None,
        time_to_failure_hours: None,
        time_to_failure_sigma_hours: None,
        filtered: None,
    };
    EpochAnalysis {
        epoch,
        observed_at: at,
        reference_epoch: 1,
        datum: DatumReport {
            method: DatumMethod::StablePoints,
            points: vec![],
            excluded: excluded.iter().map(|s| s.to_string()).collect(),
            moved: None,
            congruence: vec![],
            translation_mm: [0.0; 3],
            rotation_mrad: [0.0; 3],
            scale_ppm: 0.0,
        },
        points: vec![PointAnalysis {
            record,
            role: PointRole::Monitored,
            group: group.map(str::to_string),
            in_datum: false,
            covariance_mm2: [
                [sigma_mm * sigma_mm, 0.0, 0.0],
                [0.0, sigma_mm * sigma_mm, 0.0],
                [0.0, 0.0, sigma_mm * sigma_mm],
            ],
            sigma_along_mm: None,
            test_statistic: 0.0,
            test_dof: 3,
            critical_value: 11.34,
            kinematics: None,
            failure: None,
            filtered_along_mm: None,
            filtered_failure: None,
        }],
        new_points: vec![],
        warnings: vec![],
        blocks: vec![],
    }
}

fn contract_config() -> AlertConfig {
    let rules: Vec<AlertRule> = serde_json::from_str(
        r#"[{"level": "watch",   "metric": "displacement_mm",       "above": 5.0, "clear_below": 4.0},
            {"level": "warning", "metric": "displacement_mm",       "above": 10.0},
            {"level": "alarm",   "metric": "velocity_mm_per_day",   "above": 5.0},
            {"level": "alarm",   "metric": "time_to_failure_hours", "below": 48.0}]"#,
    )
    .expect("contract rule JSON parses");
    assert!(rules
        .iter()
        .all(|r| r.require_significant && r.validate().is_ok()));
    AlertConfig::new("kamo", rules)
}

/// Feeds a series of (d_mm, significant) and returns the event types per epoch and the final state.
fn feed(
    cfg: &AlertConfig,
    series: &[(f64, bool)],
) -> (Vec<Vec<(AlertEventType, AlertLevel)>>, AlertState) {
    let mut st = AlertState::default();
    let mut out = vec![];
    for (k, &(d, s)) in series.iter().enumerate() {
        let a = analysis(k as i64 + 2, d, s, None, &[]);
        let (n, ev) = evaluate_alerts(cfg, &st, &a, a.observed_at);
        st = n;
        out.push(ev.iter().map(|e| (e.event_type, e.alert.level)).collect());
    }
    (out, st)
}

#[test]
fn raise_escalate_deescalate_resolve_with_hysteresis() {
    use AlertEventType::*;
    use AlertLevel::*;
    let cfg = contract_config();
    let (ev, st) = feed(
        &cfg,
        &[
            (3.0, true),
            (5.5, true),
            (11.0, true),
            (9.0, true),
            (4.5, true),
            (3.9, true),
            (6.0, true),
        ],
    );
    assert_eq!(ev[0], vec![]);
    assert_eq!(ev[1], vec![(Raised, Watch)]);
    assert_eq!(ev[2], vec![(Escalated, Warning)]);
    // warning has no clear threshold: quiet_epochs = 1 clears it at once.
    assert_eq!(ev[3], vec![(Deescalated, Watch)]);
    // 4.5 is inside the watch hysteresis band (clear_below 4): still open.
    assert_eq!(ev[4], vec![]);
    assert_eq!(ev[5], vec![(Resolved, Watch)]);
    assert_eq!(ev[6], vec![(Raised, Watch)]);
    assert_eq!(st.alerts.len(), 1);
    assert_eq!(st.level_of("T1"), Some(Watch));
}

/// Hysteresis holds through an epoch whose value is not significant (a station missing, say):
/// 6 mm that cannot be told from zero is still above `clear_below` 4 and does not clear the watch
/// (clearing there would send `resolved` for a block that may be moving, and `raised` again next
/// time); a value below the clear threshold clears, significant or not.
#[test]
fn a_value_that_is_not_significant_does_not_break_the_hysteresis() {
    use AlertEventType::*;
    use AlertLevel::*;
    let (ev, st) = feed(
        &contract_config(),
        &[
            (6.0, true),
            (6.0, false),
            (4.5, false),
            (6.0, true),
            (3.0, false),
        ],
    );
    assert_eq!(ev[0], vec![(Raised, Watch)]);
    assert_eq!(ev[1], vec![], "6 mm, not significant: still open");
    assert_eq!(
        ev[2],
        vec![],
        "4.5 mm, not significant: in the band, still open"
    );
    assert_eq!(ev[3], vec![]);
    assert_eq!(ev[4], vec![(Resolved, Watch)], "3 mm < clear_below");
    assert!(st.rules.is_empty(), "{:?}", st.rules);
}

#[test]
fn not_significant_is_not_alertable() {
    let (ev, st) = feed(&contract_config(), &[(50.0, false), (50.0, false)]);
    assert!(ev.iter().all(Vec::is_empty));
    assert!(st.alerts.is_empty());
    // Unless the rule says so.
    let mut cfg = contract_config();
    cfg.rules[0].require_significant = false;
    let (ev, _) = feed(&cfg, &[(6.0, false)]);
    assert_eq!(ev[0], vec![(AlertEventType::Raised, AlertLevel::Watch)]);
}

#[test]
fn quiet_epochs_delay_clearing() {
    let mut cfg = contract_config();
    cfg.rules[1].quiet_epochs = Some(3);
    let (ev, _) = feed(&cfg, &[(11.0, true), (8.0, true), (8.0, true), (8.0, true)]);
    assert_eq!(ev[0], vec![(AlertEventType::Raised, AlertLevel::Warning)]);
    assert_eq!(ev[1], vec![]);
    assert_eq!(ev[2], vec![]);
    assert_eq!(
        ev[3],
        vec![(AlertEventType::Deescalated, AlertLevel::Watch)]
    );
}

#[test]
fn groups_restrict_rules() {
    let mut cfg = contract_config();
    for r in &mut cfg.rules {
        r.group = Some("block".into());
    }
    let a = analysis(2, 20.0, true, Some("other"), &[]);
    let (_, ev) = evaluate_alerts(&cfg, &AlertState::default(), &a, a.observed_at);
    assert!(ev.is_empty());
    let a = analysis(2, 20.0, true, Some("block"), &[]);
    let (_, ev) = evaluate_alerts(&cfg, &AlertState::default(), &a, a.observed_at);
    assert_eq!(ev.len(), 1);
    assert_eq!(ev[0].alert.level, AlertLevel::Warning);
}

#[test]
fn acknowledge_and_resolve_by_hand() {
    let cfg = contract_config();
    let (_, st) = feed(&cfg, &[(6.0, true)]);
    let id = st.alerts[0].id.clone();
    assert_eq!(id, "kamo:T1:displacement_mm:2");
    let (st, ev) = acknowledge(&st, &id, "ops", Some("seen"), t0()).expect("ack");
    assert_eq!(ev.event_type, AlertEventType::Acknowledged);
    assert_eq!(st.alerts[0].status, AlertStatus::Acknowledged);
    assert_eq!(st.alerts[0].acknowledged_by.as_deref(), Some("ops"));
    // The acknowledgement stands: a second one is refused and changes nothing.
    assert_eq!(
        acknowledge(&st, &id, "night shift", None, t0()).map(|_| ()),
        Err(AnalysisError::AlreadyAcknowledged {
            id: id.clone(),
            by: "ops".into()
        })
    );
    // Escalation re-opens for acknowledgement and clears the old one (its event keeps it).
    let a = analysis(3, 12.0, true, None, &[]);
    let (st, ev) = evaluate_alerts(&cfg, &st, &a, a.observed_at);
    assert_eq!(ev[0].event_type, AlertEventType::Escalated);
    assert_eq!(st.alerts[0].status, AlertStatus::Open);
    assert_eq!(st.alerts[0].acknowledged_by, None);
    assert_eq!(st.alerts[0].comment, None);
    assert!(acknowledge(&st, "nope", "ops", None, t0()).is_err());
    let (acked, _) = acknowledge(&st, &id, "night shift", None, t0()).expect("ack again");
    assert_eq!(
        acked.alerts[0].acknowledged_by.as_deref(),
        Some("night shift")
    );
    let (st, ev) = resolve(&st, &id, "ops", t0()).expect("resolve");
    assert_eq!(ev.event_type, AlertEventType::Resolved);
    assert!(st.alerts.is_empty() && st.rules.is_empty());
    // State round-trips through JSON (it is stored).
    let json = serde_json::to_string(&st).expect("ser");
    assert_eq!(serde_json::from_str::<AlertState>(&json).expect("de"), st);
}

#[test]
fn site_level_alerts() {
    let mut cfg = contract_config();
    cfg.schedule_hours = Some(24.0);
    let st = AlertState::default();
    let last = t0();
    let (st, ev) = check_overdue(&cfg, &st, Some(last), last + Duration::hours(29));
    assert!(ev.is_empty(), "within the 25 % grace");
    let (st, ev) = check_overdue(&cfg, &st, Some(last), last + Duration::hours(31));
    assert_eq!(ev.len(), 1);
    assert_eq!(ev[0].alert.rule, AlertKind::CampaignOverdue);
    assert!(ev[0].alert.point.is_none());
    let (st, ev) = check_overdue(&cfg, &st, Some(last), last + Duration::hours(40));
    assert!(ev.is_empty(), "raised once");
    // An epoch excluding a stable point: overdue resolves; one exclusion is not yet a finding.
    let a = analysis(2, 1.0, false, None, &["R3"]);
    let (st, ev) = evaluate_alerts(&cfg, &st, &a, a.observed_at);
    let kinds: Vec<_> = ev.iter().map(|e| (e.alert.rule, e.event_type)).collect();
    assert_eq!(
        kinds,
        vec![(AlertKind::CampaignOverdue, AlertEventType::Resolved)]
    );
    // Excluded again in the next epoch: confirmed, reference_unstable raised naming it.
    let a = analysis(3, 1.0, false, None, &["R3"]);
    let (st, ev) = evaluate_alerts(&cfg, &st, &a, a.observed_at);
    assert_eq!(ev.len(), 1, "{ev:?}");
    assert_eq!(ev[0].alert.rule, AlertKind::ReferenceUnstable);
    assert_eq!(ev[0].event_type, AlertEventType::Raised);
    let ru = st.find(None, AlertKind::ReferenceUnstable).expect("open");
    assert_eq!(ru.points, vec!["R3".to_string()]);
    assert_eq!(ru.level, AlertLevel::Warning);
    // Resolved by hand: gone, its memory too, so that it takes two exclusions again.
    let id = ru.id.clone();
    let (st, ev) = resolve(&st, &id, "ops", t0()).expect("resolve");
    assert_eq!(ev.event_type, AlertEventType::Resolved);
    assert!(st.find(None, AlertKind::ReferenceUnstable).is_none());
    let a = analysis(4, 1.0, false, None, &["R3"]);
    let (st, ev) = evaluate_alerts(&cfg, &st, &a, a.observed_at);
    assert!(ev.is_empty(), "{ev:?}");
    let a = analysis(5, 1.0, false, None, &["R3"]);
    let (st, ev) = evaluate_alerts(&cfg, &st, &a, a.observed_at);
    assert_eq!(ev[0].event_type, AlertEventType::Raised, "{ev:?}");
    assert!(st.find(None, AlertKind::ReferenceUnstable).is_some());
}

/// The epoch `epoch` whose stable-point datum kept `kept` and excluded `excluded`.
fn datum_epoch(epoch: i64, kept: &[&str], excluded: &[&str]) -> EpochAnalysis {
    let mut a = analysis(epoch, 1.0, false, None, excluded);
    a.datum.points = kept.iter().map(|s| s.to_string()).collect();
    a
}

/// The `reference_unstable` events of a run of epochs, one entry per epoch: (raised / resolved
/// or none, the points the open alert names after it).
fn reference_run(
    cfg: &AlertConfig,
    epochs: &[EpochAnalysis],
) -> Vec<(Option<AlertEventType>, Vec<String>)> {
    let mut st = AlertState::default();
    let mut out = vec![];
    for a in epochs {
        let (next, ev) = evaluate_alerts(cfg, &st, a, a.observed_at);
        st = next;
        let e = ev
            .iter()
            .find(|e| e.alert.rule == AlertKind::ReferenceUnstable)
            .map(|e| e.event_type);
        let points = st
            .find(None, AlertKind::ReferenceUnstable)
            .map(|a| a.points.clone())
            .unwrap_or_default();
        out.push((e, points));
    }
    out
}

/// `reference_unstable` names a stable point excluded in 2 of its last 3 tested epochs; a single
/// exclusion (the test's 1 % by chance) raises nothing; epochs that do not test the point
/// (not measured, or an IWST datum) neither count nor clear; a confirmed point clears after
/// `reference_quiet_epochs` epochs kept in the datum, and the alert resolves when none is left.
#[test]
fn reference_unstable_is_confirmed_and_clears_after_quiet_epochs() {
    use AlertEventType::*;
    let mut cfg = contract_config();
    cfg.reference_quiet_epochs = 3;
    let all = ["R1", "R2", "R3", "R4"];
    let without = |p: &str| all.iter().copied().filter(|q| *q != p).collect::<Vec<_>>();
    // One exclusion, then two epochs kept: never raised.
    let run = reference_run(
        &cfg,
        &[
            datum_epoch(1, &without("R3"), &["R3"]),
            datum_epoch(2, &all, &[]),
            datum_epoch(3, &all, &[]),
            datum_epoch(4, &without("R3"), &["R3"]),
        ],
    );
    assert!(run.iter().all(|(e, _)| e.is_none()), "{run:?}");
    // Excluded, kept once, excluded: 2 of 3, raised at the second exclusion.
    let mut epochs = vec![
        datum_epoch(1, &without("R3"), &["R3"]),
        datum_epoch(2, &all, &[]),
        datum_epoch(3, &without("R3"), &["R3"]),
    ];
    // Not measured (R3 absent from the datum and not excluded), and an IWST epoch: no change.
    epochs.push(datum_epoch(4, &without("R3"), &[]));
    let mut iwst = datum_epoch(5, &all, &[]);
    iwst.datum.method = DatumMethod::Iwst;
    epochs.push(iwst);
    // R2 excluded twice in a row joins; then both are kept: R3 clears after its 3rd epoch kept
    // (epoch 8), R2 after its own (epoch 10), and only then does the alert resolve.
    epochs.push(datum_epoch(6, &without("R2"), &["R2"]));
    epochs.push(datum_epoch(7, &without("R2"), &["R2"]));
    for e in 8..=11 {
        epochs.push(datum_epoch(e, &all, &[]));
    }
    let run = reference_run(&cfg, &epochs);
    let r3 = vec!["R3".to_string()];
    let both = vec!["R2".to_string(), "R3".to_string()];
    let r2 = vec!["R2".to_string()];
    let expected = vec![
        (None, vec![]),
        (None, vec![]),
        (Some(Raised), r3.clone()),
        (None, r3.clone()),
        (None, r3.clone()),
        (None, r3),
        (None, both),
        (None, r2.clone()),
        (None, r2),
        (Some(Resolved), vec![]),
        (None, vec![]),
    ];
    assert_eq!(run, expected);
}

#[test]
fn invalid_rules_are_reported() {
    let bad: AlertRule =
        serde_json::from_str(r#"{"level": "watch", "metric": "displacement_mm"}"#).expect("parses");
    assert!(bad.validate().is_err());
    let bad: AlertRule = serde_json::from_str(
        r#"{"level": "watch", "metric": "displacement_mm", "above": 5, "clear_below": 6}"#,
    )
    .expect("parses");
    assert!(bad.validate().is_err());
    assert!(serde_json::from_str::<AlertRule>(
        r#"{"level": "severe", "metric": "displacement_mm", "above": 5}"#
    )
    .is_err());
    // thresholds within ±1e9 in the metric's unit, hysteresis included
    let rule = |json: &str| serde_json::from_str::<AlertRule>(json).expect("parses");
    for (ok, json) in [
        (
            true,
            r#"{"level": "watch", "metric": "displacement_mm", "above": 1e9}"#,
        ),
        (
            false,
            r#"{"level": "watch", "metric": "displacement_mm", "above": 1.5e9}"#,
        ),
        (
            false,
            r#"{"level": "watch", "metric": "velocity_mm_per_day", "below": -1e300}"#,
        ),
        (
            false,
            r#"{"level": "watch", "metric": "displacement_along_mm", "below": -5, "clear_above": 1e10}"#,
        ),
        (
            true,
            r#"{"level": "watch", "metric": "displacement_along_mm", "below": -5, "clear_above": -1}"#,
        ),
    ] {
        let r = rule(json).validate();
        assert_eq!(r.is_ok(), ok, "{json}: {r:?}");
        if let Err(e) = r {
            assert!(e.to_string().contains("±1e9"), "{e}");
        }
    }
}

/// After a recomputation only the net change is announced: an alert open before and after keeps
/// its id, raising time and acknowledgement (escalation re-opens it), one that no longer holds is
/// resolved, a new one is raised; campaign_overdue is not replayed and stays.
#[test]
fn reconcile_announces_only_the_net_change() {
    use AlertEventType::*;
    let cfg = contract_config();
    let now = t0() + Duration::days(30);
    // Stored: T1 at watch (acknowledged), plus an overdue campaign.
    let (_, st) = feed(&cfg, &[(6.0, true)]);
    let id = st.alerts[0].id.clone();
    let (st, _) = acknowledge(&st, &id, "geologist", Some("seen"), t0()).expect("ack");
    let (st, _) = check_overdue(
        &AlertConfig {
            schedule_hours: Some(24.0),
            ..cfg.clone()
        },
        &st,
        Some(t0()),
        t0() + Duration::days(3),
    );
    assert_eq!(st.alerts.len(), 2);

    // Replayed at the same level: nothing to send, the acknowledgement stays.
    let (_, same) = feed(&cfg, &[(3.0, true), (6.5, true)]);
    let (r, ev) = reconcile(&st, &same, now, "the reference was set to epoch 2");
    assert!(ev.is_empty(), "{ev:?}");
    let a = r.find(Some("T1"), AlertKind::DisplacementMm).expect("kept");
    assert_eq!(a.id, id);
    assert_eq!(a.status, AlertStatus::Acknowledged);
    assert_eq!(a.acknowledged_by.as_deref(), Some("geologist"));
    assert_eq!(a.value, Some(6.5));
    assert!(r.find(None, AlertKind::CampaignOverdue).is_some());

    // Replayed at warning: one escalation, same id, open again.
    let (_, higher) = feed(&cfg, &[(11.0, true)]);
    let (r, ev) = reconcile(&st, &higher, now, "the reference was set to epoch 2");
    assert_eq!(ev.len(), 1);
    assert_eq!(ev[0].event_type, Escalated);
    assert_eq!(ev[0].alert.id, id);
    assert_eq!(ev[0].timestamp, now);
    let a = r.find(Some("T1"), AlertKind::DisplacementMm).expect("kept");
    assert_eq!(
        (a.status, a.acknowledged_by.as_deref(), a.comment.as_deref()),
        (AlertStatus::Open, None, None),
        "the acknowledgement of the lower level is cleared"
    );

    // Replayed with nothing: resolved once; the overdue campaign is still open.
    let (_, none) = feed(&cfg, &[(1.0, true)]);
    let (r, ev) = reconcile(&st, &none, now, "the reference was set to epoch 2");
    assert_eq!(ev.len(), 1);
    assert_eq!(
        (ev[0].event_type, ev[0].alert.id.as_str()),
        (Resolved, id.as_str())
    );
    // the message says why it resolved
    assert!(
        ev[0]
            .alert
            .message
            .ends_with(" — resolved: the reference was set to epoch 2"),
        "{}",
        ev[0].alert.message
    );
    assert_eq!(r.alerts.len(), 1);
    assert_eq!(r.alerts[0].rule, AlertKind::CampaignOverdue);

    // Nothing stored, the replay holds an alert: raised now.
    let (r, ev) = reconcile(
        &AlertState::default(),
        &higher,
        now,
        "the reference was set to epoch 2",
    );
    assert_eq!(ev.len(), 1);
    assert_eq!(ev[0].event_type, Raised);
    assert_eq!(ev[0].alert.raised_at, now);
    assert_eq!(r.alerts.len(), 1);
}

/// A failed analysis raises one site-level warning naming the epoch and the reason; a second
/// failure updates it silently; the next analysed epoch resolves it.
#[test]
fn analysis_failed_raises_once_and_resolves_on_the_next_analysis() {
    use AlertEventType::*;
    let cfg = contract_config();
    let (st, ev) = analysis_failed(
        &cfg,
        &AlertState::default(),
        7,
        t0(),
        "too few points",
        t0(),
    );
    assert_eq!(ev.len(), 1);
    assert_eq!(ev[0].event_type, Raised);
    assert_eq!(ev[0].alert.rule, AlertKind::AnalysisFailed);
    assert_eq!(ev[0].alert.level, AlertLevel::Warning);
    assert!(ev[0].alert.point.is_none());
    assert!(
        ev[0].alert.message.contains("epoch 7"),
        "{}",
        ev[0].alert.message
    );
    assert!(ev[0].alert.message.contains("too few points"));
    let (st, ev) = analysis_failed(&cfg, &st, 8, t0(), "still too few", t0());
    assert!(ev.is_empty());
    assert!(st.alerts[0].message.contains("epoch 8"));
    let a = analysis(9, 1.0, false, None, &[]);
    let (st, ev) = evaluate_alerts(&cfg, &st, &a, t0());
    assert_eq!(ev.len(), 1);
    assert_eq!(ev[0].event_type, Resolved);
    assert_eq!(ev[0].alert.rule, AlertKind::AnalysisFailed);
    assert!(st.alerts.is_empty());
}

/// Feeds (d_mm, σ_mm) epochs (all significant) and returns the event types per epoch.
fn feed_sigma(cfg: &AlertConfig, series: &[(f64, f64)]) -> Vec<Vec<(AlertEventType, AlertLevel)>> {
    let mut st = AlertState::default();
    let mut out = vec![];
    for (k, &(d, s)) in series.iter().enumerate() {
        let a = analysis_sigma(k as i64 + 2, d, s, true, None, &[]);
        let (n, ev) = evaluate_alerts(cfg, &st, &a, a.observed_at);
        st = n;
        out.push(ev.iter().map(|e| (e.event_type, e.alert.level)).collect());
    }
    out
}

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
    let f = |h: f64, s: f64| -> cliffwatch::analysis::FailureForecast {
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
    let f = |h: f64, s: f64| -> cliffwatch::analysis::FailureForecast {
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

/// A filtered state of `d` mm along X with σ `s` mm on each axis, still.
fn filtered_along_x(d: f64, s: f64) -> cliffwatch::analysis::FilteredValues {
    cliffwatch::analysis::FilteredValues {
        f_dx_mm: d,
        f_dy_mm: 0.0,
        f_dz_mm: 0.0,
        f_d_mm: d,
        sigma_f_dx_mm: s,
        sigma_f_dy_mm: s,
        sigma_f_dz_mm: s,
        sigma_f_d_mm: s,
        f_velocity_mm_per_day: 0.0,
        sigma_f_velocity_mm_per_day: 0.1,
        f_acceleration_mm_per_day2: None,
        sigma_f_acceleration_mm_per_day2: None,
        f_time_to_failure_hours: None,
        sigma_f_time_to_failure_hours: None,
    }
}

/// Rules read the filtered state when they say so (and velocity and time to failure by default).
#[test]
fn filtered_source_reads_the_filtered_state() {
    use cliffwatch::analysis::{Metric, Source};
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

/// Displacement rules read either estimate by default: the raw value raises at once on a step,
/// the filtered one on a steady creep whose raw epochs are too noisy, and the rule clears only
/// when both are under the clear threshold.
#[test]
fn either_source_fires_on_raw_or_filtered_and_clears_on_both() {
    use cliffwatch::analysis::{Metric, Source};
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
    let epochs: [Epoch; 5] = [
        // neither exceeds at 99 %: 6 − 2.33 < 5 and 5.5 − 2.33·0.4 < 5
        ((6.0, 1.0), (5.5, 0.4), vec![]),
        // the filter does: 6.2 − 0.93 > 5, while the raw 6.5 ± 1 does not
        ((6.5, 1.0), (6.2, 0.4), vec![(Raised, Watch)]),
        // raw below the clear threshold, filtered not: stays open
        ((3.5, 1.0), (4.5, 0.4), vec![]),
        // both below 4: clears
        ((3.0, 1.0), (3.9, 0.4), vec![(Resolved, Watch)]),
        // a step: the raw value raises at once though the filter lags
        ((12.0, 1.0), (6.0, 0.4), vec![(Raised, Watch)]),
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
    use cliffwatch::analysis::rigid_body::{BlockModel, BlockMotion};
    use cliffwatch::analysis::{BlockAnalysis, Metric, Reading, Readings, Source};
    let rule: AlertRule = serde_json::from_str(
        r#"{"level": "warning", "metric": "displacement_mm", "above": 10, "group": "B1"}"#,
    )
    .expect("rule");
    let cfg = AlertConfig::new("kamo", vec![rule]);
    let mut a = analysis_sigma(2, 20.0, 0.1, true, Some("B1"), &[]);
    let mut readings = Readings::default();
    readings.set(
        Metric::DisplacementMm,
        Source::Raw,
        Reading {
            value: Some(12.0),
            sigma: 0.2,
            significant: true,
        },
    );
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
