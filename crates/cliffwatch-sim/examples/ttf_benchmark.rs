//! The time-to-failure benchmark on realistic kinematics ([`cliffwatch_sim::kinematics`]):
//! cliffwatch's alarm against the oracle (the true model and noise, the same rule on its upper
//! bound) and a plain inverse-velocity baseline on the same series. Prints the tables of
//! `docs/accuracy.md`.
//!
//! `cargo run --release -p cliffwatch-sim --example ttf_benchmark [-- SEEDS [FIRST]]` (default 40 seeds per kind
//! from 0: 200 series). For the trade-off table, the time-to-failure settings from the
//! environment: `TTF_CONFIRM_HOURS` (hours a forecast must converge over, 0 for none),
//! `TTF_BOTH_WAYS` (1: the earlier and current failure times agree both ways, 0: one way),
//! `TTF_SPREAD` (1: the spread of the confirmation's failure times in σ, 0: not),
//! `TTF_BACKWARD` (1: withheld when the motion went backward within the window),
//! `TTF_SLOWING` (1: withheld when it slowed), `TTF_CYCLE` (margin: withheld when creep plus a
//! cycle fits within it of the law; `off` for none),
//! `TTF_POOL_RADIUS` (m, 0: no pooling of undeclared targets), `TTF_METHOD` (`onset_law`, `displacement` or `smoothed_velocity`), `TTF_KINDS` (comma-separated
//! kinds, e.g. `failing,burst`), and of the time-to-failure rule `TTF_CONFIDENCE` and
//! `TTF_FOR_EPOCHS`; the windows `TTF_WINDOW`, `TTF_LAW_WINDOW`, `TTF_ACCELERATION_WINDOW`
//! (`N` epochs or `Dd` days), `TTF_BIN_HOURS` (`FailureConfig::forecast_bin_hours`) and
//! `TTF_FILTER_EPOCHS` (`AnalysisConfig::filter_epochs`); kinds `failing_hourly` and
//! `burst_hourly` are sampled hourly, or every `TTF_SPACING_HOURS`; `TTF_SERIES=1` adds the
//! failing series one by one;
//! `TTF_UNDECLARED=1` runs the series with the block not declared (`ttf_undeclared`), each
//! target's σ scaled by `TTF_TARGET_SIGMA`.

use cliffwatch_core::analysis::{AnalysisConfig, FailureConfig, Window};
use cliffwatch_sim::kinematics::{case_sampled, MotionKind};
use cliffwatch_sim::ttf_benchmark::{
    false_alarm_table, rules_with, run_cases_in, series_table, table,
};
use cliffwatch_sim::ttf_undeclared::{run_undeclared_kinds, undeclared_table};

fn main() {
    let mut args = std::env::args().skip(1);
    let seeds: u64 = args.next().and_then(|s| s.parse().ok()).unwrap_or(40);
    let first: u64 = args.next().and_then(|s| s.parse().ok()).unwrap_or(0);
    let mut failure = FailureConfig::default();
    if let Some(h) = std::env::var("TTF_CONFIRM_HOURS")
        .ok()
        .and_then(|h| h.parse().ok())
    {
        failure.confirm_hours = h;
    }
    if let Ok(b) = std::env::var("TTF_BOTH_WAYS") {
        failure.confirm_both_ways = b == "1";
    }
    if let Ok(m) = std::env::var("TTF_METHOD") {
        match serde_json::from_value(serde_json::Value::String(m.clone())) {
            Ok(method) => failure.method = method,
            Err(e) => {
                eprintln!("TTF_METHOD {m:?}: {e}");
                std::process::exit(2);
            }
        }
    }
    if let Ok(b) = std::env::var("TTF_SPREAD") {
        failure.confirm_spread = b == "1";
    }
    if let Ok(b) = std::env::var("TTF_BACKWARD") {
        failure.refuse_backward = b == "1";
    }
    if let Ok(b) = std::env::var("TTF_SLOWING") {
        failure.refuse_slowing = b == "1";
    }
    if let Ok(m) = std::env::var("TTF_CYCLE") {
        failure.cycle_margin = m.parse().ok();
    }
    if let Some(r) = std::env::var("TTF_POOL_RADIUS")
        .ok()
        .and_then(|r| r.parse().ok())
    {
        failure.pool_radius_m = r;
    }
    // Windows: `N` epochs or `Dd` days.
    let window = |name: &str| -> Option<Window> {
        let v = std::env::var(name).ok()?;
        match v.strip_suffix('d') {
            Some(d) => d.parse().ok().map(Window::Days),
            None => v.parse().ok().map(Window::Epochs),
        }
    };
    if let Some(w) = window("TTF_WINDOW") {
        failure.window = w;
    }
    if let Some(w) = window("TTF_LAW_WINDOW") {
        failure.law_window = w;
    }
    if let Some(w) = window("TTF_ACCELERATION_WINDOW") {
        failure.acceleration_window = w;
    }
    if let Some(h) = std::env::var("TTF_BIN_HOURS")
        .ok()
        .and_then(|h| h.parse().ok())
    {
        failure.forecast_bin_hours = h;
    }
    let mut base = AnalysisConfig {
        failure: failure.clone(),
        ..AnalysisConfig::default()
    };
    if let Some(n) = std::env::var("TTF_FILTER_EPOCHS")
        .ok()
        .and_then(|n| n.parse().ok())
    {
        base.filter_epochs = n;
    }
    let kinds: Vec<MotionKind> = match std::env::var("TTF_KINDS") {
        Ok(names) => names
            .split(',')
            .filter_map(|n| MotionKind::EVERY.into_iter().find(|k| k.name() == n.trim()))
            .collect(),
        Err(_) => MotionKind::ALL.to_vec(),
    };
    let number = |name: &str| std::env::var(name).ok().and_then(|v| v.parse::<f64>().ok());
    let confidence = number("TTF_CONFIDENCE");
    let for_epochs = number("TTF_FOR_EPOCHS").map(|n| n as u32);
    let rules = rules_with(confidence, for_epochs);
    let started = std::time::Instant::now();
    if std::env::var("TTF_UNDECLARED").is_ok_and(|v| v == "1") {
        let target_sigma = number("TTF_TARGET_SIGMA").unwrap_or(1.0);
        let outcomes = run_undeclared_kinds(first, seeds, &kinds, &failure, &rules, target_sigma);
        if std::env::var_os("TTF_VERBOSE").is_some() {
            for o in &outcomes {
                println!("{o:?}");
            }
        }
        println!(
            "{} series with the block undeclared ({seeds} seeds per kind from {first}), {:.1} s\n",
            outcomes.len(),
            started.elapsed().as_secs_f64()
        );
        print!("{}", undeclared_table(&outcomes));
        return;
    }
    // The hourly kinds sampled every `TTF_SPACING_HOURS` instead (1 by default).
    let spacing = number("TTF_SPACING_HOURS").unwrap_or(1.0);
    let cases: Vec<_> = kinds
        .iter()
        .flat_map(|&k| (first..first + seeds).map(move |s| case_sampled(k, s, None, spacing)))
        .collect();
    let outcomes = run_cases_in(&cases, &base, &rules);
    let epochs: usize = cases.iter().map(|c| c.scenario.epochs).sum();
    if std::env::var_os("TTF_VERBOSE").is_some() {
        for o in &outcomes {
            println!("{o:?}");
        }
    }
    println!(
        "{} series ({seeds} seeds per kind from {first}; method {:?}, confirmation over {} h (both ways: {}), \
         rule confidence {confidence:?}, for_epochs {for_epochs:?}; windows {:?} / {:?} / {:?}, \
         bins of {} h, filter over {} epochs), {:.1} s, {:.1} ms per epoch on {} threads\n",
        outcomes.len(),
        failure.method,
        failure.confirm_hours,
        failure.confirm_both_ways,
        failure.window,
        failure.law_window,
        failure.acceleration_window,
        failure.forecast_bin_hours,
        base.filter_epochs,
        started.elapsed().as_secs_f64(),
        1e3 * started.elapsed().as_secs_f64() * rayon::current_num_threads() as f64
            / epochs.max(1) as f64,
        rayon::current_num_threads(),
    );
    print!("{}", table(&outcomes));
    if std::env::var_os("TTF_SERIES").is_some() {
        print!("\n{}", series_table(&outcomes));
        print!("\n{}", false_alarm_table(&outcomes));
    }
}
