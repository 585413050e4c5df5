//! Displacement analysis and alert evaluation of a 500-point epoch against a 10-year daily history
//! (3650 records per point). Target: ≤ 50 ms per epoch. And the pure part of a full-site recompute
//! (`service::recompute` → `analysis::analyse_series`): 1000 daily epochs × 30 points analysed
//! again against the reference with the rules replayed. Figures in `docs/performance.md`.

use chrono::Duration;
use criterion::{black_box, criterion_group, criterion_main, Criterion};

use cliffwatch_core::analysis::analyse_series;
use cliffwatch_core::analysis::{
    analyse_epoch, evaluate_alerts, AlertConfig, AlertRule, AlertState, AnalysisConfig,
    DisplacementRecord, History,
};
use cliffwatch_sim::monitoring::MonitoringScenario;

/// The contract's four rules.
const RULES: &str = r#"[
    {"level": "watch",   "metric": "displacement_mm",       "above": 5.0, "clear_below": 4.0},
    {"level": "warning", "metric": "displacement_mm",       "above": 10.0},
    {"level": "alarm",   "metric": "velocity_mm_per_day",   "above": 5.0},
    {"level": "alarm",   "metric": "time_to_failure_hours", "below": 48.0}]"#;

fn setup() -> (
    MonitoringScenario,
    cliffwatch_sim::monitoring::MonitoringSeries,
    History,
    AlertConfig,
) {
    let sc = MonitoringScenario {
        seed: 9,
        stable_points: 20,
        block_points: 30,
        other_points: 450,
        epochs: 2,
        interval_hours: 24.0 * 3650.0,
        creep_mm_per_day: 0.002,
        acceleration_start_days: None,
        ..Default::default()
    };
    let series = sc.generate();
    let now = series.epochs[1].coordinates.observed_at;
    let mut history = History::new();
    for p in &series.epochs[1].coordinates.points {
        let recs: Vec<DisplacementRecord> = (1..=3650)
            .rev()
            .map(|k| {
                let d = 0.002 * (3650 - k) as f64 + 0.3;
                DisplacementRecord {
                    point: p.name.clone(),
                    epoch: 3651 - k,
                    observed_at: now - Duration::days(k),
                    dx_mm: d,
                    dy_mm: 0.0,
                    dz_mm: 0.0,
                    d_mm: d,
                    sigma_dx_mm: 0.7,
                    sigma_dy_mm: 1.4,
                    sigma_dz_mm: 0.7,
                    sigma_mm: 0.7,
                    cov_dxdy_mm2: None,
                    cov_dxdz_mm2: None,
                    cov_dydz_mm2: None,
                    d_along_mm: None,
                    significant: false,
                    velocity_mm_per_day: Some(0.002),
                    time_to_failure_hours: None,
                    time_to_failure_sigma_hours: None,
                    filtered: None,
                }
            })
            .collect();
        history.insert(p.name.clone(), recs);
    }
    let rules: Vec<AlertRule> = serde_json::from_str(RULES).expect("rules");
    (sc, series, history, AlertConfig::new("bench", rules))
}

fn bench(c: &mut Criterion) {
    let (_sc, series, history, alerts) = setup();
    let config = AnalysisConfig::default();
    let (reference, current) = (&series.epochs[0].coordinates, &series.epochs[1].coordinates);
    let state = AlertState::default();
    c.bench_function(
        "analyse_epoch+evaluate_alerts 500 points, 10 y daily history",
        |b| {
            b.iter(|| {
                let a = analyse_epoch(
                    reference,
                    current,
                    &series.points,
                    black_box(&history),
                    &config,
                )
                .expect("analysis");
                let (s, ev) = evaluate_alerts(&alerts, &state, &a, a.observed_at);
                black_box((s, ev))
            })
        },
    );
    let no_stable: Vec<_> = series
        .points
        .iter()
        .map(|p| cliffwatch_core::analysis::PointConfig {
            role: cliffwatch_core::analysis::PointRole::Monitored,
            ..p.clone()
        })
        .collect();
    c.bench_function("analyse_epoch 500 points, IWST (no stable points)", |b| {
        b.iter(|| {
            black_box(
                analyse_epoch(reference, current, &no_stable, &history, &config).expect("analysis"),
            )
        })
    });
}

/// The analysis part of a full-site recompute: [`cliffwatch_core::analysis::analyse_series`] (the function
/// `service::recompute::recompute_site` runs on a blocking thread) over 1000 daily epochs of 30 points (8
/// stable, 6 on a creeping block, 16 others), the contract's four rules replayed.
fn bench_recompute(c: &mut Criterion) {
    let sc = MonitoringScenario {
        seed: 11,
        stable_points: 8,
        block_points: 6,
        other_points: 16,
        epochs: 1000,
        interval_hours: 24.0,
        creep_mm_per_day: 0.02,
        acceleration_start_days: None,
        ..Default::default()
    };
    let series = sc.generate();
    let epochs: Vec<_> = series
        .epochs
        .iter()
        .map(|e| e.coordinates.clone())
        .collect();
    let rules: Vec<AlertRule> = serde_json::from_str(RULES).expect("rules");
    let alerts = AlertConfig::new("bench", rules);
    let config = AnalysisConfig::default();
    let mut g = c.benchmark_group("recompute");
    g.sample_size(10);
    g.bench_function("analyse_series 1000 epochs x 30 points", |b| {
        b.iter(|| {
            let out = analyse_series(
                &epochs[0],
                black_box(&epochs),
                &series.points,
                &config,
                &alerts,
            );
            assert_eq!(out.analysed.len(), 1000, "{:?}", out.failures.first());
            black_box(out)
        })
    });
    g.finish();
}

criterion_group!(benches, bench, bench_recompute);
criterion_main!(benches);
