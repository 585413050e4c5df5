//! The site page's alerts grouped the way people think: one row per subject (a block with its
//! member points' alerts, a point outside any block, or the site) with its worst level, the
//! metrics behind it in words, and when and on which epoch it was first raised (the raising
//! epoch, not the latest one); the row expands (`<details>`) to the single alerts, each with its
//! acknowledgement form ([`super::acknowledge::alert_row`]).
//!
//! [`group`] is pure; [`table`] renders.

use std::collections::HashMap;

use maud::{html, Markup};

use super::acknowledge::alert_row;
use super::layout::{level_badge, metric_name, seg, Viewer};
use super::local_time::when;
use crate::store::alerts::Alert;
use cliffwatch_core::analysis::{AlertLevel, AlertStatus};

/// Whose alerts a row gathers.
#[derive(Debug, Clone, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Subject {
    /// A declared block: its own alerts and its member points'.
    Block(String),
    /// A point that is in no declared block.
    Point(String),
    /// The site's own alerts (reference, schedule, analysis).
    Site,
}

impl Subject {
    /// Its key in the page (`block:B1`, `point:T203`, `site`), for `data-subject`.
    pub fn key(&self) -> String {
        match self {
            Subject::Block(b) => format!("block:{b}"),
            Subject::Point(p) => format!("point:{p}"),
            Subject::Site => "site".into(),
        }
    }
}

/// One row: a subject and its alerts (most severe first).
#[derive(Debug)]
pub struct SubjectAlerts<'a> {
    /// Whose.
    pub subject: Subject,
    /// Its alerts, highest level first, then by metric, then by point.
    pub alerts: Vec<&'a Alert>,
}

impl SubjectAlerts<'_> {
    /// The highest level of its alerts.
    pub fn worst(&self) -> AlertLevel {
        self.alerts
            .iter()
            .map(|a| a.level)
            .max()
            .unwrap_or_default()
    }

    /// The metrics behind it, each once with its highest level, the highest first.
    pub fn metrics(&self) -> Vec<(&str, AlertLevel)> {
        let mut out: Vec<(&str, AlertLevel)> = Vec::new();
        for a in &self.alerts {
            match out.iter_mut().find(|(r, _)| *r == a.rule) {
                Some((_, l)) => *l = (*l).max(a.level),
                None => out.push((a.rule.as_str(), a.level)),
            }
        }
        out.sort_by_key(|m| std::cmp::Reverse(m.1));
        out
    }

    /// The first raised of its alerts: the one whose raising epoch was observed first (then
    /// the one processed first).
    pub fn first_raised(&self) -> Option<&Alert> {
        self.alerts.iter().copied().min_by(|a, b| {
            let at = |x: &Alert| x.raised_observed_at.clone().unwrap_or(x.raised_at.clone());
            (at(a), &a.raised_at).cmp(&(at(b), &b.raised_at))
        })
    }
}

/// The subject of alert `a`, given the declared block of each point in one (`block_of`).
fn subject_of(a: &Alert, block_of: &HashMap<String, String>) -> Subject {
    match (&a.group, &a.point) {
        (Some(g), _) => Subject::Block(g.clone()),
        (None, Some(p)) => match block_of.get(p) {
            Some(b) => Subject::Block(b.clone()),
            None => Subject::Point(p.clone()),
        },
        (None, None) => Subject::Site,
    }
}

/// Groups `alerts` into one row per subject: rows by worst level (highest first), then by the
/// newest first raising, then by subject; `block_of` names the declared block of each point in
/// one.
pub fn group<'a>(
    alerts: &'a [Alert],
    block_of: &HashMap<String, String>,
) -> Vec<SubjectAlerts<'a>> {
    let mut rows: Vec<SubjectAlerts<'a>> = Vec::new();
    for a in alerts {
        let s = subject_of(a, block_of);
        match rows.iter_mut().find(|r| r.subject == s) {
            Some(r) => r.alerts.push(a),
            None => rows.push(SubjectAlerts {
                subject: s,
                alerts: vec![a],
            }),
        }
    }
    for r in &mut rows {
        r.alerts.sort_by(|a, b| {
            (b.level, &a.rule, &a.group, &a.point).cmp(&(a.level, &b.rule, &b.group, &b.point))
        });
    }
    let raised = |r: &SubjectAlerts<'_>| {
        r.first_raised()
            .map(|a| a.raised_observed_at.clone().unwrap_or(a.raised_at.clone()))
            .unwrap_or_default()
    };
    rows.sort_by(|a, b| {
        (b.worst(), raised(b), &a.subject).cmp(&(a.worst(), raised(a), &b.subject))
    });
    rows
}

/// "2 open · 1 acknowledged · 1 resolved": how many of `alerts` are in each state.
fn states(alerts: &[&Alert]) -> String {
    [
        AlertStatus::Open,
        AlertStatus::Acknowledged,
        AlertStatus::Resolved,
    ]
    .iter()
    .filter_map(|s| {
        let n = alerts.iter().filter(|a| a.state == *s).count();
        (n > 0).then(|| format!("{n} {s}"))
    })
    .collect::<Vec<_>>()
    .join(" · ")
}

/// The grouped alert table: per subject a row (worst level, subject, metrics, first raised on
/// which epoch, states) and under it the expandable list of its alerts.
pub fn table(rows: &[SubjectAlerts<'_>], v: &Viewer, site_href: &str, tz: Option<&str>) -> Markup {
    html! {
        table.alerts.grouped {
            thead { tr { th { "level" } th { "subject" } th { "metrics" } th { "raised (epoch)" } th.wide { "state" } } }
            @for r in rows {
                tbody.subject data-subject=(r.subject.key()) {
                    tr.subject {
                        td { (level_badge(Some(r.worst()))) }
                        td.who {
                            @match &r.subject {
                                Subject::Block(b) => {
                                    "block " a href={ (site_href) "/groups/" (seg(b)) } { (b) }
                                }
                                Subject::Point(p) => {
                                    "point " a href={ (site_href) "/points/" (seg(p)) } { (p) }
                                }
                                Subject::Site => "site",
                            }
                        }
                        td.metrics {
                            @for (i, (m, l)) in r.metrics().iter().enumerate() {
                                @if i > 0 { ", " }
                                span.metric { (metric_name(m)) " (" (l) ")" }
                            }
                        }
                        td.raised {
                            @if let Some(a) = r.first_raised() {
                                @match (&a.raised_observed_at, a.raised_epoch) {
                                    (Some(o), Some(e)) => {
                                        (when(o, tz)) " "
                                        a.raising-epoch href={ (site_href) "/epochs/" (e) } { "epoch " (e) }
                                    }
                                    _ => { (when(&a.raised_at, tz)) " (processed)" }
                                }
                            }
                        }
                        td.wide.states { (states(&r.alerts)) }
                    }
                    tr.members {
                        td colspan="5" {
                            details {
                                summary { (r.alerts.len()) " alert" @if r.alerts.len() > 1 { "s" } " behind it" }
                                table.alerts {
                                    thead { tr { th { "level" } th { "subject" } th { "rule" } th { "value" } th.wide { "latest epoch" } th { "state" } th { "acknowledge" } } }
                                    tbody { @for a in &r.alerts { (alert_row(a, v, tz)) } }
                                }
                            }
                        }
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn alert(point: Option<&str>, group: Option<&str>, rule: &str, level: &str, at: &str) -> Alert {
        let mut a = Alert::default();
        a.point = point.map(str::to_string);
        a.group = group.map(str::to_string);
        a.rule = rule.into();
        a.level = level.parse().unwrap();
        a.raised_at = "2026-12-01T20:43:00Z".into();
        a.raised_observed_at = Some(at.into());
        a
    }

    /// A block's own alerts and its members' gather in one row, with the worst level, the
    /// metrics each once and the earliest raising; a point outside blocks keeps its own row.
    #[test]
    fn a_block_and_its_members_make_one_row() {
        let alerts = vec![
            alert(
                Some("T10"),
                None,
                "displacement_mm",
                "watch",
                "2026-11-03T09:00:00Z",
            ),
            alert(
                Some("T11"),
                None,
                "velocity_mm_per_day",
                "warning",
                "2026-11-04T09:00:00Z",
            ),
            alert(
                None,
                Some("B1"),
                "displacement_mm",
                "alarm",
                "2026-11-05T09:00:00Z",
            ),
            alert(
                Some("T20"),
                None,
                "displacement_mm",
                "warning",
                "2026-11-02T09:00:00Z",
            ),
            alert(
                None,
                None,
                "campaign_overdue",
                "watch",
                "2026-11-06T09:00:00Z",
            ),
        ];
        let block_of: HashMap<String, String> = [("T10", "B1"), ("T11", "B1")]
            .map(|(p, b)| (p.into(), b.into()))
            .into();
        let rows = group(&alerts, &block_of);
        let subjects: Vec<Subject> = rows.iter().map(|r| r.subject.clone()).collect();
        assert_eq!(
            subjects,
            [
                Subject::Block("B1".into()),
                Subject::Point("T20".into()),
                Subject::Site
            ]
        );
        let b1 = &rows[0];
        assert_eq!(b1.alerts.len(), 3);
        assert_eq!(b1.worst(), AlertLevel::Alarm);
        assert_eq!(
            b1.metrics(),
            [
                ("displacement_mm", AlertLevel::Alarm),
                ("velocity_mm_per_day", AlertLevel::Warning)
            ]
        );
        assert_eq!(
            b1.first_raised()
                .and_then(|a| a.raised_observed_at.as_deref()),
            Some("2026-11-03T09:00:00Z")
        );
    }
}
