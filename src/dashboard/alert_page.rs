//! `GET /sites/{site}/alerts/{id}`: one alert and its history, oldest first: each event (raised,
//! escalated, acknowledged, de-escalated, resolved) with the time it was processed beside the
//! observation time of the epoch that decided it, its level, value, and who
//! acknowledged with their comment, as its webhooks carried them
//! ([`crate::store::alerts::history`]; the API's `GET /api/v1/alerts/{id}/events`). An
//! acknowledgement that a later escalation cleared stays in the history.

use axum::extract::{Path, State};
use axum::response::Html;
use axum::Extension;
use maud::html;

use super::layout::{level_badge, num, page, seg};
use super::local_time::when;
use super::page::{viewer, PageError};
use crate::http::auth::Access;
use crate::http::AppState;
use crate::store::alerts;

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
    let body = html! {
        h1 { (level_badge(Some(a.level))) " " (a.rule) " · " (subject) }
        (headline)
        p { (a.message) }
        p { "state: " (a.state) " · highest level: " (a.peak_level.as_str()) }
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
                }
            }
        }
    };
    let crumbs = [
        (site.name.clone(), format!("/sites/{s}")),
        (a.id.clone(), format!("/sites/{s}/alerts/{}", seg(&a.id))),
    ];
    Ok(Html(page(&a.id, &crumbs, &v, body).into_string()))
}
