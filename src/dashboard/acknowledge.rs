//! Acknowledging an alert from the site page: a form posts `by` and `comment` to
//! `POST /dashboard/alerts/{id}/ack` (role `upload`, and with a session cookie its CSRF token in
//! `x-csrf-token` or the form's `csrf` field), which acknowledges exactly as the API does. With
//! htmx it answers the alert's new table row; a plain form post (no JavaScript) is redirected to
//! the site page.

use axum::extract::{Path, State};
use axum::http::HeaderMap;
use axum::response::{Html, IntoResponse, Redirect, Response};
use axum::{Extension, Form};
use maud::{html, Markup};
use serde::Deserialize;

use super::layout::{level_badge, metric_name, num, page, seg, Viewer};
use super::local_time::when;
use super::page::viewer;
use crate::http::auth::Access;
use crate::http::AppState;
use crate::service::acknowledge::{MAX_COMMENT_CHARS, MAX_NAME_CHARS};
use crate::store::alerts::Alert;
use cliffwatch_core::analysis::AlertStatus;

/// The acknowledgement form's fields.
#[derive(Debug, Deserialize)]
pub struct AckForm {
    /// Who acknowledges (required, at most [`MAX_NAME_CHARS`] characters).
    pub by: String,
    /// Optional comment (at most [`MAX_COMMENT_CHARS`] characters).
    #[serde(default)]
    pub comment: Option<String>,
}

/// One row of the alert table: level, subject, rule, value, epoch, state, and the
/// acknowledgement form while the alert is open and the viewer may acknowledge.
pub fn alert_row(a: &Alert, v: &Viewer, time_zone: Option<&str>) -> Markup {
    let site = seg(&a.site);
    html! {
        tr id={ "alert-" (a.id) } {
            td { (level_badge(Some(a.level))) }
            td {
                @if let Some(p) = &a.point {
                    a href={ "/sites/" (site) "/points/" (seg(p)) } { (p) }
                } @else if let Some(g) = &a.group {
                    "group " (g) " (" (a.points.join(", ")) ")"
                } @else {
                    "site"
                }
            }
            td { a href={ "/sites/" (site) "/alerts/" (seg(&a.id)) } title="history" { (metric_name(&a.rule)) } }
            td.num { (num(a.value, 2)) " " (a.unit.as_deref().unwrap_or("")) }
            td.wide { @if let Some(e) = a.epoch { a href={ "/sites/" (site) "/epochs/" (e) } { (when(a.observed_at.as_deref().unwrap_or(""), time_zone)) } } }
            td.state {
                (a.state)
                @if let Some(by) = &a.acknowledged_by { " by " (by) }
                @if let Some(c) = &a.ack_comment { ": " q { (c) } }
            }
            td {
                @if a.state == AlertStatus::Open && v.can_acknowledge {
                    form.ack method="post" action={ "/dashboard/alerts/" (seg(&a.id)) "/ack" } hx-post={ "/dashboard/alerts/" (seg(&a.id)) "/ack" } hx-target="closest tr" hx-swap="outerHTML" {
                        input type="hidden" name="csrf" value=[v.csrf.as_deref()];
                        input name="by" placeholder="your name" required maxlength=(MAX_NAME_CHARS);
                        input name="comment" placeholder="comment" maxlength=(MAX_COMMENT_CHARS);
                        button type="submit" { "acknowledge" }
                    }
                }
            }
        }
    }
}

/// `POST /dashboard/alerts/{id}/ack`: acknowledges; answers the new row (htmx) or redirects to
/// the site page (a plain form post).
pub async fn acknowledge(
    State(state): State<AppState>,
    Path(id): Path<String>,
    headers: HeaderMap,
    access: Option<Extension<Access>>,
    Form(form): Form<AckForm>,
) -> Response {
    let ack = crate::service::acknowledge::acknowledge(
        &state.store,
        &id,
        &form.by,
        form.comment.as_deref(),
        state.public_url(),
    );
    match ack.await {
        Ok(alert) => {
            if headers.contains_key("hx-request") {
                let zone = crate::store::sites::get(state.store.reader(), &alert.site)
                    .await
                    .ok()
                    .flatten()
                    .and_then(|s| s.time_zone);
                Html(alert_row(&alert, &viewer(access.as_deref()), zone.as_deref()).into_string())
                    .into_response()
            } else {
                Redirect::to(&format!("/sites/{}", seg(&alert.site))).into_response()
            }
        }
        Err(e) => {
            let e = crate::http::error::ApiError::from(e);
            if headers.contains_key("hx-request") {
                // forms.js shows it beside the form.
                return (e.status, e.message).into_response();
            }
            let body = html! {
                h1 { "Not acknowledged" }
                p.error { (e.message) }
                p { a href="/" { "back to the sites" } }
            };
            let v = viewer(access.as_deref());
            (
                e.status,
                Html(page("Not acknowledged", &[], &v, body).into_string()),
            )
                .into_response()
        }
    }
}

/// The acknowledgement form of a whole incident (`block:B1`, `point:T203`, `site`) of `site`:
/// one action for every open alert of it ([`crate::service::incidents::acknowledge`]).
pub fn incident_form(site: &str, incident: &str, open: usize, v: &Viewer) -> Markup {
    let action = format!(
        "/dashboard/sites/{}/incidents/{}/ack",
        seg(site),
        seg(incident)
    );
    html! {
        @if open > 0 && v.can_acknowledge {
            form.ack.incident method="post" action=(action) {
                input type="hidden" name="csrf" value=[v.csrf.as_deref()];
                input name="by" placeholder="your name" required maxlength=(MAX_NAME_CHARS);
                input name="comment" placeholder="comment" maxlength=(MAX_COMMENT_CHARS);
                button type="submit" {
                    "acknowledge " @if open > 1 { "all " (open) " open alerts" } @else { "the open alert" }
                }
            }
        }
    }
}

/// `POST /dashboard/sites/{site}/incidents/{incident}/ack`: acknowledges every open alert of the
/// incident and redirects to the site page's alerts; a refusal is a page naming why.
pub async fn acknowledge_incident(
    State(state): State<AppState>,
    Path((site, incident)): Path<(String, String)>,
    access: Option<Extension<Access>>,
    Form(form): Form<AckForm>,
) -> Response {
    let ack = crate::service::incidents::acknowledge(
        &state.store,
        &site,
        &incident,
        &form.by,
        form.comment.as_deref(),
        state.public_url(),
    );
    match ack.await {
        Ok(_) => Redirect::to(&format!("/sites/{}#alerts", seg(&site))).into_response(),
        Err(e) => {
            let e = crate::http::error::ApiError::from(e);
            let body = html! {
                h1 { "Not acknowledged" }
                p.error { (e.message) }
                p { a href={ "/sites/" (seg(&site)) } { "back to the site" } }
            };
            let v = viewer(access.as_deref());
            (
                e.status,
                Html(page("Not acknowledged", &[], &v, body).into_string()),
            )
                .into_response()
        }
    }
}
