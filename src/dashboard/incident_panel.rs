//! The incident a block or point page is the page of: the links webhooks and Alertmanager
//! carry open it ([`crate::service::incidents::Subject::page`]). A panel under the headline
//! carries the one form that acknowledges all the incident's open alerts, and lists them (open
//! and acknowledged, each linked to its page) in a fold below it; a point inside a declared block points to its block's
//! page instead, where its incident is.

use maud::{html, Markup};

use super::acknowledge::incident_form;
use super::layout::{level_badge, metric_name, seg, Viewer};
use crate::service::incidents::{self, Subject};
use crate::store::{alerts, groups, points, ReadPool, StoreError};
use cliffwatch_core::analysis::AlertStatus;

/// The incident panel of `subject`'s page in `site`, for viewer `v`: nothing when the subject
/// has no open or acknowledged alert.
pub async fn panel(
    db: &ReadPool,
    site: &str,
    subject: &Subject,
    v: &Viewer,
) -> Result<Markup, StoreError> {
    let blocks = groups::list(db, site).await?;
    let pts = points::list(db, site, None, i64::MAX).await?;
    let block_of = incidents::block_of(&blocks, &pts);
    if let Subject::Point(p) = subject {
        if let Some(b) = block_of.get(p) {
            let block = Subject::Block(b.clone());
            return Ok(html! {
                p.incident-of {
                    "Point " (p) " is in block " (b) ": its alerts are acknowledged as the "
                    a href=(block.page(site)) { "incident of block " (b) } "."
                }
            });
        }
    }
    let active: Vec<alerts::Alert> = alerts::list_active(db, site, incidents::ALERTS_READ)
        .await?
        .into_iter()
        .map(|(_, a)| a)
        .filter(|a| incidents::subject_of(a, &block_of) == *subject)
        .collect();
    if active.is_empty() {
        return Ok(html! {});
    }
    let open = active
        .iter()
        .filter(|a| a.state == AlertStatus::Open)
        .count();
    let rows = incidents::group(&active, &block_of);
    let mut metrics: Vec<String> = vec![];
    for (m, _) in rows.iter().flat_map(|r| r.metrics()) {
        let name = metric_name(m).to_string();
        if !metrics.contains(&name) {
            metrics.push(name);
        }
    }
    let s = seg(site);
    Ok(html! {
        section.incident aria-label="incident" data-subject=(subject.key()) {
            h2 { "Incident: " (subject.words()) }
            p {
                (active.len()) " alert" @if active.len() != 1 { "s" } " (" (metrics.join(", ")) "), " (open) " open"
                @if open == 0 { " (all acknowledged)" }
            }
            (incident_form(site, &subject.key(), open, v))
            details.incident-alerts {
                summary { "its " (active.len()) " alert" @if active.len() != 1 { "s" } " one by one" }
                ul {
                    @for r in &rows {
                        @for a in &r.alerts {
                            li {
                                (level_badge(Some(a.level))) " "
                                a href={ "/sites/" (s) "/alerts/" (seg(&a.id)) } {
                                    (metric_name(&a.rule))
                                    @if let Some(p) = &a.point { " · point " (p) }
                                    @else if let Some(g) = &a.group { " · block " (g) }
                                }
                                @if a.state == AlertStatus::Acknowledged {
                                    " (acknowledged"
                                    @if let Some(by) = &a.acknowledged_by { " by " (by) }
                                    ")"
                                }
                            }
                        }
                    }
                }
            }
        }
    })
}
