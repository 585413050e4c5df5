//! One series of the time-to-failure benchmark epoch by epoch: the block's displacement along
//! its direction (mm, raw), its filtered velocity ± σ (mm/day) and acceleration (mm/day²), the
//! forecast time to failure ± σ (h), and the time-to-failure alarms raised, for diagnosing why
//! a series alarms.
//!
//! `cargo run --release -p cliffwatch-sim --example ttf_trace -- KIND SEED` (KIND `failing`,
//! `burst`, `step`, `cyclic`, `creep`, `failing_hourly` or `burst_hourly`); of the benchmark's
//! `TTF_*` settings only `TTF_BIN_HOURS`,
//! `TTF_CONFIRM_HOURS` and `TTF_FILTER_EPOCHS` are read here.

use cliffwatch_core::analysis::{
    analyse_series, AlertConfig, AlertEventType, AlertKind, AlertLevel,
};
use cliffwatch_sim::kinematics::{case, MotionKind};
use cliffwatch_sim::ttf_benchmark::{config, rules, GROUP};

fn main() {
    let mut args = std::env::args().skip(1);
    let kind_name = args.next().unwrap_or_else(|| "cyclic".into());
    let seed: u64 = args.next().and_then(|s| s.parse().ok()).unwrap_or(0);
    let Some(kind) = MotionKind::EVERY
        .into_iter()
        .find(|k| k.name() == kind_name)
    else {
        eprintln!("unknown kind {kind_name:?}");
        std::process::exit(2);
    };
    let c = case(kind, seed);
    println!(
        "{kind_name} seed {seed}: creep {:.2} mm/day, scatter {:.1} × σ ({:.2} mm), failure {:?}, onset {:?}",
        c.creep_mm_per_day, c.scatter, c.scatter_mm, c.failure_days, c.onset_days
    );
    let series = c.scenario.generate();
    let epochs: Vec<_> = series
        .epochs
        .iter()
        .map(|e| e.coordinates.clone())
        .collect();
    let alerts = AlertConfig::new("ttf-trace", rules());
    let mut config = config(&c);
    let number = |name: &str| std::env::var(name).ok().and_then(|v| v.parse::<f64>().ok());
    if let Some(h) = number("TTF_BIN_HOURS") {
        config.failure.forecast_bin_hours = h;
    }
    if let Some(h) = number("TTF_CONFIRM_HOURS") {
        config.failure.confirm_hours = h;
    }
    if let Some(n) = number("TTF_FILTER_EPOCHS") {
        config.filter_epochs = n as usize;
    }
    let out = analyse_series(&epochs[0], &epochs[1..], &series.points, &config, &alerts);
    println!("epoch | d along | v ± σ | a | ttf ± σ");
    for r in out.block_records.iter().filter(|r| r.point == GROUP) {
        let f = r.filtered;
        let v = f.map_or("—".into(), |f| {
            format!(
                "{:6.2} ± {:4.2} | {:6.3}",
                f.f_velocity_mm_per_day,
                f.sigma_f_velocity_mm_per_day,
                f.f_acceleration_mm_per_day2.unwrap_or(f64::NAN)
            )
        });
        let ttf = f
            .and_then(|f| {
                f.f_time_to_failure_hours
                    .zip(f.sigma_f_time_to_failure_hours)
            })
            .map_or("".into(), |(h, s)| format!("{h:7.1} ± {s:6.1}"));
        println!(
            "{:3} | {:7.2} | {v} | {ttf}",
            r.epoch,
            r.d_along_mm.unwrap_or(f64::NAN)
        );
    }
    for (epoch, ev) in &out.events {
        let a = &ev.alert;
        if a.rule == AlertKind::TimeToFailureHours
            && a.level == AlertLevel::Alarm
            && matches!(
                ev.event_type,
                AlertEventType::Raised | AlertEventType::Escalated
            )
        {
            println!("alarm at epoch {epoch}: {:?} {:?}", a.point, a.group);
        }
    }
}
