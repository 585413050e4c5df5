//! A site's audit trail on the dashboard: the latest changes on the site page ([`section`]),
//! every change page by page at `GET /sites/{site}/audit?cursor=` ([`audit`]), and the changes
//! of a period in the campaign report ([`table`]). Each row says when, who (and from where),
//! what, and what the setting was before → after, in words (a rule reads "watch
//! displacement_mm above 5 mm").

use axum::extract::{Path, Query, State};
use axum::response::Html;
use axum::Extension;
use maud::{html, Markup};
use serde::Deserialize;
use serde_json::Value;

use super::layout::{page, seg};
use super::local_time::when;
use super::page::{viewer, PageError};
use crate::http::auth::Access;
use crate::http::AppState;
use crate::store::audit::{self, AuditEntry};

/// Changes shown on the site page.
pub const ON_SITE_PAGE: i64 = 10;

/// Changes per page of the audit page.
const PER_PAGE: i64 = 50;

/// Longest text of one side (before or after) of a row, in characters.
const MAX_SIDE_CHARS: usize = 400;

/// One alert rule in words: `watch displacement_mm above 5 (clear below 4)`.
fn rule_words(r: &Value) -> String {
    let field = |k: &str| r.get(k).filter(|v| !v.is_null());
    let mut w = format!(
        "{} {}",
        field("level").and_then(Value::as_str).unwrap_or("?"),
        field("metric").and_then(Value::as_str).unwrap_or("?")
    );
    for k in ["above", "below"] {
        if let Some(v) = field(k) {
            w.push_str(&format!(" {k} {v}"));
        }
    }
    for (k, words) in [
        ("clear_below", "clear below"),
        ("clear_above", "clear above"),
        ("group", "group"),
        ("for_epochs", "for epochs"),
        ("source", "source"),
        ("confidence", "confidence"),
    ] {
        if let Some(v) = field(k) {
            let v = v.as_str().map_or_else(|| v.to_string(), str::to_string);
            w.push_str(&format!(" ({words} {v})"));
        }
    }
    w
}

/// A setting's value in words: rules one by one, text as itself, the rest as JSON.
fn value_words(v: &Value) -> String {
    match v {
        Value::Null => "none".into(),
        Value::String(s) => s.clone(),
        Value::Array(items) if items.iter().all(|r| r.get("metric").is_some()) => {
            if items.is_empty() {
                "no rule".into()
            } else {
                items.iter().map(rule_words).collect::<Vec<_>>().join("; ")
            }
        }
        v => v.to_string(),
    }
}

/// One side of a change (the JSON text stored) in words: `member: value` per member of an
/// object, cut at [`MAX_SIDE_CHARS`].
fn side_words(json: Option<&str>) -> String {
    let Some(text) = json else {
        return "—".into();
    };
    let words = match serde_json::from_str::<Value>(text) {
        Ok(Value::Object(m)) => m
            .iter()
            .map(|(k, v)| format!("{k}: {}", value_words(v)))
            .collect::<Vec<_>>()
            .join(", "),
        Ok(v) => value_words(&v),
        Err(_) => text.to_string(),
    };
    if words.chars().count() > MAX_SIDE_CHARS {
        let cut: String = words.chars().take(MAX_SIDE_CHARS).collect();
        format!("{cut}…")
    } else {
        words
    }
}

/// The changes `rows` as a table: when (UTC and `tz`), who and from where, what, before → after.
pub fn table(rows: &[AuditEntry], tz: Option<&str>) -> Markup {
    html! {
        table.audit {
            thead { tr { th { "when" } th { "who" } th { "what" } th { "before → after" } } }
            tbody {
                @for e in rows {
                    tr {
                        td { (when(&e.at, tz)) }
                        td { (e.actor) " (" (e.source) ")" }
                        td { (e.action) " · " (e.target) }
                        td.change { (side_words(e.value_before.as_deref())) " → " (side_words(e.value_after.as_deref())) }
                    }
                }
            }
        }
    }
}

/// The site page's section: the latest [`ON_SITE_PAGE`] changes and a link to all of them.
pub fn section(site_href: &str, rows: &[AuditEntry], tz: Option<&str>) -> Markup {
    html! {
        section #audit {
            h2 { "Changes (audit trail)" }
            @if rows.is_empty() {
                p.note { "No change of the site's settings yet." }
            } @else {
                (table(rows, tz))
                p.pager { a href={ (site_href) "/audit" } { "every change →" } }
            }
        }
    }
}

/// Query of the audit page.
#[derive(Debug, Deserialize)]
pub struct AuditQuery {
    /// `at|id` of the last row of the previous page.
    pub cursor: Option<String>,
}

/// `GET /sites/{site}/audit?cursor=`: every change of the site, newest first, [`PER_PAGE`] a
/// page.
pub async fn audit(
    State(state): State<AppState>,
    Path(site_id): Path<String>,
    Query(q): Query<AuditQuery>,
    access: Option<Extension<Access>>,
) -> Result<Html<String>, PageError> {
    let db = state.store.reader();
    let site = super::page::site_or_404(db, &site_id).await?;
    let after = match q.cursor.as_deref() {
        None => None,
        Some(c) => Some(c.split_once('|').ok_or_else(|| {
            PageError::bad_request("cursor: the link of the previous page".to_string())
        })?),
    };
    let mut rows = audit::list(db, &site.id, after, PER_PAGE + 1).await?;
    let next = (rows.len() as i64 > PER_PAGE).then(|| {
        rows.truncate(PER_PAGE as usize);
        rows.last().map(|e| format!("{}|{}", e.at, e.id))
    });
    let site_href = format!("/sites/{}", seg(&site.id));
    let tz = site.time_zone.as_deref();
    let body = html! {
        h1 { "Changes of " (site.name) }
        @if rows.is_empty() { p.note { "No change." } } @else { (table(&rows, tz)) }
        @if let Some(c) = next.flatten() {
            p.pager { a.older href={ (site_href) "/audit?cursor=" (seg(&c)) } { "older changes →" } }
        }
        @if after.is_some() { p.pager { a href={ (site_href) "/audit" } { "← newest changes" } } }
    };
    let crumbs = [
        (site.name.clone(), site_href.clone()),
        ("changes".to_string(), format!("{site_href}/audit")),
    ];
    let v = viewer(access.as_deref());
    Ok(Html(page("changes", &crumbs, &v, body).into_string()))
}
