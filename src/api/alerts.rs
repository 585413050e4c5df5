//! `GET /api/v1/alerts`, `GET /api/v1/alerts/{id}/events`, `POST /api/v1/alerts/{id}/ack`.

use axum::extract::State;
use axum::response::IntoResponse;
use serde::Deserialize;
use utoipa::ToSchema;

use super::list::{Listing, Page, PageParams};
use crate::http::error::{ApiError, ApiJson, ApiPath, ApiQuery};
use crate::http::AppState;
use crate::service;
use crate::store::alerts;
use crate::webhooks::WebhookPayload;
use cliffwatch_core::analysis::AlertStatus;

/// Query of the alert list.
#[derive(Debug, Default, Deserialize)]
pub struct AlertParams {
    /// Only this site.
    pub site: Option<String>,
    /// `open`, `acknowledged` or `resolved`.
    pub state: Option<String>,
    /// Page size.
    pub limit: Option<i64>,
    /// Cursor.
    pub cursor: Option<String>,
}

/// `GET /api/v1/alerts`: newest first.
#[utoipa::path(get, path = "/api/v1/alerts", operation_id = "list_alerts", params(("site" = Option<String>, Query), ("state" = Option<String>, Query, pattern = "^(open|acknowledged|resolved)$"), ("limit" = Option<i64>, Query, minimum = 1, description = "page size (default 100; above 1000 read as 1000)"), ("cursor" = Option<String>, Query)),
    responses((status = 200, description = "alerts, newest first", body = crate::api::list::Page<crate::store::alerts::Alert>),
        (status = 400, description = "bad state, page size or cursor", body = crate::api::schemas::ErrorBody),
        (status = 404, description = "unknown site", body = crate::api::schemas::ErrorBody)))]
pub async fn list(
    State(state): State<AppState>,
    ApiQuery(q): ApiQuery<AlertParams>,
) -> Result<impl IntoResponse, ApiError> {
    let wanted = match &q.state {
        None => None,
        Some(s) => Some(s.parse::<AlertStatus>().map_err(|_| {
            ApiError::bad_request(format!(
                "state '{}': open, acknowledged or resolved",
                cliffwatch_core::contract::truncate_for_message(s)
            ))
        })?),
    };
    let page = PageParams {
        limit: q.limit,
        cursor: q.cursor,
    };
    let cursor = page.cursor(Listing::Alerts)?;
    let limit = page.limit()?;
    // A misspelt site is named, not answered with an empty list that reads as "all quiet".
    if let Some(site) = &q.site {
        super::sites::find(&state, site).await?;
    }
    let after = cursor.as_deref().and_then(|c| c.split_once('|'));
    let rows = alerts::list(
        state.store.reader(),
        q.site.as_deref(),
        wanted,
        after,
        limit + 1,
    )
    .await?;
    let page = Page::from_fetched(rows, limit, Listing::Alerts, |(raw, a)| {
        format!("{raw}|{}", a.id)
    });
    Ok(axum::Json(Page {
        items: page.items.into_iter().map(|(_, a)| a).collect(),
        next_cursor: page.next_cursor,
    }))
}

/// Body of an acknowledgement.
#[derive(Debug, Deserialize, ToSchema)]
pub struct AckBody {
    /// Who acknowledges: 1 to 200 characters once trimmed, without the NUL character.
    #[schema(
        min_length = 1,
        max_length = 200,
        pattern = "^[^\\u0000]*[^\\s\\u0000][^\\u0000]*$"
    )]
    pub by: String,
    /// Comment: at most 2000 characters once trimmed, without the NUL character; blank is none.
    #[serde(default)]
    #[schema(max_length = 2000, pattern = "^[^\\u0000]*$")]
    pub comment: Option<String>,
}

// utoipa's `max_length` takes only a literal: keep the schema above in step with the limits the
// service enforces.
const _: () = assert!(
    service::acknowledge::MAX_NAME_CHARS == 200 && service::acknowledge::MAX_COMMENT_CHARS == 2000,
    "AckBody's schema states the acknowledgement limits as literals"
);

/// `POST /api/v1/alerts/{id}/ack`: acknowledges an open alert; queues an `alert.acknowledged`
/// webhook event. An acknowledgement given stands: acknowledging again is 409 until an
/// escalation opens the alert again.
#[utoipa::path(post, path = "/api/v1/alerts/{id}/ack", operation_id = "acknowledge_alert", request_body = AckBody, params(("id" = String, Path)),
    responses((status = 200, body = crate::store::alerts::Alert),
              (status = 400, description = "not JSON", body = crate::api::schemas::ErrorBody),
              (status = 404, description = "unknown alert", body = crate::api::schemas::ErrorBody),
              (status = 409, description = "acknowledged already (code `already_acknowledged`, naming who)", body = crate::api::schemas::ErrorBody),
              (status = 422, description = "`by` blank or too long, `comment` too long", body = crate::api::schemas::ErrorBody)))]
pub async fn acknowledge(
    State(state): State<AppState>,
    ApiPath(id): ApiPath<String>,
    ApiJson(body): ApiJson<AckBody>,
) -> Result<impl IntoResponse, ApiError> {
    let (by, comment) = (&body.by, body.comment.as_deref());
    let alert =
        service::acknowledge::acknowledge(&state.store, &id, by, comment, state.public_url())
            .await?;
    Ok(axum::Json(alert))
}

/// An alert's history.
#[derive(Debug, serde::Serialize, ToSchema)]
pub struct AlertHistory {
    /// Every event of the alert, oldest first, with the body its webhooks carried: raised,
    /// escalated, acknowledged (who, and the comment), de-escalated, resolved. An acknowledgement
    /// that a later escalation cleared stays here.
    pub items: Vec<WebhookPayload>,
}

/// `GET /api/v1/alerts/{id}/events`: the alert's history, oldest first.
#[utoipa::path(get, path = "/api/v1/alerts/{id}/events", operation_id = "list_alert_events", params(("id" = String, Path)),
    responses((status = 200, description = "the alert's events, oldest first", body = AlertHistory),
              (status = 404, description = "unknown alert", body = crate::api::schemas::ErrorBody)))]
pub async fn events(
    State(state): State<AppState>,
    ApiPath(id): ApiPath<String>,
) -> Result<impl IntoResponse, ApiError> {
    let db = state.store.reader();
    if alerts::get(db, &id).await?.is_none() {
        return Err(service::ServiceError::UnknownAlert(id).into());
    }
    let items = alerts::history(db, &id).await?;
    Ok(axum::Json(AlertHistory { items }))
}
