//! `POST /api/v1/sites/{site}/retire`, `GET /api/v1/sites/{site}/export`,
//! `DELETE /api/v1/sites/{site}`: the end of a site's life ([`crate::service::site_lifecycle`]).

use axum::extract::State;
use axum::http::{header, Method, StatusCode};
use axum::response::IntoResponse;
use axum::Extension;
use serde::Deserialize;
use utoipa::ToSchema;

use super::sites::find;
use crate::http::auth::Access;
use crate::http::error::{ApiError, ApiJson, ApiPath};
use crate::http::AppState;
use crate::service::site_lifecycle;
use crate::service::ServiceError;

/// Body of `POST .../retire`.
#[derive(Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct RetireBody {
    /// Why the site is retired (1 to 2000 characters): shown on its pages and in the events of
    /// the alerts it closes.
    #[schema(
        min_length = 1,
        max_length = 2000,
        pattern = "^[^\\u0000]*\\S[^\\u0000]*$"
    )]
    pub reason: String,
}

/// Refuses a site of the configuration file (applied at every start: a retirement or deletion
/// would be undone, or the site created again).
fn not_configured(state: &AppState, site: &str) -> Result<(), ApiError> {
    if state.config.sites.iter().any(|s| s.id == site) {
        return Err(ServiceError::ConfiguredSite(site.to_string()).into());
    }
    Ok(())
}

/// `POST /api/v1/sites/{site}/retire`: retires the site: further uploads (HTTP and watched
/// directory) and changes of its settings are refused (409 `site_retired`), its pages stay with
/// a banner saying when and why, every open alert is resolved with the reason in its event, and
/// the audit trail records it (`site.retire`).
#[utoipa::path(post, path = "/api/v1/sites/{site}/retire", operation_id = "retire_site", request_body = RetireBody, params(("site" = String, Path)),
    responses((status = 200, description = "the site after, with `retired_at` and `retired_reason`", body = crate::store::sites::Site),
        (status = 400, description = "not JSON", body = crate::api::schemas::ErrorBody),
        (status = 404, description = "unknown site", body = crate::api::schemas::ErrorBody),
        (status = 409, description = "retired already (code `site_retired`), or a site of the configuration file (`configured_site`)", body = crate::api::schemas::ErrorBody),
        (status = 422, description = "no reason, a blank or too long one, or another member (code `invalid_site`)", body = crate::api::schemas::ErrorBody)))]
pub async fn retire(
    State(state): State<AppState>,
    ApiPath(site): ApiPath<String>,
    access: Option<Extension<Access>>,
    ApiJson(body): ApiJson<RetireBody>,
) -> Result<impl IntoResponse, ApiError> {
    find(&state, &site).await?;
    not_configured(&state, &site)?;
    let actor = access.map(|a| a.0).unwrap_or_default().actor("api");
    let after = site_lifecycle::retire_site(
        &state.store,
        &site,
        &body.reason,
        &actor,
        state.public_url(),
    )
    .await?;
    Ok(axum::Json(after))
}

/// `GET /api/v1/sites/{site}/export`: the site's data as one JSON download (its settings,
/// epochs, points, groups, alerts and audit trail), recorded in the audit trail
/// (`site.export`); a retired site can be deleted once it was exported after its retirement.
#[utoipa::path(get, path = "/api/v1/sites/{site}/export", operation_id = "export_site", params(("site" = String, Path)),
    responses((status = 200, description = "the site's data (attachment `<site>.export.json`)", body = site_lifecycle::SiteExport),
        (status = 404, description = "unknown site", body = crate::api::schemas::ErrorBody)))]
pub async fn export(
    State(state): State<AppState>,
    ApiPath(site): ApiPath<String>,
    method: Method,
    access: Option<Extension<Access>>,
) -> Result<axum::response::Response, ApiError> {
    find(&state, &site).await?;
    let disposition = format!("attachment; filename=\"{site}.export.json\"");
    // A HEAD (which the GET route also answers) downloads nothing, so it records no export:
    // it must not open the way to the site's deletion.
    if method == Method::HEAD {
        return Ok((
            [
                (header::CONTENT_DISPOSITION, disposition),
                (header::CONTENT_TYPE, "application/json".to_string()),
            ],
            (),
        )
            .into_response());
    }
    let actor = access.map(|a| a.0).unwrap_or_default().actor("api");
    let data = site_lifecycle::export_site(&state.store, &site, &actor).await?;
    Ok((
        [(header::CONTENT_DISPOSITION, disposition)],
        axum::Json(data),
    )
        .into_response())
}

/// `DELETE /api/v1/sites/{site}`: deletes a retired site whose data was exported after the
/// retirement, every row of it in one transaction; its audit trail is kept, ending with the
/// deletion (`site.delete`, with the rows deleted per table). 204.
#[utoipa::path(delete, path = "/api/v1/sites/{site}", operation_id = "delete_site", params(("site" = String, Path)),
    responses((status = 204, description = "deleted"),
        (status = 404, description = "unknown site", body = crate::api::schemas::ErrorBody),
        (status = 409, description = "not retired, or not exported since its retirement (code `not_deletable`; the message names the missing step), or a site of the configuration file (`configured_site`)", body = crate::api::schemas::ErrorBody)))]
pub async fn delete(
    State(state): State<AppState>,
    ApiPath(site): ApiPath<String>,
    access: Option<Extension<Access>>,
) -> Result<impl IntoResponse, ApiError> {
    find(&state, &site).await?;
    not_configured(&state, &site)?;
    let actor = access.map(|a| a.0).unwrap_or_default().actor("api");
    site_lifecycle::delete_site(&state.store, &site, &actor).await?;
    Ok(StatusCode::NO_CONTENT)
}
