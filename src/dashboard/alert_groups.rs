//! The site page's alerts grouped the way people think: one row per subject (a block with its
//! member points' alerts, a point outside any block, or the site) with its worst level, the
//! metrics behind it in words, and when and on which epoch it was first raised (the raising
//! epoch, not the latest one); the row expands (`<details>`) to the single alerts, each with its
//! acknowledgement form ([`super::acknowledge::alert_row`]).
//!
//! The grouping is the service's ([`crate::service::incidents::group`]); [`table`] renders.

use maud::{html, Markup};

use super::acknowledge::{alert_row, incident_form};
use super::layout::{level_badge, metric_name, seg, Viewer};
use super::local_time::when;
use crate::service::incidents::{Subject, SubjectAlerts};
use crate::store::alerts::Alert;
use cliffwatch_core::analysis::AlertStatus;

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
pub fn table(
    rows: &[SubjectAlerts<'_>],
    v: &Viewer,
    site: &str,
    site_href: &str,
    tz: Option<&str>,
) -> Markup {
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
                    @let open = r.alerts.iter().filter(|a| a.state == AlertStatus::Open).count();
                    @if open > 0 && v.can_acknowledge {
                        tr.incident-ack {
                            td colspan="5" { (incident_form(site, &r.subject.key(), open, v)) }
                        }
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
