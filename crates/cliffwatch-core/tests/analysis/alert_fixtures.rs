//! Fixtures of the alert tests: one point's analysis at an epoch (raw value, σ, significance,
//! group, excluded stable points; a filter that agrees with a significant epoch), the contract's
//! rules, and feeding a series through them.
#![allow(dead_code)]

use chrono::{DateTime, Duration, TimeZone, Utc};

use cliffwatch_core::analysis::{
    evaluate_alerts, AlertConfig, AlertEventType, AlertLevel, AlertRule, AlertState, DatumMethod,
    DatumReport, DisplacementRecord, EpochAnalysis, PointAnalysis, PointRole,
};

pub fn t0() -> DateTime<Utc> {
    Utc.with_ymd_and_hms(2026, 11, 1, 9, 0, 0)
        .single()
        .expect("time")
}

pub fn analysis(
    epoch: i64,
    d_mm: f64,
    significant: bool,
    group: Option<&str>,
    excluded: &[&str],
) -> EpochAnalysis {
    analysis_sigma(epoch, d_mm, 0.1, significant, group, excluded)
}

pub fn analysis_sigma(
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
        // The filter agreeing with a significant epoch: the state machine's tests are not about
        // the source.
        filtered: significant.then(|| filtered_along_x(d_mm, sigma_mm)),
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
            pooled_with: vec![],
        }],
        new_points: vec![],
        warnings: vec![],
        blocks: vec![],
    }
}

pub fn contract_config() -> AlertConfig {
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
pub fn feed(
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

/// Feeds (d_mm, σ_mm) epochs (all significant) and returns the event types per epoch.
pub fn feed_sigma(
    cfg: &AlertConfig,
    series: &[(f64, f64)],
) -> Vec<Vec<(AlertEventType, AlertLevel)>> {
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

/// A filtered state of `d` mm along X with σ `s` mm on each axis, still.
pub fn filtered_along_x(d: f64, s: f64) -> cliffwatch_core::analysis::FilteredValues {
    cliffwatch_core::analysis::FilteredValues {
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
