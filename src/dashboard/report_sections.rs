//! The campaign report's sections as HTML (pure renderers, no I/O): the blocks' motion, the
//! displacement table, the epochs with their adjustment's health, and the alert history with the
//! epoch that raised each alert. The report fits a site of ≤ 30 points on three A4 pages: the
//! tables are compact and the epochs run in columns (`article.report` in `dashboard.css`).

use maud::{html, Markup};

use super::headline::{bound_confidence_words, failure_time};
use super::layout::{level_badge, metric_name, num, seg, time_to_failure, with_sigma};
use super::local_time::{text, when};
use crate::store::alerts::Alert;
use crate::store::displacements::Displacement;
use crate::store::epochs::EpochListItem;
use cliffwatch_core::photogrammetry::statistics::variance_components::PooledSigma;
use cliffwatch_core::photogrammetry::statistics::GlobalTest;

/// One block of the report: its name, member count and latest motion in the period.
pub struct BlockRow {
    /// Block (group) name.
    pub name: String,
    /// Its member points.
    pub members: usize,
    /// Its motion at the period's last epoch with one.
    pub latest: Option<Displacement>,
}

/// "likely before 2027-02-12 18:00 UTC (95 %); expected 02-12 06:00 (±2σ 02-11 20:00 to
/// 02-12 16:00)": the one-sided bound and the forecast failure time, or why there is none.
fn forecast(d: &Displacement, tz: Option<&str>) -> String {
    match failure_time(d) {
        Some(f) => format!(
            "likely before {} ({}); expected {} (±2σ {} to {})",
            text(f.likely_before, tz),
            bound_confidence_words(),
            text(f.at, None).get(5..16).unwrap_or(""),
            text(f.lower, None).get(5..16).unwrap_or(""),
            text(f.upper, None).get(5..16).unwrap_or("")
        ),
        None if d.f_time_to_failure_hours.is_some() => "no forecast yet".into(),
        None => "–".into(),
    }
}

/// The blocks' table: displacement and along its direction ± σ, filtered velocity ± σ, time to
/// failure ± σ (h, from the epoch) and the forecast failure time as a date.
pub fn blocks(site: &str, rows: &[BlockRow], tz: Option<&str>) -> Markup {
    html! {
        table.blocks {
            thead { tr { th { "block" } th { "points" } th { "epoch" } th { "d ± σ (mm)" } th { "along ± σ (mm)" } th { "velocity (mm/day)" } th { "time to failure (h)" } th { "forecast failure" } } }
            tbody { @for b in rows {
                tr {
                    td { a href={ "/sites/" (seg(site)) "/groups/" (seg(&b.name)) } { (b.name) } }
                    td.num { (b.members) }
                    @if let Some(d) = &b.latest {
                        td { (when(&d.observed_at, None)) }
                        td.num { (with_sigma(Some(d.d_mm), Some(d.sigma_mm), 2)) }
                        td.num { (num(d.d_along_mm, 2)) }
                        td.num { (with_sigma(d.f_velocity_mm_per_day, d.sigma_f_velocity_mm_per_day, 3)) }
                        td.num { (time_to_failure(d.f_time_to_failure_hours, d.sigma_f_time_to_failure_hours)) }
                        td { (forecast(d, tz)) }
                    } @else {
                        td colspan="6" { "no motion yet (fewer than 2 measured members)" }
                    }
                }
            } }
        }
    }
}

/// The displacement table at the last epoch: every point, its role, d ± σ, significance, the
/// smallest detectable movement, velocity and time to failure.
pub fn displacements(
    site: &str,
    rows: &[Displacement],
    role: &dyn Fn(&str) -> &'static str,
    mdd: &dyn Fn(&Displacement) -> Option<f64>,
) -> Markup {
    html! {
        table.displacements {
            thead { tr { th { "point" } th { "role" } th { "d ± σ (mm)" } th { "signif." } th title="the smallest movement, in its worst direction, that this epoch detects 80 % of the time at the site's confidence" { "detects ≥ (mm)" } th { "velocity (mm/day)" } th { "time to failure (h)" } } }
            tbody { @for d in rows {
                tr.(if d.significant { "moved" } else { "" }) {
                    td { a href={ "/sites/" (seg(site)) "/points/" (seg(&d.point)) } { (d.point) } }
                    td { (role(&d.point)) }
                    td.num { (with_sigma(Some(d.d_mm), Some(d.sigma_mm), 2)) }
                    td { @if d.significant { "yes" } @else { "no" } }
                    td.num { (num(mdd(d), 2)) }
                    td.num { (with_sigma(d.f_velocity_mm_per_day, d.sigma_f_velocity_mm_per_day, 3)) }
                    td.num { (time_to_failure(d.f_time_to_failure_hours, d.sigma_f_time_to_failure_hours)) }
                }
            } }
        }
    }
}

/// The epochs oldest first, in columns: time, σ0, variance factor and the global test's verdict;
/// above them how many failed it.
pub fn epochs(rows: &[EpochListItem], tz: Option<&str>) -> Markup {
    let tests: Vec<Option<GlobalTest>> = rows
        .iter()
        .map(|e| Some(GlobalTest::of(e.dof?, e.variance_factor?)))
        .collect();
    let failed = tests.iter().flatten().filter(|t| !t.accepted).count();
    let tested = tests.iter().flatten().count();
    html! {
        p.health {
            (tested) " epochs tested: the global test of the adjustment's variance factor "
            @if failed == 0 { "passed on all." } @else { "failed on " strong { (failed) } " (" (num(Some(100.0 * failed as f64 / tested.max(1) as f64), 0)) " %)." }
            " Each line: observed at · σ0 (mm) · variance factor · ✓ passed / ✗ failed."
        }
        ol.epoch-health {
            @for (e, t) in rows.iter().zip(&tests).rev() {
                li.(match t { Some(t) if !t.accepted => "failed", _ => "" }) {
                    (short_time(&e.observed_at, tz)) " · " (num(Some(e.sigma0_mm), 5)) " · "
                    (num(e.variance_factor, 2)) " "
                    @match t { Some(t) if t.accepted => "✓", Some(_) => "✗", None => "–" }
                }
            }
        }
    }
}

/// Which a-priori σ the period's `total` epochs were adjusted with: the uploaded cameras' σ, or
/// on how many the σ estimated from earlier epochs, and the last of those.
pub fn sigma_used(estimated: &[(i64, Vec<PooledSigma>)], total: usize) -> Markup {
    html! {
        p.sigma-used {
            "A-priori σ of the image coordinates: "
            @match estimated.last() {
                None => { "the cameras' σ as uploaded, on every epoch." },
                Some((epoch, used)) => {
                    "estimated from the site's earlier epochs (" code { "apriori_sigma: estimated" } ") on "
                    (estimated.len()) " of " (total) " epochs, the uploaded σ on the others; at epoch " (epoch) ": "
                    @for (i, u) in used.iter().enumerate() {
                        @if i > 0 { ", " }
                        "camera " (u.camera) " " (num(Some(u.sigma_mm * 1000.0), 2)) " µm"
                    }
                    "."
                },
            }
        }
    }
}

/// "2026-11-04 09:00" in UTC (the zone's time is in the page's header).
fn short_time(rfc3339: &str, _tz: Option<&str>) -> String {
    rfc3339
        .get(..16)
        .map_or_else(|| rfc3339.to_string(), |s| s.replace('T', " "))
}

/// One subject's alerts in the period: the point's, or a block's own.
struct SubjectHistory<'a> {
    subject: String,
    alerts: Vec<&'a Alert>,
}

/// The alert history, one row per subject (point or block) as people think of it: the highest
/// level reached, the metrics in words with theirs, the earliest epoch that raised one and when it
/// was observed, and how many are open, acknowledged or resolved. The most severe first.
pub fn history(rows: &[Alert], tz: Option<&str>) -> Markup {
    let mut subjects: Vec<SubjectHistory<'_>> = Vec::new();
    for a in rows {
        let subject = a
            .point
            .clone()
            .or_else(|| a.group.as_ref().map(|g| format!("block {g}")))
            .unwrap_or_else(|| "site".into());
        match subjects.iter_mut().find(|s| s.subject == subject) {
            Some(s) => s.alerts.push(a),
            None => subjects.push(SubjectHistory {
                subject,
                alerts: vec![a],
            }),
        }
    }
    let peak = |s: &SubjectHistory<'_>| s.alerts.iter().map(|a| a.peak_level).max();
    let first = |s: &SubjectHistory<'_>| {
        s.alerts
            .iter()
            .filter_map(|a| Some((a.raised_observed_at.clone()?, a.raised_epoch)))
            .min()
    };
    subjects.sort_by(|a, b| {
        peak(b)
            .cmp(&peak(a))
            .then_with(|| first(a).cmp(&first(b)))
            .then_with(|| super::natural_order::natural_cmp(&a.subject, &b.subject))
    });
    html! {
        table.history {
            thead { tr { th { "highest level" } th { "subject" } th { "metrics (highest level)" } th { "first raised by the epoch of" } th { "alerts" } } }
            tbody { @for s in &subjects {
                tr.subject {
                    td { (level_badge(peak(s))) }
                    td { (s.subject) }
                    td { (metrics(&s.alerts)) }
                    td.raised {
                        @match first(s) {
                            Some((t, Some(e))) => { (when(&t, tz)) " (epoch " (e) ")" },
                            Some((t, None)) => { (when(&t, tz)) },
                            None => { "–" },
                        }
                    }
                    td { (states(&s.alerts)) }
                }
            } }
        }
    }
}

/// "displacement (warning), velocity (watch)": each metric once, with the highest level its
/// alerts reached.
fn metrics(alerts: &[&Alert]) -> String {
    let mut out: Vec<(&str, cliffwatch_core::analysis::AlertLevel)> = Vec::new();
    for a in alerts {
        let name = metric_name(&a.rule);
        match out.iter_mut().find(|(m, _)| *m == name) {
            Some((_, l)) => *l = (*l).max(a.peak_level),
            None => out.push((name, a.peak_level)),
        }
    }
    out.sort_by(|a, b| b.1.cmp(&a.1).then(a.0.cmp(b.0)));
    out.iter()
        .map(|(m, l)| format!("{m} ({l})"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// "2 open, 1 acknowledged by Sato, 3 resolved".
fn states(alerts: &[&Alert]) -> String {
    let mut counts: Vec<(String, usize)> = Vec::new();
    for a in alerts {
        let state = match &a.acknowledged_by {
            Some(by) => format!("{} by {by}", a.state),
            None => a.state.to_string(),
        };
        match counts.iter_mut().find(|(s, _)| *s == state) {
            Some((_, n)) => *n += 1,
            None => counts.push((state, 1)),
        }
    }
    counts
        .iter()
        .map(|(s, n)| format!("{n} {s}"))
        .collect::<Vec<_>>()
        .join(", ")
}
