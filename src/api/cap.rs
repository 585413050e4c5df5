//! `GET /api/v1/cap/feed.atom` and `GET /api/v1/cap/alerts/{id}.xml`: the public-warning feed
//! (CAP 1.2 messages of the warning- and alarm-level alerts, see [`crate::cap`]).

use axum::extract::State;
use axum::http::header;
use axum::response::IntoResponse;
use serde::Deserialize;

use crate::cap::{self, CapContext, CapStep, FeedEntry};
use crate::http::error::{ApiError, ApiPath, ApiQuery};
use crate::http::AppState;
use crate::store::alerts::{self, Alert};
use crate::store::sites::{self, Site};
use crate::store::StoreError;

/// Most entries a feed carries (`limit`).
pub const MAX_FEED_ENTRIES: i64 = 500;

/// Query of the feed.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FeedParams {
    /// Only this site.
    pub site: Option<String>,
    /// Entries, 1 to [`MAX_FEED_ENTRIES`] (default 100), most recently sent first.
    pub limit: Option<i64>,
}

const CAP_XML: &str = "application/cap+xml; charset=utf-8";
const ATOM_XML: &str = "application/atom+xml; charset=utf-8";

fn link(state: &AppState, path: &str) -> String {
    match &state.config.public_url {
        Some(base) => format!("{}{path}", base.trim_end_matches('/')),
        None => path.to_string(),
    }
}

fn context<'a>(state: &'a AppState, site: &'a Site) -> CapContext<'a> {
    CapContext {
        sender: &state.config.cap_sender,
        status: &state.config.cap_status,
        site_name: &site.name,
        area: site.area.as_ref(),
        web: state
            .config
            .public_url
            .as_ref()
            .map(|_| link(state, &format!("/sites/{}", site.id))),
    }
}

/// A UUID that names `what` for this sender, the same on every node and every request (Atom ids
/// must not change).
fn stable_uuid(state: &AppState, what: &str) -> uuid::Uuid {
    uuid::Uuid::new_v5(
        &uuid::Uuid::NAMESPACE_URL,
        format!("cliffwatch:{}:{what}", state.config.cap_sender).as_bytes(),
    )
}

/// The CAP module's view of a stored alert (its own input type: `cap` knows nothing of the
/// store).
fn subject(a: &Alert) -> cap::Subject<'_> {
    cap::Subject {
        id: &a.id,
        site: &a.site,
        point: a.point.as_deref(),
        group: a.group.as_deref(),
        rule: &a.rule,
    }
}

/// The alert's CAP thread.
async fn thread_of(state: &AppState, alert: &Alert) -> Result<Vec<CapStep>, StoreError> {
    Ok(cap::steps(
        &alerts::changes_of(state.store.reader(), &alert.id).await?,
    ))
}

/// `GET /api/v1/cap/alerts/{id}.xml`: the alert's latest CAP 1.2 message;
/// `{id}.{n}.xml`: message `n` of its thread (the identifiers its `references` name).
#[utoipa::path(get, path = "/api/v1/cap/alerts/{file}", operation_id = "get_cap_message", params(("file" = String, Path, description = "`<alert id>.xml` (the latest message) or `<alert id>.<n>.xml` (message n)", pattern = r"^[^/]+\.xml$")),
    responses((status = 200, description = "a CAP 1.2 message", content_type = "application/cap+xml", body = String),
        (status = 404, description = "unknown alert or message, an alert that never reached warning, or a datum or system alert (not published)", body = crate::api::schemas::ErrorBody)))]
pub async fn message(
    State(state): State<AppState>,
    ApiPath(file): ApiPath<String>,
) -> Result<impl IntoResponse, ApiError> {
    let stem = file.strip_suffix(".xml").ok_or_else(|| {
        ApiError::not_found(format!(
            "'{}': CAP messages are <alert id>.xml",
            cliffwatch_core::contract::truncate_for_message(&file)
        ))
    })?;
    // Alert ids may hold dots (site and point names do): the whole stem names an alert, or
    // `<alert id>.<n>` one of its messages.
    let (alert, seq) = match alerts::get(state.store.reader(), stem).await? {
        Some(a) => (a, None),
        None => {
            let message = stem
                .rsplit_once('.')
                .and_then(|(id, n)| Some((id, n.parse::<usize>().ok()?)));
            let found = match message {
                Some((id, n)) => alerts::get(state.store.reader(), id)
                    .await?
                    .map(|a| (a, Some(n))),
                None => None,
            };
            found.ok_or_else(|| {
                ApiError::not_found(format!(
                    "alert or CAP message '{}'",
                    cliffwatch_core::contract::truncate_for_message(stem)
                ))
            })?
        }
    };
    let id = alert.id.as_str();
    let site = sites::get(state.store.reader(), &alert.site)
        .await?
        .ok_or_else(|| ApiError::internal("the alert's site vanished"))?;
    if !cap::is_public_rule(&alert.rule) {
        return Err(ApiError::not_found(format!(
            "alert '{id}' is a {} alert: the CAP feed carries movement alerts only",
            alert.rule
        )));
    }
    let thread = thread_of(&state, &alert).await?;
    let step = match seq {
        Some(n) => thread.iter().find(|s| s.seq == n).ok_or_else(|| {
            ApiError::not_found(format!(
                "alert '{id}' has {} CAP message(s); there is no message {n}",
                thread.len()
            ))
        })?,
        None => thread.last().ok_or_else(|| {
            ApiError::not_found(format!(
                "alert '{id}' never reached warning or alarm; the CAP feed carries those only"
            ))
        })?,
    };
    let body = cap::cap_message(&subject(&alert), &context(&state, &site), &thread, step);
    Ok(([(header::CONTENT_TYPE, CAP_XML)], body))
}

/// `GET /api/v1/cap/feed.atom`: an Atom feed with one entry per alert that reached warning or
/// alarm, linking its latest CAP message, most recently sent first.
#[utoipa::path(get, path = "/api/v1/cap/feed.atom", operation_id = "get_cap_feed", params(("site" = Option<String>, Query, description = "only this site"), ("limit" = Option<i64>, Query, minimum = 1, maximum = 500, description = "entries (default 100)")),
    responses((status = 200, description = "an Atom feed", content_type = "application/atom+xml", body = String),
        (status = 400, description = "bad query", body = crate::api::schemas::ErrorBody),
        (status = 404, description = "unknown site", body = crate::api::schemas::ErrorBody)))]
pub async fn feed(
    State(state): State<AppState>,
    ApiQuery(q): ApiQuery<FeedParams>,
) -> Result<impl IntoResponse, ApiError> {
    let limit = q.limit.unwrap_or(100);
    if !(1..=MAX_FEED_ENTRIES).contains(&limit) {
        return Err(ApiError::bad_request(format!(
            "limit {limit}: 1 to {MAX_FEED_ENTRIES}"
        )));
    }
    let only = match &q.site {
        Some(id) => Some(sites::get(state.store.reader(), id).await?.ok_or_else(|| {
            ApiError::not_found(format!(
                "site '{}'",
                cliffwatch_core::contract::truncate_for_message(id)
            ))
        })?),
        None => None,
    };
    let candidates = alerts::ever_public(state.store.reader(), q.site.as_deref(), limit).await?;
    let mut site_cache: Vec<Site> = only.iter().cloned().collect();
    let mut entries = Vec::with_capacity(candidates.len());
    for alert in &candidates {
        let Some(step) = thread_of(&state, alert).await?.pop() else {
            continue;
        };
        if !site_cache.iter().any(|s| s.id == alert.site) {
            if let Some(s) = sites::get(state.store.reader(), &alert.site).await? {
                site_cache.push(s);
            }
        }
        let Some(site) = site_cache.iter().find(|s| s.id == alert.site) else {
            continue;
        };
        entries.push(FeedEntry {
            id: format!("urn:uuid:{}", stable_uuid(&state, &alert.id)),
            title: cap::headline(&subject(alert), &site.name, &step),
            summary: format!(
                "{} ({}) · {} · {}",
                step.msg_type.as_str(),
                step.level,
                site.name,
                step.snapshot.message
            ),
            updated: step.sent,
            href: link(&state, &format!("/api/v1/cap/alerts/{}.xml", alert.id)),
            level: step.level,
        });
    }
    entries.sort_by(|a, b| b.updated.cmp(&a.updated).then(b.id.cmp(&a.id)));
    let scope = only.as_ref().map_or("*", |s| s.id.as_str());
    let id = stable_uuid(&state, &format!("feed:{scope}"));
    let title = match &only {
        Some(s) => format!("cliffwatch warnings: {}", s.name),
        None => "cliffwatch warnings: all sites".to_string(),
    };
    let self_path = match &only {
        Some(s) => format!("/api/v1/cap/feed.atom?site={}", s.id),
        None => "/api/v1/cap/feed.atom".to_string(),
    };
    let body = cap::atom_feed(
        &format!("urn:uuid:{id}"),
        &title,
        &link(&state, &self_path),
        &entries,
        chrono::Utc::now(),
    );
    Ok(([(header::CONTENT_TYPE, ATOM_XML)], body))
}
