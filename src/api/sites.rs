//! `POST/GET /api/v1/sites`, `GET /api/v1/sites/{site}`, `PUT /api/v1/sites/{site}/reference`.

use axum::extract::State;
use axum::http::StatusCode;
use axum::response::IntoResponse;
use axum::Extension;
use serde::Deserialize;
use utoipa::ToSchema;

use super::list::{Listing, Page, PageParams};
use crate::http::auth::Access;
use crate::http::error::{ApiError, ApiJson, ApiPath, ApiQuery};
use crate::http::AppState;
use crate::service::ServiceError;
use crate::store::sites::{self, NewSite, Site};
use cliffwatch_core::photogrammetry::input::epoch::is_valid_identifier;

/// `POST /api/v1/sites`: creates a site (201), or 409 when the id exists.
#[utoipa::path(post, path = "/api/v1/sites", operation_id = "create_site", request_body = NewSite,
    responses((status = 201, body = Site), (status = 409, description = "exists", body = crate::api::schemas::ErrorBody), (status = 422, description = "invalid", body = crate::api::schemas::ErrorBody)))]
pub async fn create(
    State(state): State<AppState>,
    ApiJson(site): ApiJson<NewSite>,
) -> Result<impl IntoResponse, ApiError> {
    let stored = crate::service::sites::create_site(&state.store, &site).await?;
    Ok((StatusCode::CREATED, axum::Json(stored)))
}

/// `GET /api/v1/sites`: every site, newest first.
#[utoipa::path(get, path = "/api/v1/sites", operation_id = "list_sites", params(("limit" = Option<i64>, Query, minimum = 1, description = "page size (default 100; above 1000 read as 1000)"), ("cursor" = Option<String>, Query)),
    responses((status = 200, description = "sites", body = crate::api::list::Page<crate::store::sites::Site>)))]
pub async fn list(
    State(state): State<AppState>,
    ApiQuery(page): ApiQuery<PageParams>,
) -> Result<impl IntoResponse, ApiError> {
    let cursor = page.cursor(Listing::Sites)?;
    let limit = page.limit()?;
    let after = cursor.as_deref().and_then(|c| c.split_once('|'));
    let items = sites::list(state.store.reader(), after, limit + 1).await?;
    let mut raw = Vec::with_capacity(items.len());
    for s in &items {
        raw.push(
            sites::created_at_raw(state.store.reader(), &s.id)
                .await?
                .unwrap_or_default(),
        );
    }
    let pairs: Vec<(String, Site)> = raw.into_iter().zip(items).collect();
    let page = Page::from_fetched(pairs, limit, Listing::Sites, |(t, s)| {
        format!("{t}|{}", s.id)
    });
    Ok(axum::Json(Page {
        items: page.items.into_iter().map(|(_, s)| s).collect(),
        next_cursor: page.next_cursor,
    }))
}

/// `GET /api/v1/sites/{site}`.
#[utoipa::path(get, path = "/api/v1/sites/{site}", operation_id = "get_site", params(("site" = String, Path)),
    responses((status = 200, body = Site), (status = 404, description = "unknown site", body = crate::api::schemas::ErrorBody)))]
pub async fn get_one(
    State(state): State<AppState>,
    ApiPath(site): ApiPath<String>,
) -> Result<impl IntoResponse, ApiError> {
    Ok(axum::Json(find(&state, &site).await?))
}

/// Reads a site or answers 404.
pub async fn find(state: &AppState, site: &str) -> Result<Site, ApiError> {
    // No site has an id outside the identifier rule: not asked of the database (PostgreSQL
    // would refuse a NUL in it as a value it cannot hold, where the answer is "no such site").
    if !is_valid_identifier(site) {
        return Err(ApiError::not_found(format!(
            "unknown site '{}'",
            cliffwatch_core::contract::truncate_for_message(site)
        )));
    }
    sites::get(state.store.reader(), site)
        .await?
        .ok_or_else(|| ApiError::not_found(format!("unknown site '{site}'")))
}

/// Body of `PUT .../reference`: `{"epoch": ID}`, or `{"epoch": null}` / `{}` back to the
/// earliest epoch. No other member is taken: a misspelt one (`epoch_id`) would otherwise read as
/// a reset of the reference and recompute the site.
#[derive(Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct ReferenceBody {
    /// The reference epoch's integer id; null or absent: back to the earliest.
    #[serde(
        default,
        deserialize_with = "cliffwatch_core::contract::json_integer::optional_i64"
    )]
    pub epoch: Option<i64>,
}

/// `PUT /api/v1/sites/{site}/reference`: sets the reference epoch and recomputes displacements.
#[utoipa::path(put, path = "/api/v1/sites/{site}/reference", operation_id = "set_site_reference", request_body = ReferenceBody, params(("site" = String, Path)),
    responses((status = 409, description = "the site is retired (code `site_retired`): it takes no more changes", body = crate::api::schemas::ErrorBody), (status = 200, body = Site), (status = 404, description = "unknown site", body = crate::api::schemas::ErrorBody),
        (status = 422, description = "an epoch the site does not have, or a member other than `epoch`", body = crate::api::schemas::ErrorBody)))]
pub async fn set_reference(
    State(state): State<AppState>,
    ApiPath(site): ApiPath<String>,
    access: Option<Extension<Access>>,
    ApiJson(body): ApiJson<ReferenceBody>,
) -> Result<impl IntoResponse, ApiError> {
    let actor = access.map(|a| a.0).unwrap_or_default().actor("api");
    crate::service::site_settings::set_reference(
        &state.store,
        &site,
        body.epoch,
        &actor,
        state.public_url(),
    )
    .await
    .map_err(|e| match e {
        // Named in the body, like an unknown camera of an upload: 422, not 404.
        ServiceError::UnknownEpoch { .. } => {
            ApiError::unprocessable("unknown_epoch", e.to_string())
        }
        e => ApiError::from(e),
    })?;
    Ok(axum::Json(find(&state, &site).await?))
}

/// `PATCH /api/v1/sites/{site}`: changes a site's settings with a JSON merge patch (RFC 7396:
/// the members given replace the stored ones, null removes an optional one), checked as a new
/// site is; a change of the rules or the analysis settings recomputes the site and
/// re-evaluates its alerts at once. Recorded in the site's audit trail. A site of the
/// configuration file is refused (409 `configured_site`): the file is applied at every start.
#[utoipa::path(patch, path = "/api/v1/sites/{site}", operation_id = "update_site", params(("site" = String, Path)),
    request_body(content = Object, content_type = "application/merge-patch+json", description = "the members of the site form to change (not `id`); null removes an optional one"),
    responses((status = 200, description = "the site after", body = Site),
        (status = 400, description = "not JSON", body = crate::api::schemas::ErrorBody),
        (status = 404, description = "unknown site", body = crate::api::schemas::ErrorBody),
        (status = 409, description = "a site of the configuration file (code `configured_site`), or a retired site (`site_retired`)", body = crate::api::schemas::ErrorBody),
        (status = 422, description = "a setting refused (the field at fault is named), an unknown member, a new id, or a new model once the site has epochs", body = crate::api::schemas::ErrorBody)))]
pub async fn update(
    State(state): State<AppState>,
    ApiPath(site): ApiPath<String>,
    access: Option<Extension<Access>>,
    ApiJson(patch): ApiJson<serde_json::Value>,
) -> Result<impl IntoResponse, ApiError> {
    find(&state, &site).await?;
    if state.config.sites.iter().any(|s| s.id == site) {
        return Err(ServiceError::ConfiguredSite(site).into());
    }
    let actor = access.map(|a| a.0).unwrap_or_default().actor("api");
    let after = crate::service::site_admin::update_site(
        &state.store,
        &site,
        &patch,
        &actor,
        state.public_url(),
    )
    .await?;
    Ok(axum::Json(after))
}

/// A page of a site's audit trail.
#[derive(Debug, serde::Serialize, ToSchema)]
pub struct AuditPage {
    /// Changes, newest first.
    pub items: Vec<crate::store::audit::AuditEntry>,
    /// Cursor of the next (older) page; null on the last.
    pub next_cursor: Option<String>,
}

/// Query of the audit trail.
#[derive(Debug, Default, Deserialize)]
pub struct AuditParams {
    /// Page size (default 100, at most 1000).
    pub limit: Option<i64>,
    /// Cursor of the page (`next_cursor` of the previous one).
    pub cursor: Option<String>,
}

/// `GET /api/v1/sites/{site}/audit`: every change of the site's settings, newest first: when,
/// who, from where, what, before and after.
#[utoipa::path(get, path = "/api/v1/sites/{site}/audit", operation_id = "list_site_audit",
    params(("site" = String, Path), ("limit" = Option<i64>, Query, minimum = 1, description = "page size (default 100; above 1000 read as 1000)"), ("cursor" = Option<String>, Query)),
    responses((status = 200, description = "changes, newest first", body = AuditPage),
        (status = 400, description = "bad page size or cursor", body = crate::api::schemas::ErrorBody),
        (status = 404, description = "unknown site", body = crate::api::schemas::ErrorBody)))]
pub async fn audit(
    State(state): State<AppState>,
    ApiPath(site): ApiPath<String>,
    crate::http::error::ApiQuery(q): crate::http::error::ApiQuery<AuditParams>,
) -> Result<impl IntoResponse, ApiError> {
    find(&state, &site).await?;
    let limit = match q.limit {
        None => 100,
        Some(n) if n >= 1 => n.min(1000),
        Some(n) => return Err(ApiError::bad_request(format!("limit {n}: at least 1"))),
    };
    let after = match q.cursor.as_deref() {
        None => None,
        Some(c) => Some(c.split_once('|').ok_or_else(|| {
            ApiError::bad_request(format!(
                "cursor '{}': the next_cursor of a page",
                cliffwatch_core::contract::truncate_for_message(c)
            ))
        })?),
    };
    let mut items =
        crate::service::site_admin::audit_trail(&state.store, &site, after, limit + 1).await?;
    let next_cursor = (items.len() as i64 > limit).then(|| {
        items.truncate(limit as usize);
        items.last().map(|e| format!("{}|{}", e.at, e.id))
    });
    Ok(axum::Json(AuditPage {
        items,
        next_cursor: next_cursor.flatten(),
    }))
}
