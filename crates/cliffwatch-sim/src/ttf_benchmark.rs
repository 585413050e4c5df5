//! The time-to-failure benchmark: series of [`super::kinematics`] analysed as a recompute
//! analyses them ([`analyse_series`]: the stable-point datum, the block declared as a group, the
//! rules replayed epoch by epoch), scored against the truth, beside a plain inverse-velocity
//! baseline on the same series (Fukuzono 1985 on the block's raw displacement along its
//! direction: daily velocities, a 7-epoch moving average, Carlà et al. 2017's long-term window,
//! and a straight line through the last 7 smoothed inverse velocities).
//!
//! `cargo run --release -p cliffwatch-sim --example ttf_benchmark [-- SEEDS]` prints the table of
//! `docs/accuracy.md`; `crates/cliffwatch-core/tests/analysis/ttf.rs` asserts the goals on a few seeds per kind.

use chrono::{DateTime, Utc};

use super::kinematics::{case, MotionCase, MotionKind};
use super::ttf_bound::oracle_alarm_lead_hours;
use cliffwatch_core::analysis::{
    analyse_series, AlertConfig, AlertEventType, AlertKind, AlertLevel, AlertRule, AnalysisConfig,
    DisplacementRecord, FailureConfig, GroupConfig, GroupKind,
};

/// Hours to failure below which the alarm rule fires.
pub const ALARM_BELOW_HOURS: f64 = 96.0;
/// The block's group name.
pub const GROUP: &str = "block";

/// The rules of the issue's field case: watch d > 5 mm (clear below 4), warning d > 15 mm,
/// warning v > 1 mm/day, alarm time to failure < 96 h.
pub fn rules() -> Vec<AlertRule> {
    serde_json::from_str(
        r#"[
        {"level": "watch",   "metric": "displacement_mm",       "above": 5.0, "clear_below": 4.0},
        {"level": "warning", "metric": "displacement_mm",       "above": 15.0},
        {"level": "warning", "metric": "velocity_mm_per_day",   "above": 1.0},
        {"level": "alarm",   "metric": "time_to_failure_hours", "below": 96.0}]"#,
    )
    .unwrap_or_default()
}

/// What one series gave.
#[derive(Debug, Clone, PartialEq)]
pub struct Outcome {
    /// The series.
    pub kind: MotionKind,
    /// Its seed.
    pub seed: u64,
    /// Its scatter (× the block's σ along its direction).
    pub scatter: f64,
    /// cliffwatch's first time-to-failure alarm on the block or one of its targets: hours before
    /// the failure (failing series) or days after the first epoch (never-failing ones).
    pub alarm: Option<Alarm>,
    /// Time-to-failure alarms on targets that never fail (still targets; every subject of a
    /// series that never fails).
    pub false_alarms: usize,
    /// The subjects of those false alarms (points `T…`/`B…`, or the block), each once.
    pub false_subjects: Vec<String>,
    /// The baseline's first alarm on the block.
    pub baseline: Option<Alarm>,
    /// The first alarm had the rule read the forecast's point estimate (forecast < 96 h)
    /// instead of its upper bound (forecast + 1.64 σ < 96 h), and the false alarms it would
    /// have raised ([`point_estimate_alarm`]).
    pub point_estimate: (Option<Alarm>, usize),
    /// The oracle: hours before failure of the first epoch at which a forecaster with every
    /// advantage (the true model, direction and noise, its Cramér–Rao σ) has its upper bound
    /// below the rule's 96 h ([`oracle_alarm_lead_hours`]; failing series).
    pub oracle_lead_hours: Option<f64>,
}

/// A first alarm: when, and the forecast then.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Alarm {
    /// Days after the first epoch.
    pub at_days: f64,
    /// Hours from the alarm to the true failure (failing series).
    pub lead_hours: Option<f64>,
    /// The forecast time to failure at the alarm (h).
    pub forecast_hours: f64,
    /// Its σ (h; 0 for the baseline, which has none).
    pub sigma_hours: f64,
}

impl Alarm {
    /// Forecast failure minus true failure (h; negative: forecast early).
    pub fn error_hours(&self) -> Option<f64> {
        self.lead_hours.map(|lead| self.forecast_hours - lead)
    }

    /// Whether the truth lies within ±2σ of the forecast.
    pub fn covered(&self) -> Option<bool> {
        self.error_hours()
            .map(|e| e.abs() <= 2.0 * self.sigma_hours)
    }
}

/// The analysis settings of the benchmark: the defaults with the block declared along its
/// direction.
pub fn config(c: &MotionCase) -> AnalysisConfig {
    config_with(c, &FailureConfig::default())
}

/// [`config`] with the time-to-failure settings `failure`.
pub fn config_with(c: &MotionCase, failure: &FailureConfig) -> AnalysisConfig {
    config_in(
        c,
        &AnalysisConfig {
            failure: failure.clone(),
            ..AnalysisConfig::default()
        },
    )
}

/// The analysis settings `base` with the block declared along its direction.
pub fn config_in(c: &MotionCase, base: &AnalysisConfig) -> AnalysisConfig {
    AnalysisConfig {
        groups: vec![GroupConfig {
            name: GROUP.into(),
            kind: GroupKind::Block,
            direction: Some(c.direction),
            points: vec![],
            process_noise: None,
        }],
        ..base.clone()
    }
}

/// [`rules`] with the time-to-failure rule's `confidence` and `for_epochs` set (None: the
/// defaults), for the trade-off table.
pub fn rules_with(confidence: Option<f64>, for_epochs: Option<u32>) -> Vec<AlertRule> {
    let mut rules = rules();
    for r in &mut rules {
        if r.metric == cliffwatch_core::analysis::alerts::Metric::TimeToFailureHours {
            r.confidence = confidence.or(r.confidence);
            r.for_epochs = for_epochs.or(r.for_epochs);
        }
    }
    rules
}

/// Runs one series through the analysis and the baseline.
pub fn run(c: &MotionCase) -> Outcome {
    run_with(c, &FailureConfig::default(), &rules())
}

/// [`run`] with the time-to-failure settings `failure` and the rules `rules`.
pub fn run_with(c: &MotionCase, failure: &FailureConfig, rules: &[AlertRule]) -> Outcome {
    let base = AnalysisConfig {
        failure: failure.clone(),
        ..AnalysisConfig::default()
    };
    run_in(c, &base, rules)
}

/// [`run`] with the analysis settings `base` (the block declared in them) and the rules `rules`.
pub fn run_in(c: &MotionCase, base: &AnalysisConfig, rules: &[AlertRule]) -> Outcome {
    let series = c.scenario.generate();
    let epochs: Vec<_> = series
        .epochs
        .iter()
        .map(|e| e.coordinates.clone())
        .collect();
    let config = config_in(c, base);
    let alerts = AlertConfig::new("ttf-benchmark", rules.to_vec());
    let out = analyse_series(&epochs[0], &epochs[1..], &series.points, &config, &alerts);
    let days = |t: DateTime<Utc>| (t - series.start).num_milliseconds() as f64 / 86_400_000.0;
    let epoch_days = |epoch: i64| days(epochs[(epoch - 1) as usize].observed_at);
    let moving = |name: &str| name.starts_with('B');
    let lead = |at: f64| c.failure_days.map(|tf| (tf - at) * 24.0);
    let forecast_of = |records: &[DisplacementRecord], who: &str, epoch: i64| {
        records
            .iter()
            .find(|r| r.point == who && r.epoch == epoch)
            .and_then(|r| r.filtered)
            .and_then(|f| {
                f.f_time_to_failure_hours
                    .zip(f.sigma_f_time_to_failure_hours)
            })
    };
    let mut alarm: Option<Alarm> = None;
    let mut false_alarms = 0;
    let mut false_subjects: Vec<String> = vec![];
    for (epoch, ev) in &out.events {
        let a = &ev.alert;
        if a.rule != AlertKind::TimeToFailureHours
            || a.level != AlertLevel::Alarm
            || !matches!(
                ev.event_type,
                AlertEventType::Raised | AlertEventType::Escalated
            )
        {
            continue;
        }
        let (who, records) = match (&a.point, &a.group) {
            (Some(p), _) => (p.as_str(), &out.records),
            (None, Some(g)) => (g.as_str(), &out.block_records),
            _ => continue,
        };
        let on_block = who == GROUP || moving(who);
        if !c.kind.fails() || !on_block {
            false_alarms += 1;
            if !false_subjects.iter().any(|s| s == who) {
                false_subjects.push(who.to_string());
            }
        }
        if !on_block {
            continue;
        }
        let at = epoch_days(*epoch);
        if alarm.is_none_or(|x| at < x.at_days) {
            let (h, s) = forecast_of(records, who, *epoch).unwrap_or((f64::NAN, f64::NAN));
            alarm = Some(Alarm {
                at_days: at,
                lead_hours: lead(at),
                forecast_hours: h,
                sigma_hours: s,
            });
        }
    }
    // The baseline on the block's raw displacement along its direction.
    let block: Vec<(f64, f64)> = out
        .block_records
        .iter()
        .filter_map(|r| Some((epoch_days(r.epoch), r.d_along_mm?)))
        .collect();
    let mut baseline = None;
    for k in 0..block.len() {
        let t: Vec<f64> = block[..=k].iter().map(|b| b.0).collect();
        let d: Vec<f64> = block[..=k].iter().map(|b| b.1).collect();
        if let Some(h) = baseline_forecast(&t, &d).filter(|h| *h < ALARM_BELOW_HOURS) {
            baseline = Some(Alarm {
                at_days: t[k],
                lead_hours: lead(t[k]),
                forecast_hours: h,
                sigma_hours: 0.0,
            });
            break;
        }
    }
    let point_estimate = point_estimate_alarm(&out.records, &out.block_records, |e, t, s| Alarm {
        at_days: epoch_days(e),
        lead_hours: lead(epoch_days(e)),
        forecast_hours: t,
        sigma_hours: s,
    });
    // On a series that never fails the block's alarm is false too.
    let on_block_false = usize::from(!c.kind.fails() && point_estimate.0.is_some());
    let point_estimate = (point_estimate.0, point_estimate.1 + on_block_false);
    Outcome {
        kind: c.kind,
        seed: c.seed,
        scatter: c.scatter,
        alarm,
        false_alarms,
        false_subjects,
        baseline,
        point_estimate,
        oracle_lead_hours: oracle_alarm_lead_hours(c, ALARM_BELOW_HOURS),
    }
}

/// The first time-to-failure alarm on the block (or one of its targets `B…`) had the rule read
/// the filtered forecast's point estimate: the first epoch whose forecast is below
/// [`ALARM_BELOW_HOURS`] (`alarm` makes the [`Alarm`] from the epoch,
/// the forecast and its σ), and the subjects off the block that would have alarmed.
pub fn point_estimate_alarm(
    points: &[DisplacementRecord],
    block: &[DisplacementRecord],
    alarm: impl Fn(i64, f64, f64) -> Alarm,
) -> (Option<Alarm>, usize) {
    let mut first: Option<(i64, f64, f64)> = None;
    let mut off_block = std::collections::BTreeSet::new();
    for r in points.iter().chain(block) {
        let Some((t, s)) = r.filtered.and_then(|f| {
            f.f_time_to_failure_hours
                .zip(f.sigma_f_time_to_failure_hours)
        }) else {
            continue;
        };
        if t.is_nan() || t >= ALARM_BELOW_HOURS {
            continue;
        }
        if r.point == GROUP || r.point.starts_with('B') {
            if first.is_none_or(|f| r.epoch < f.0) {
                first = Some((r.epoch, t, s));
            }
        } else {
            off_block.insert(r.point.clone());
        }
    }
    (first.map(|(e, t, s)| alarm(e, t, s)), off_block.len())
}

/// Epochs of the baseline's moving average of velocities (Carlà et al. 2017's long-term
/// window; their short-term one, 3, alarms on every scattering series).
pub const BASELINE_SMOOTHING: usize = 7;
/// Smoothed inverse velocities the baseline's line goes through.
pub const BASELINE_LINE: usize = 7;

/// The plain inverse-velocity forecast at the last of `t_days` (days, oldest first) from the
/// displacements `d_mm`: velocities between consecutive epochs, a moving average over
/// [`BASELINE_SMOOTHING`] of them, the least-squares line through the last [`BASELINE_LINE`]
/// inverse velocities and its zero; hours from the last epoch, None while the line does not fall
/// or fewer than 5 of the velocities are positive.
pub fn baseline_forecast(t_days: &[f64], d_mm: &[f64]) -> Option<f64> {
    let n = t_days.len();
    if n < BASELINE_SMOOTHING + BASELINE_LINE {
        return None;
    }
    let v: Vec<(f64, f64)> = (1..n)
        .map(|k| {
            let dt = t_days[k] - t_days[k - 1];
            (
                0.5 * (t_days[k] + t_days[k - 1]),
                (d_mm[k] - d_mm[k - 1]) / dt,
            )
        })
        .collect();
    let sma: Vec<(f64, f64)> = v
        .windows(BASELINE_SMOOTHING)
        .map(|w| {
            let m = w.len() as f64;
            (
                w.iter().map(|x| x.0).sum::<f64>() / m,
                w.iter().map(|x| x.1).sum::<f64>() / m,
            )
        })
        .collect();
    let last = &sma[sma.len().saturating_sub(BASELINE_LINE)..];
    let pts: Vec<(f64, f64)> = last
        .iter()
        .filter(|x| x.1 > 0.0)
        .map(|x| (x.0, 1.0 / x.1))
        .collect();
    if pts.len() < 5 {
        return None;
    }
    let m = pts.len() as f64;
    let tm = pts.iter().map(|p| p.0).sum::<f64>() / m;
    let ym = pts.iter().map(|p| p.1).sum::<f64>() / m;
    let stt: f64 = pts.iter().map(|p| (p.0 - tm).powi(2)).sum();
    let sty: f64 = pts.iter().map(|p| (p.0 - tm) * (p.1 - ym)).sum();
    let b = sty / stt;
    if b.is_nan() || b >= 0.0 {
        return None;
    }
    let tf = tm - ym / b;
    Some(((tf - t_days[n - 1]) * 24.0).max(0.0))
}

/// Runs `seeds` series of every kind (seeds `first..first + seeds`), in parallel.
pub fn run_all(first: u64, seeds: u64) -> Vec<Outcome> {
    run_kinds(
        first,
        seeds,
        &MotionKind::ALL,
        &FailureConfig::default(),
        &rules(),
    )
}

/// Runs `seeds` series of each of `kinds` (seeds `first..first + seeds`) with the
/// time-to-failure settings `failure` and the rules `rules`, in parallel.
pub fn run_kinds(
    first: u64,
    seeds: u64,
    kinds: &[MotionKind],
    failure: &FailureConfig,
    rules: &[AlertRule],
) -> Vec<Outcome> {
    let base = AnalysisConfig {
        failure: failure.clone(),
        ..AnalysisConfig::default()
    };
    run_kinds_in(first, seeds, kinds, &base, rules)
}

/// [`run_kinds`] with the analysis settings `base`.
pub fn run_kinds_in(
    first: u64,
    seeds: u64,
    kinds: &[MotionKind],
    base: &AnalysisConfig,
    rules: &[AlertRule],
) -> Vec<Outcome> {
    let cases: Vec<MotionCase> = kinds
        .iter()
        .flat_map(|&k| (first..first + seeds).map(move |s| case(k, s)))
        .collect();
    run_cases_in(&cases, base, rules)
}

/// Every case of `cases` run in parallel with the analysis settings `base`.
pub fn run_cases_in(
    cases: &[MotionCase],
    base: &AnalysisConfig,
    rules: &[AlertRule],
) -> Vec<Outcome> {
    use rayon::prelude::*;
    cases.par_iter().map(|c| run_in(c, base, rules)).collect()
}

/// The benchmark's figures for one forecaster (cliffwatch or the baseline).
#[derive(Debug, Clone, PartialEq)]
pub struct Scores {
    /// Failing series.
    pub failing: usize,
    /// Failing series with an alarm.
    pub alarmed: usize,
    /// Hours before failure of the first alarms: median and the worst (earliest and latest).
    pub lead_median: f64,
    /// Earliest first alarm (most hours before failure).
    pub lead_earliest: f64,
    /// Latest first alarm (fewest hours; negative: after the failure time).
    pub lead_latest: f64,
    /// Failing series whose first alarm came 24–120 h before failure.
    pub in_window: usize,
    /// Never-failing series with an alarm, per kind.
    pub false_by_kind: Vec<(MotionKind, usize, usize)>,
    /// Median |forecast error| at the alarm (h).
    pub error_median: f64,
    /// Largest |forecast error| at the alarm (h).
    pub error_worst: f64,
    /// Failing series whose ±2σ interval at the alarm covers the truth (of those alarmed).
    pub covered: usize,
}

fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(|a, b| a.total_cmp(b));
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// Scores the first alarms `pick` chooses (cliffwatch's, the baseline's, or cliffwatch's with the
/// rule reading the point estimate) over `outcomes`; `alarmed_falsely`: whether a series raised a
/// false alarm (cliffwatch: on any subject that never fails, still targets included; the baseline
/// runs on the block alone).
pub fn score(
    outcomes: &[Outcome],
    pick: impl Fn(&Outcome) -> Option<Alarm>,
    alarmed_falsely: impl Fn(&Outcome) -> bool,
) -> Scores {
    let failing: Vec<&Outcome> = outcomes.iter().filter(|o| o.kind.fails()).collect();
    let alarms: Vec<Alarm> = failing.iter().filter_map(|o| pick(o)).collect();
    let leads: Vec<f64> = alarms.iter().filter_map(|a| a.lead_hours).collect();
    let errors: Vec<f64> = alarms
        .iter()
        .filter_map(|a| a.error_hours())
        .filter(|e| e.is_finite())
        .map(f64::abs)
        .collect();
    // The daily kinds always (0/0 when not run), the hourly ones when run.
    let false_by_kind = MotionKind::EVERY
        .iter()
        .filter(|k| !k.fails())
        .filter(|k| !k.hourly() || outcomes.iter().any(|o| o.kind == **k))
        .map(|&k| {
            let of_kind: Vec<&Outcome> = outcomes.iter().filter(|o| o.kind == k).collect();
            let with = of_kind.iter().filter(|o| alarmed_falsely(o)).count();
            (k, with, of_kind.len())
        })
        .collect();
    Scores {
        failing: failing.len(),
        alarmed: alarms.len(),
        lead_median: median(leads.clone()),
        lead_earliest: leads.iter().copied().fold(f64::NAN, f64::max),
        lead_latest: leads.iter().copied().fold(f64::NAN, f64::min),
        in_window: leads.iter().filter(|h| (24.0..=120.0).contains(*h)).count(),
        false_by_kind,
        error_median: median(errors.clone()),
        error_worst: errors.iter().copied().fold(f64::NAN, f64::max),
        covered: alarms.iter().filter(|a| a.covered() == Some(true)).count(),
    }
}

/// Failing series whose first cliffwatch alarm came no earlier than the baseline's (or where
/// the baseline never alarmed and cliffwatch did; or neither did), of the failing series.
pub fn not_earlier_than_baseline(outcomes: &[Outcome]) -> (usize, usize) {
    let failing: Vec<&Outcome> = outcomes.iter().filter(|o| o.kind.fails()).collect();
    let ok = failing
        .iter()
        .filter(|o| match (o.alarm, o.baseline) {
            (Some(a), Some(b)) => a.at_days >= b.at_days - 1e-9,
            (_, None) | (None, _) => true,
        })
        .count();
    (ok, failing.len())
}

/// The Markdown table of `docs/accuracy.md`.
pub fn table(outcomes: &[Outcome]) -> String {
    let ours = score(outcomes, |o| o.alarm, |o| o.false_alarms > 0);
    let point = score(outcomes, |o| o.point_estimate.0, |o| o.point_estimate.1 > 0);
    let base = score(outcomes, |o| o.baseline, |o| o.baseline.is_some());
    let mut s = String::new();
    let kinds: Vec<&str> = ours.false_by_kind.iter().map(|k| k.0.name()).collect();
    s.push_str(&format!("| forecaster | failing series alarmed | first alarm, h before failure: median (earliest, latest) | 24–120 h before | never-failing series with an alarm ({}) | forecast error at the alarm: median / worst (h) | truth within ±2σ at the alarm |\n", kinds.join(", ")));
    s.push_str("|---|---|---|---|---|---|---|\n");
    for (name, sc) in [
        ("cliffwatch", &ours),
        ("cliffwatch, rule reading the point estimate", &point),
        ("plain inverse velocity", &base),
    ] {
        let falses: Vec<String> = sc
            .false_by_kind
            .iter()
            .map(|(_, with, of)| format!("{with}/{of}"))
            .collect();
        let cover = if name.starts_with("cliffwatch") {
            format!("{}/{}", sc.covered, sc.alarmed)
        } else {
            "— (no σ)".into()
        };
        s.push_str(&format!(
            "| {name} | {}/{} | {:.0} ({:.0}, {:.0}) | {}/{} | {} | {:.0} / {:.0} | {cover} |\n",
            sc.alarmed,
            sc.failing,
            sc.lead_median,
            sc.lead_earliest,
            sc.lead_latest,
            sc.in_window,
            sc.failing,
            falses.join(", "),
            sc.error_median,
            sc.error_worst,
        ));
    }
    let (ok, n) = not_earlier_than_baseline(outcomes);
    s.push_str(&format!(
        "\ncliffwatch's first alarm no earlier than the baseline's: {ok}/{n} failing series.\n"
    ));
    let oracle = oracle_in_window(outcomes);
    s.push_str(&format!(
        "The oracle (true model, direction and noise; the same rule on its upper bound) alarms \
         24–120 h before failure in {}/{} failing series; cliffwatch alarms in that window in {} of \
         them ({}).\n",
        oracle.oracle,
        oracle.failing,
        oracle.both,
        ratio(oracle.both, oracle.oracle),
    ));
    s
}

/// "83 %", or "—" of nothing.
fn ratio(part: usize, of: usize) -> String {
    if of == 0 {
        "—".into()
    } else {
        format!("{:.0} %", 100.0 * part as f64 / of as f64)
    }
}

/// The failing series beside the oracle: how many there are, in how many the oracle's first
/// alarm comes 24–120 h before failure, and in how many of those cliffwatch's does too.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct OracleScore {
    /// Failing series.
    pub failing: usize,
    /// Failing series whose oracle alarms 24–120 h before failure.
    pub oracle: usize,
    /// Of those, the series whose first cliffwatch alarm came 24–120 h before failure.
    pub both: usize,
}

/// [`OracleScore`] of `outcomes`.
pub fn oracle_in_window(outcomes: &[Outcome]) -> OracleScore {
    let in_window = |h: Option<f64>| h.is_some_and(|h| (24.0..=120.0).contains(&h));
    let failing: Vec<&Outcome> = outcomes.iter().filter(|o| o.kind.fails()).collect();
    let oracle: Vec<&&Outcome> = failing
        .iter()
        .filter(|o| in_window(o.oracle_lead_hours))
        .collect();
    OracleScore {
        failing: failing.len(),
        oracle: oracle.len(),
        both: oracle
            .iter()
            .filter(|o| in_window(o.alarm.and_then(|a| a.lead_hours)))
            .count(),
    }
}

/// The failing series one by one (Markdown): seed, scatter, the oracle's first alarm and
/// cliffwatch's (hours before failure), cliffwatch's forecast then with its σ, and the
/// baseline's first alarm.
pub fn series_table(outcomes: &[Outcome]) -> String {
    let hours = |h: Option<f64>| h.map_or("—".into(), |h| format!("{h:.0}"));
    let mut s = String::from(
        "| seed | scatter (× σ) | oracle's first alarm (h before failure) | cliffwatch's | its forecast ± σ (h) | baseline's |\n|---|---|---|---|---|---|\n",
    );
    for o in outcomes.iter().filter(|o| o.kind.fails()) {
        let forecast = o.alarm.map_or("—".into(), |a| {
            format!("{:.0} ± {:.0}", a.forecast_hours, a.sigma_hours)
        });
        s.push_str(&format!(
            "| {} | {:.1} | {} | {} | {forecast} | {} |\n",
            o.seed,
            o.scatter,
            hours(o.oracle_lead_hours),
            hours(o.alarm.and_then(|a| a.lead_hours)),
            hours(o.baseline.and_then(|a| a.lead_hours)),
        ));
    }
    s
}

/// The never-failing series with a time-to-failure alarm one by one (Markdown): kind, seed,
/// scatter, the first alarm (days after the first epoch) with its forecast ± σ (h), and the
/// subjects that alarmed.
pub fn false_alarm_table(outcomes: &[Outcome]) -> String {
    let mut s = String::from(
        "| kind | seed | scatter (× σ) | first alarm (day) | its forecast ± σ (h) | subjects |\n|---|---|---|---|---|---|\n",
    );
    for o in outcomes
        .iter()
        .filter(|o| !o.kind.fails() && o.false_alarms > 0)
    {
        let (at, forecast) = o.alarm.map_or(("—".into(), "—".into()), |a| {
            (
                format!("{:.0}", a.at_days),
                format!("{:.0} ± {:.0}", a.forecast_hours, a.sigma_hours),
            )
        });
        s.push_str(&format!(
            "| {} | {} | {:.1} | {at} | {forecast} | {} |\n",
            o.kind.name(),
            o.seed,
            o.scatter,
            o.false_subjects.join(", "),
        ));
    }
    s
}
