//! The closest simulated case of issue 75's real failure kept aside: daily epochs of the
//! long-range cliff through the image pipeline (cameras set up again each epoch, c drifting,
//! 0.25 px), a declared 6-target block creeping and then accelerating to failure, the series
//! ending 96 h before the failure, the rule "alarm when time to failure < 96 h". Prints the
//! first time-to-failure alarm, the block's forecast at the last epochs, and the alerts of the
//! other targets.
//!
//! `cargo run --release -p cliffwatch-sim --example field_case [-- SEEDS]`

use chrono::{DateTime, Duration, Utc};

use cliffwatch_core::analysis::{
    analyse_series, AlertConfig, AlertEventType, AlertKind, AlertLevel, AnalysisConfig,
    EpochCoordinates, GroupConfig, GroupKind, PointRole,
};
use cliffwatch_core::photogrammetry::{adjust, AdjustOptions};
use cliffwatch_sim::monitoring::FailureLaw;
use cliffwatch_sim::series::{image_series, ImageSeriesScenario};
use cliffwatch_sim::ttf_benchmark::rules;

/// Daily epochs (the last 4 days before the failure).
const EPOCHS: usize = 92;

fn main() {
    let seeds: u64 = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(3);
    for seed in 1..=seeds {
        run(seed);
    }
}

/// One series: adjusted epoch by epoch, analysed with the block declared, the alarms printed.
fn run(seed: u64) {
    let last_day = (EPOCHS - 1) as f64;
    let sc = ImageSeriesScenario {
        seed,
        epochs: EPOCHS,
        interval_hours: 24.0,
        block_points: 6,
        law: FailureLaw {
            creep_mm_per_day: 1.2,
            acceleration_start_days: Some(last_day - 16.0),
            failure_days: last_day + 4.0,
        },
        ..ImageSeriesScenario::default()
    };
    let Ok(series) = image_series(&sc) else {
        eprintln!("seed {seed}: no series");
        return;
    };
    let points = series.truth.point_configs(Some("block"), None);
    let mut options = AdjustOptions {
        joint_covariance_of: points
            .iter()
            .filter(|p| p.role == PointRole::Stable || p.group.is_some())
            .map(|p| p.name.clone())
            .collect(),
        ..AdjustOptions::default()
    };
    let mut epochs = vec![];
    for (k, epoch) in series.epochs.iter().enumerate() {
        let Ok(adj) = adjust(epoch, &options) else {
            eprintln!("seed {seed}: epoch {} not adjusted", k + 1);
            return;
        };
        options.prior = adj.points.iter().map(|p| (p.name.clone(), p.xyz)).collect();
        epochs.push(EpochCoordinates::from_adjustment(
            k as i64 + 1,
            series.truth.epochs[k].observed_at,
            &adj,
        ));
    }
    let config = AnalysisConfig {
        groups: vec![GroupConfig {
            name: "block".into(),
            kind: GroupKind::Block,
            direction: None,
            points: vec![],
            process_noise: None,
        }],
        ..AnalysisConfig::default()
    };
    let alerts = AlertConfig::new("field", rules());
    let out = analyse_series(&epochs[0], &epochs[1..], &points, &config, &alerts);
    let failure: DateTime<Utc> = sc.start + Duration::hours((sc.law.failure_days * 24.0) as i64);
    let hours_before = |epoch: i64| {
        let at = epochs[(epoch - 1) as usize].observed_at;
        (failure - at).num_minutes() as f64 / 60.0
    };
    let first_ttf = out.events.iter().find(|(_, e)| {
        e.alert.rule == AlertKind::TimeToFailureHours
            && e.alert.level == AlertLevel::Alarm
            && e.event_type == AlertEventType::Raised
    });
    println!(
        "seed {seed}: first time-to-failure alarm {:?} h before failure on {:?}",
        first_ttf.map(|(e, _)| hours_before(*e)),
        first_ttf.map(|(_, e)| e.alert.point.clone().or(e.alert.group.clone()))
    );
    for r in out.block_records.iter().rev().take(4).rev() {
        let f = r.filtered.and_then(|f| {
            f.f_time_to_failure_hours
                .zip(f.sigma_f_time_to_failure_hours)
        });
        println!(
            "  epoch {} ({:.0} h before failure): block forecast {:?}",
            r.epoch,
            hours_before(r.epoch),
            f.map(|(h, s)| format!("{h:.0} ± {s:.0} h"))
        );
    }
    let off_block: Vec<String> = out
        .events
        .iter()
        .filter(|(_, e)| e.event_type == AlertEventType::Raised)
        .filter_map(|(_, e)| e.alert.point.clone())
        .filter(|p| points.iter().any(|c| &c.name == p && c.group.is_none()))
        .collect();
    println!("  alerts raised on targets off the block: {off_block:?}");
}
