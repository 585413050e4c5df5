//! Editing a site from its page: a form of its name, time zone and alert rules (the rules as
//! the JSON list of the API's form) posts to `POST /dashboard/sites/{site}/settings` (role
//! `admin`, and with a session cookie its CSRF token in the form's `csrf` field, as the
//! acknowledgement form), which calls the use case of `PATCH /api/v1/sites/{site}`
//! ([`crate::service::site_admin::update_site`]): checked as a new site is, recorded in the
//! audit trail with the source `page`, and a rule change re-evaluates the open alerts at once.
//! Done: back to the site page's changes; refused: a page naming the field at fault. Beside it
//! the retirement form (`POST /dashboard/sites/{site}/retire`, the use case of the API's
//! retirement), and for a retired site the link of its export.

use axum::extract::{Path, State};
use axum::response::{Html, IntoResponse, Redirect, Response};
use axum::{Extension, Form};
use maud::{html, Markup};
use serde::Deserialize;
use serde_json::{json, Value};

use super::layout::{page, seg, Viewer};
use super::page::viewer;
use crate::http::auth::Access;
use crate::http::AppState;
use crate::service::site_lifecycle::MAX_REASON_CHARS;
use crate::service::ServiceError;
use crate::store::sites::Site;

/// The form's fields.
#[derive(Debug, Deserialize)]
pub struct SettingsForm {
    /// Display name.
    pub name: String,
    /// IANA time zone; blank: UTC only.
    #[serde(default)]
    pub time_zone: String,
    /// The alert rules: a JSON list of rule objects.
    pub alert_rules: String,
}

/// The settings section of the site page: the form for a viewer who may administer a site in
/// service (not one of the configuration file), else the rules in words.
pub fn section(site: &Site, v: &Viewer, configured: bool) -> Markup {
    let rules = serde_json::to_string_pretty(&site.alert_rules).unwrap_or_else(|_| "[]".into());
    let action = format!("/dashboard/sites/{}/settings", seg(&site.id));
    html! {
        section #settings {
            h2 { "Settings" }
            @if !v.can_administer || site.retired_at.is_some() || configured {
                p.note {
                    "Alert rules: "
                    @if site.alert_rules.is_empty() { "none." }
                    @for r in &site.alert_rules { br; code { (r.to_string()) } }
                }
                @if configured && v.can_administer {
                    p.note { "This site is defined in the configuration file ([[sites]]): change it there." }
                }
            } @else {
                form.settings method="post" action=(action) {
                    input type="hidden" name="csrf" value=[v.csrf.as_deref()];
                    label { "Name " input name="name" value=(site.name) required maxlength="200"; }
                    label { "Time zone (IANA, e.g. Asia/Tokyo; blank: UTC only) "
                        input name="time_zone" value=[site.time_zone.as_deref()] maxlength="64"; }
                    label for="alert_rules" { "Alert rules (JSON list; each "
                        code { "{\"level\", \"metric\", \"above\"|\"below\", …}" } ")" }
                    textarea #alert_rules name="alert_rules" rows="8" cols="80" spellcheck="false" { (rules) }
                    button type="submit" { "save the settings" }
                    p.note { "Saving re-evaluates the open alerts at once and is recorded in the changes below." }
                }
            }
            @if v.can_administer && !configured { (retirement(site, v)) }
        }
    }
}

/// For an administrator: the retirement form of a site in service, or the export link of a
/// retired one (the deletion needs that export; it stays an API call).
fn retirement(site: &Site, v: &Viewer) -> Markup {
    let s = seg(&site.id);
    html! {
        @if site.retired_at.is_some() {
            p.note {
                a href={ "/api/v1/sites/" (s) "/export" } download { "Download the site's data (JSON)" }
                ": recorded in the changes; once downloaded after the retirement, the site can be deleted ("
                code { "DELETE /api/v1/sites/" (site.id) } ")."
            }
        } @else {
            form.retire method="post" action={ "/dashboard/sites/" (s) "/retire" } {
                input type="hidden" name="csrf" value=[v.csrf.as_deref()];
                label { "Reason " input name="reason" required maxlength=(MAX_REASON_CHARS); }
                button type="submit" { "retire the site" }
                p.note { "Retiring refuses every further epoch and change, and closes each open alert with the reason; the pages stay." }
            }
        }
    }
}

/// The retirement form's field.
#[derive(Debug, Deserialize)]
pub struct RetireForm {
    /// Why the site is retired.
    pub reason: String,
}

/// `POST /dashboard/sites/{site}/retire`: retires the site as `POST /api/v1/sites/{site}/retire`
/// does (audited as `page`); redirects to the site page, or answers a page naming why not.
pub async fn retire(
    State(state): State<AppState>,
    Path(site): Path<String>,
    access: Option<Extension<Access>>,
    Form(form): Form<RetireForm>,
) -> Response {
    let v = viewer(access.as_deref());
    let actor = access.map(|a| a.0).unwrap_or_default().actor("page");
    let outcome = async {
        if state.config.sites.iter().any(|s| s.id == site) {
            return Err(ServiceError::ConfiguredSite(site.clone()));
        }
        crate::service::site_lifecycle::retire_site(
            &state.store,
            &site,
            &form.reason,
            &actor,
            state.public_url(),
        )
        .await
    };
    match outcome.await {
        Ok(_) => Redirect::to(&format!("/sites/{}", seg(&site))).into_response(),
        Err(e) => refused(&site, "Site not retired", e, &v),
    }
}

/// The page of a refused form: the message naming what was wrong, nothing changed.
fn refused(site: &str, title: &str, e: ServiceError, v: &Viewer) -> Response {
    let e = crate::http::error::ApiError::from(e);
    let body = html! {
        h1 { (title) }
        p.error { (e.message) }
        p { "Nothing was changed. " a href={ "/sites/" (seg(site)) "#settings" } { "back to the site" } }
    };
    (e.status, Html(page(title, &[], v, body).into_string())).into_response()
}

/// `POST /dashboard/sites/{site}/settings`: applies the form as a merge patch through the
/// API's use case (audited as `page`); redirects to the site page's changes, or answers a page
/// naming what was refused.
pub async fn save(
    State(state): State<AppState>,
    Path(site): Path<String>,
    access: Option<Extension<Access>>,
    Form(form): Form<SettingsForm>,
) -> Response {
    let v = viewer(access.as_deref());
    let actor = access.map(|a| a.0).unwrap_or_default().actor("page");
    let outcome = async {
        if state.config.sites.iter().any(|s| s.id == site) {
            return Err(ServiceError::ConfiguredSite(site.clone()));
        }
        let rules: Value = serde_json::from_str(&form.alert_rules).map_err(|e| {
            ServiceError::InvalidSite(format!("alert_rules: not a JSON list of rules ({e})"))
        })?;
        let zone = form.time_zone.trim();
        let patch = json!({
            "name": form.name.trim(),
            "time_zone": if zone.is_empty() { Value::Null } else { json!(zone) },
            "alert_rules": rules,
        });
        crate::service::site_admin::update_site(
            &state.store,
            &site,
            &patch,
            &actor,
            state.public_url(),
        )
        .await
    };
    match outcome.await {
        Ok(_) => Redirect::to(&format!("/sites/{}#audit", seg(&site))).into_response(),
        Err(e) => refused(&site, "Settings not saved", e, &v),
    }
}
