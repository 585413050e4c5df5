//! `GET /api/v1/sites/{site}/incidents`, `POST /api/v1/sites/{site}/incidents/{incident}/ack`:
//! the open alerts gathered per block or point ([`crate::service::incidents`]), and their
//! acknowledgement in one action.

use axum::extract::State;
use axum::response::IntoResponse;
use serde::Serialize;
use utoipa::ToSchema;

use super::alerts::AckBody;
use crate::http::error::{ApiError, ApiJson, ApiPath};
use crate::http::AppState;
use crate::service;
use crate::service::incidents::Incident;

/// A site's incidents.
#[derive(Debug, Serialize, ToSchema)]
pub struct IncidentList {
    /// Most urgent first: the earliest "failure likely before", then the highest level, then
    /// the oldest.
    pub items: Vec<Incident>,
}

/// `GET /api/v1/sites/{site}/incidents`: one incident per declared block (with its member
/// points' alerts), per point outside any block and for the site, each with every open or
/// acknowledged alert on it.
#[utoipa::path(get, path = "/api/v1/sites/{site}/incidents", operation_id = "list_incidents", params(("site" = String, Path)),
    responses((status = 200, description = "the site's incidents, most urgent first", body = IncidentList),
              (status = 404, description = "unknown site", body = crate::api::schemas::ErrorBody)))]
pub async fn list(
    State(state): State<AppState>,
    ApiPath(site): ApiPath<String>,
) -> Result<impl IntoResponse, ApiError> {
    super::sites::find(&state, &site).await?;
    let items = service::incidents::list(&state.store, &site).await?;
    Ok(axum::Json(IncidentList { items }))
}

/// `POST /api/v1/sites/{site}/incidents/{incident}/ack`: acknowledges every open alert of the
/// incident in one transaction (each queues its `alert.acknowledged` event), with the body of an
/// alert's acknowledgement. 409 when all of them are acknowledged already.
#[utoipa::path(post, path = "/api/v1/sites/{site}/incidents/{incident}/ack", operation_id = "acknowledge_incident", request_body = AckBody,
    params(("site" = String, Path), ("incident" = String, Path, description = "`block:NAME`, `point:NAME` or `site`")),
    responses((status = 200, description = "the incident after", body = Incident),
              (status = 400, description = "not JSON", body = crate::api::schemas::ErrorBody),
              (status = 404, description = "unknown site, or no open incident with that id", body = crate::api::schemas::ErrorBody),
              (status = 409, description = "every alert of it acknowledged already (code `already_acknowledged`, naming who)", body = crate::api::schemas::ErrorBody),
              (status = 422, description = "`by` blank or too long, `comment` too long", body = crate::api::schemas::ErrorBody)))]
pub async fn acknowledge(
    State(state): State<AppState>,
    ApiPath((site, incident)): ApiPath<(String, String)>,
    ApiJson(body): ApiJson<AckBody>,
) -> Result<impl IntoResponse, ApiError> {
    super::sites::find(&state, &site).await?;
    let done = service::incidents::acknowledge(
        &state.store,
        &site,
        &incident,
        &body.by,
        body.comment.as_deref(),
        state.public_url(),
    )
    .await?;
    Ok(axum::Json(done))
}
