//! The alert state machine: contract rule JSON, raise/escalate/de-escalate/resolve, hysteresis,
//! quiet epochs, significance, groups, acknowledgement, manual resolution, site-level alerts.
//!
//! The state-machine tests use σ = 0.1 mm, so that a value 0.25 mm past a threshold exceeds it at
//! 99 % (z = 2.33).

use chrono::Duration;

use cliffwatch_core::analysis::{
    acknowledge, analysis_failed, check_overdue, evaluate_alerts, reconcile, resolve, AlertConfig,
    AlertEventType, AlertKind, AlertLevel, AlertRule, AlertState, AlertStatus, AnalysisError,
    DatumMethod, EpochAnalysis, REFERENCE_INDEPENDENT,
};

use super::alert_fixtures::*;

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
    // (no filtered state here: the raw exceedance is confirmed by the next epoch)
    let (ev, _) = feed(&cfg, &[(6.0, false), (6.0, false)]);
    assert!(ev[0].is_empty(), "{ev:?}");
    assert_eq!(ev[1], vec![(AlertEventType::Raised, AlertLevel::Watch)]);
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
    let (r, ev) = reconcile(&st, &same, now, "the reference was set to epoch 2", &[]);
    assert!(ev.is_empty(), "{ev:?}");
    let a = r.find(Some("T1"), AlertKind::DisplacementMm).expect("kept");
    assert_eq!(a.id, id);
    assert_eq!(a.status, AlertStatus::Acknowledged);
    assert_eq!(a.acknowledged_by.as_deref(), Some("geologist"));
    assert_eq!(a.value, Some(6.5));
    assert!(r.find(None, AlertKind::CampaignOverdue).is_some());

    // Replayed at warning: one escalation, same id, open again.
    let (_, higher) = feed(&cfg, &[(11.0, true)]);
    let (r, ev) = reconcile(&st, &higher, now, "the reference was set to epoch 2", &[]);
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
    let (r, ev) = reconcile(&st, &none, now, "the reference was set to epoch 2", &[]);
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
        &[],
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

/// Kinds the change cannot lower stay as they are: an open alert of a kept kind is neither
/// resolved nor de-escalated by a replay that no longer finds it (or finds it lower), keeps its
/// rules' memory, and a higher replay still escalates it. Velocity and time to failure are kept
/// on a reference move.
#[test]
fn reconcile_keeps_the_kinds_the_change_cannot_lower() {
    use AlertEventType::*;
    assert!(REFERENCE_INDEPENDENT.contains(&AlertKind::VelocityMmPerDay));
    assert!(REFERENCE_INDEPENDENT.contains(&AlertKind::TimeToFailureHours));
    assert!(!REFERENCE_INDEPENDENT.contains(&AlertKind::DisplacementMm));
    let cfg = contract_config();
    let now = t0() + Duration::days(30);
    let kept = [AlertKind::DisplacementMm];
    // Stored: T1 at warning (11 mm).
    let (_, st) = feed(&cfg, &[(11.0, true)]);
    let stored = st.alerts[0].clone();
    assert_eq!(stored.level, AlertLevel::Warning);
    let memories = |s: &AlertState| -> Vec<(String, String)> {
        s.rules
            .iter()
            .filter(|(k, _)| k.starts_with("T1|displacement_mm:"))
            .map(|(k, m)| (k.clone(), format!("{m:?}")))
            .collect()
    };
    assert!(!memories(&st).is_empty());
    for (what, replay) in [("nothing", 1.0), ("lower", 6.0)] {
        let (_, replayed) = feed(&cfg, &[(replay, true)]);
        let (r, ev) = reconcile(
            &st,
            &replayed,
            now,
            "the reference was set to epoch 2",
            &kept,
        );
        assert!(ev.is_empty(), "{what}: {ev:?}");
        let a = r.find(Some("T1"), AlertKind::DisplacementMm).expect(what);
        assert_eq!(a, &stored, "{what}");
        assert_eq!(memories(&r), memories(&st), "{what}");
        // Without the kind kept, the same replay changes it.
        let (_, ev) = reconcile(&st, &replayed, now, "the reference was set to epoch 2", &[]);
        assert_eq!(ev.len(), 1, "{what}");
        assert!(matches!(ev[0].event_type, Resolved | Deescalated), "{what}");
    }
    // A replay at a higher level than stored still escalates a kept kind.
    let (_, low) = feed(&cfg, &[(6.0, true)]);
    let (_, high) = feed(&cfg, &[(11.0, true)]);
    let (r, ev) = reconcile(&low, &high, now, "the reference was set to epoch 2", &kept);
    assert_eq!(ev.len(), 1);
    assert_eq!(ev[0].event_type, Escalated);
    assert_eq!(
        r.find(Some("T1"), AlertKind::DisplacementMm)
            .map(|a| a.level),
        Some(AlertLevel::Warning)
    );
}
