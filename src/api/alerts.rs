//! `GET /api/v1/alerts`, `POST /api/v1/alerts/{id}/ack`.

use axum::extract::State;
use axum::response::IntoResponse;
use serde::Deserialize;
use utoipa::ToSchema;

use super::error::{ApiError, ApiJson, ApiPath, ApiQuery};
use super::list::{Page, PageParams};
use super::AppState;
use crate::store::{alerts, StoreError};

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
#[utoipa::path(get, path = "/api/v1/alerts", params(("site" = Option<String>, Query), ("state" = Option<String>, Query, pattern = "^(open|acknowledged|resolved)$"), ("limit" = Option<i64>, Query), ("cursor" = Option<String>, Query)),
    responses((status = 200, description = "alerts, newest first", body = crate::api::list::Page<crate::store::alerts::Alert>)))]
pub async fn list(
    State(state): State<AppState>,
    ApiQuery(q): ApiQuery<AlertParams>,
) -> Result<impl IntoResponse, ApiError> {
    if let Some(s) = &q.state {
        if !["open", "acknowledged", "resolved"].contains(&s.as_str()) {
            return Err(ApiError::bad_request(format!(
                "state '{s}': open, acknowledged or resolved"
            )));
        }
    }
    let page = PageParams {
        limit: q.limit,
        cursor: q.cursor,
    };
    let cursor = page.cursor()?;
    let after = cursor.as_deref().and_then(|c| c.split_once('|'));
    let rows = alerts::list(
        state.store.reader(),
        q.site.as_deref(),
        q.state.as_deref(),
        after,
        page.limit() + 1,
    )
    .await?;
    let page = Page::from_fetched(rows, page.limit(), |(raw, a)| format!("{raw}|{}", a.id));
    Ok(axum::Json(Page {
        items: page.items.into_iter().map(|(_, a)| a).collect(),
        next_cursor: page.next_cursor,
    }))
}

/// Body of an acknowledgement.
#[derive(Debug, Deserialize, ToSchema)]
pub struct AckBody {
    /// Who acknowledges.
    pub by: String,
    /// Comment.
    #[serde(default)]
    pub comment: Option<String>,
}

/// `POST /api/v1/alerts/{id}/ack`: acknowledges; queues an `alert.acknowledged` webhook event.
#[utoipa::path(post, path = "/api/v1/alerts/{id}/ack", request_body = AckBody, params(("id" = String, Path)),
    responses((status = 200, body = crate::store::alerts::Alert), (status = 404, description = "unknown alert", body = crate::api::schemas::ErrorBody)))]
pub async fn acknowledge(
    State(state): State<AppState>,
    ApiPath(id): ApiPath<String>,
    ApiJson(body): ApiJson<AckBody>,
) -> Result<impl IntoResponse, ApiError> {
    let alert = acknowledge_alert(&state, &id, &body.by, body.comment.as_deref()).await?;
    Ok(axum::Json(alert))
}

/// Acknowledges alert `id` for `by` with an optional comment in one write transaction: an open
/// alert moves to `acknowledged` and queues an `alert.acknowledged` event; a resolved one only
/// records who acknowledged it. 404 for an unknown id.
pub async fn acknowledge_alert(
    state: &AppState,
    id: &str,
    by: &str,
    comment: Option<&str>,
) -> Result<alerts::Alert, ApiError> {
    let mut tx = state.store.begin_write().await?;
    let Some(stored) = alerts::get(&mut *tx, id).await? else {
        return Err(ApiError::not_found(format!("unknown alert '{id}'")));
    };
    let engine = crate::alerting::load_state(&mut tx, &stored.site).await?;
    match crate::analysis::acknowledge(&engine, id, by, comment, chrono::Utc::now()) {
        Ok((engine, event)) => {
            crate::alerting::save_state(&mut tx, &stored.site, &engine).await?;
            crate::alerting::record_events(&mut tx, &[event]).await?;
        }
        // Not open any more (resolved): note who acknowledged it, no event.
        Err(_) => {
            alerts::acknowledge(&mut tx, id, by, comment).await?;
        }
    }
    let alert = alerts::get(&mut *tx, id)
        .await?
        .ok_or_else(|| ApiError::internal("alert vanished"))?;
    tx.commit().await.map_err(StoreError::from)?;
    Ok(alert)
}
