//! `GET /sites/{site}/alerts/{id}`: one alert and its history, oldest first: each event (raised,
//! escalated, acknowledged, de-escalated, resolved) with the time it was processed beside the
//! observation time of the epoch that decided it, its level, value, and who
//! acknowledged with their comment, and for a de-escalation or a resolution by the rules the test
//! that decided it (value ± σ, threshold, confidence), as its webhooks carried them
//! ([`crate::store::alerts::history`]; the API's `GET /api/v1/alerts/{id}/events`). An
//! acknowledgement that a later escalation cleared stays in the history.

use axum::extract::{Path, State};
use axum::response::Html;
use axum::Extension;
use maud::{html, Markup};

use super::acknowledge::incident_form;
use super::layout::{level_badge, metric_name, num, page, seg};
use super::local_time::when;
use super::page::{viewer, PageError};
use crate::http::auth::Access;
use crate::http::AppState;
use crate::service::acknowledge::{MAX_COMMENT_CHARS, MAX_NAME_CHARS};
use crate::service::incidents;
use crate::store::alerts;
use cliffwatch_core::analysis::{AlertStatus, ClearedHow, ClearingTest};

/// The alert page.
pub async fn alert(
    State(state): State<AppState>,
    Path((site_id, id)): Path<(String, String)>,
    access: Option<Extension<Access>>,
) -> Result<Html<String>, PageError> {
    let db = state.store.reader();
    let site = super::page::site_or_404(db, &site_id).await?;
    let Some(a) = alerts::get(db, &id).await?.filter(|a| a.site == site.id) else {
        return Err(PageError::not_found(format!(
            "no alert '{id}' in site '{site_id}'"
        )));
    };
    let history = alerts::history(db, &a.id).await?;
    let tz = site.time_zone.as_deref();
    let s = seg(&site.id);
    let subject = html! {
        @if let Some(p) = &a.point {
            "point " a href={ "/sites/" (s) "/points/" (seg(p)) } { (p) }
        } @else if let Some(g) = &a.group {
            "group " (g) " (" (a.points.join(", ")) ")"
        } @else {
            "site"
        }
    };
    let v = viewer(access.as_deref());
    let headline = super::headline::render(&site, &super::headline::load(&state, &site).await?);
    // The incident the alert belongs to, and how many of its alerts are open.
    let blocks = crate::store::groups::list(db, &site.id).await?;
    let pts = crate::store::points::list(db, &site.id, None, i64::MAX).await?;
    let block_of = incidents::block_of(&blocks, &pts);
    let incident = incidents::subject_of(&a, &block_of);
    let incident_open = alerts::list_active(db, &site.id, incidents::ALERTS_READ)
        .await?
        .into_iter()
        .filter(|(_, x)| {
            x.state == AlertStatus::Open && incidents::subject_of(x, &block_of) == incident
        })
        .count();
    let acknowledge = html! {
        @if v.can_acknowledge && (a.state == AlertStatus::Open || incident_open > 0) {
            section.acknowledge aria-label="acknowledge" {
                h2 { "Acknowledge" }
                @if a.state == AlertStatus::Open {
                    p { "This alert only:" }
                    form.ack method="post" action={ "/dashboard/alerts/" (seg(&a.id)) "/ack" } {
                        input type="hidden" name="csrf" value=[v.csrf.as_deref()];
                        input name="by" placeholder="your name" required maxlength=(MAX_NAME_CHARS);
                        input name="comment" placeholder="comment" maxlength=(MAX_COMMENT_CHARS);
                        button type="submit" { "acknowledge this alert" }
                    }
                }
                @if incident_open > 0 && incident != incidents::Subject::Site {
                    p { "The whole incident (" (incident.words()) "):" }
                    (incident_form(&site.id, &incident.key(), incident_open, &v))
                }
            }
        }
    };
    let body = html! {
        h1 { (level_badge(Some(a.level))) " " (metric_name(&a.rule)) " · " (subject) }
        p.rule { "rule metric " code { (a.rule) } @if let (Some(v), Some(t)) = (a.value, a.threshold) { " · value " (num(Some(v), 2)) " " (a.unit.as_deref().unwrap_or("")) " against " (num(Some(t), 2)) } }
        (headline)
        p { (a.message) }
        p { "state: " (a.state) " · highest level: " (a.peak_level.as_str()) }
        (acknowledge)
        h2 { "History" }
        table.history {
            thead { tr { th { "event" } th { "processed at" } th { "level" } th.num { "value" } th { "epoch" } th { "epoch observed at" } th { "acknowledged by" } th { "comment" } } }
            tbody {
                @for e in &history {
                    tr {
                        td.event { (e.event_type.trim_start_matches("alert.")) }
                        td { (when(&e.timestamp, tz)) }
                        td { (level_badge(Some(e.data.level))) }
                        td.num { (num(e.data.value, 2)) " " (e.data.unit) }
                        td { @if let Some(k) = e.data.epoch { a href={ "/sites/" (s) "/epochs/" (k) } { (k) } } }
                        td.observed { @if let Some(o) = &e.data.observed_at { (when(o, tz)) } }
                        td { (e.data.acknowledged_by.as_deref().unwrap_or("")) }
                        td { @if let Some(c) = &e.data.comment { q { (c) } } }
                    }
                    @if let Some(t) = &e.data.cleared_by {
                        tr.test { td colspan="8" { (clearing_words(t, &e.data.unit)) } }
                    }
                }
            }
        }
    };
    let crumbs = [
        (site.name.clone(), format!("/sites/{s}")),
        (a.id.clone(), format!("/sites/{s}/alerts/{}", seg(&a.id))),
    ];
    let title = format!(
        "{} {} · {}",
        a.level,
        metric_name(&a.rule),
        a.point.as_deref().or(a.group.as_deref()).unwrap_or("site")
    );
    Ok(Html(page(&title, &crumbs, &v, body).into_string()))
}

/// The test that cleared a level, in words: "decided by the warning rule (threshold 10 mm):
/// value 8.21 ± 0.35 mm; 8.21 − 2.33 × 0.35 = 7.40 is not above 10 mm at 99 % confidence for 1
/// epoch". The numbers sit in their own elements (`.value`, `.sigma`, `.threshold`,
/// `.confidence`).
fn clearing_words(t: &ClearingTest, unit: &str) -> Markup {
    let pct = format!("{}", (t.confidence * 1000.0).round() / 10.0);
    let n = t.quiet_epochs;
    let (op, edge, side) = match t.value {
        Some(v) if t.below => ("+", v + t.z * t.sigma, "below"),
        Some(v) => ("−", v - t.z * t.sigma, "above"),
        None => ("", 0.0, ""),
    };
    html! {
        "decided by the " (t.level) " rule"
        @if let Some(th) = t.threshold { " (" (side) " " span.threshold { (th) } " " (unit) ")" }
        ": value "
        @match t.value {
            Some(v) => { span.value { (format!("{v:.2}")) } " ± " span.sigma { (format!("{:.2}", t.sigma)) } " " (unit) }
            None => "none",
        }
        @if !t.significant { " (not significant)" }
        "; "
        @match (t.how, t.value, t.threshold) {
            (ClearedHow::PastClearThreshold, _, _) => {
                "past its clear threshold " (t.clear_threshold.map(|c| c.to_string()).unwrap_or_default()) " " (unit)
                " (hysteresis: no confidence needed; the rule's is " span.confidence { (pct) } " %)"
            }
            (ClearedHow::NotExceeded, Some(v), Some(th)) => {
                (format!("{v:.2} {op} {:.2} × {:.2} = {edge:.2}", t.z, t.sigma))
                " is not " (side) " " (th) " " (unit) " at " span.confidence { (pct) } " % confidence"
            }
            (ClearedHow::NotSignificant, _, _) => {
                "over the threshold but not significant (confidence " span.confidence { (pct) } " %)"
            }
            _ => { "no value of the metric (confidence " span.confidence { (pct) } " %)" }
        }
        @if n > 0 { " for " (n) " epoch" @if n > 1 { "s" } }
        "."
    }
}
