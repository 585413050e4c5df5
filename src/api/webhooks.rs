//! `POST/GET /api/v1/webhooks`, `DELETE /api/v1/webhooks/{id}`, `POST /api/v1/webhooks/{id}/test`
//! (admin).

use axum::extract::State;
use axum::http::StatusCode;
use axum::response::IntoResponse;

use super::list::Page;
use crate::http::error::{ApiError, ApiJson, ApiPath};
use crate::http::AppState;
use crate::store::webhooks::{self, NewWebhook};

// utoipa's `max_length` takes only a literal: keep NewWebhook's schema in step with the limits the
// service enforces.
const _: () = assert!(
    crate::service::webhooks::MAX_URL_CHARS == 2048
        && crate::service::webhooks::MAX_SECRET_CHARS == 256,
    "NewWebhook's schema states the webhook limits as literals"
);

/// `POST /api/v1/webhooks`.
#[utoipa::path(post, path = "/api/v1/webhooks", operation_id = "create_webhook", request_body = NewWebhook,
    responses((status = 201, body = crate::store::webhooks::Webhook), (status = 422, description = "invalid", body = crate::api::schemas::ErrorBody)))]
pub async fn create(
    State(state): State<AppState>,
    ApiJson(hook): ApiJson<NewWebhook>,
) -> Result<impl IntoResponse, ApiError> {
    let stored = crate::service::webhooks::create_webhook(&state.store, &hook).await?;
    Ok((StatusCode::CREATED, axum::Json(stored)))
}

/// `GET /api/v1/webhooks` (secrets are not returned).
#[utoipa::path(get, path = "/api/v1/webhooks", operation_id = "list_webhooks", responses((status = 200, description = "webhook endpoints (no secrets)", body = crate::api::list::Page<crate::store::webhooks::Webhook>)))]
pub async fn list(State(state): State<AppState>) -> Result<impl IntoResponse, ApiError> {
    Ok(axum::Json(Page {
        items: webhooks::list(state.store.reader()).await?,
        next_cursor: None,
    }))
}

/// `DELETE /api/v1/webhooks/{id}`.
#[utoipa::path(delete, path = "/api/v1/webhooks/{id}", operation_id = "delete_webhook", params(("id" = String, Path)),
    responses((status = 204, description = "deleted"), (status = 404, description = "unknown webhook", body = crate::api::schemas::ErrorBody)))]
pub async fn delete(
    State(state): State<AppState>,
    ApiPath(id): ApiPath<String>,
) -> Result<impl IntoResponse, ApiError> {
    crate::service::webhooks::delete_webhook(&state.store, &id).await?;
    Ok(StatusCode::NO_CONTENT)
}

/// What a test notification came to (`POST /api/v1/webhooks/{id}/test`).
#[derive(Debug, Clone, serde::Serialize, utoipa::ToSchema)]
pub struct WebhookTest {
    /// The endpoint.
    pub webhook_id: String,
    /// The `webhook-id` the test was sent under.
    pub message_id: String,
    /// Whether the receiver answered 2xx.
    pub delivered: bool,
    /// The receiver's HTTP status (null: no answer).
    pub status: Option<u16>,
    /// Why it was not delivered (null when it was).
    pub error: Option<String>,
    /// False when the endpoint is disabled (after a 410 Gone): the test was sent all the same,
    /// alerts are not.
    pub enabled: bool,
}

/// `POST /api/v1/webhooks/{id}/test`: sends a signed `test` event in the endpoint's format
/// ([`crate::webhooks::test_body`]) once, now, outside the outbox, and reports the receiver's
/// answer.
#[utoipa::path(post, path = "/api/v1/webhooks/{id}/test", operation_id = "test_webhook", params(("id" = String, Path)),
    responses((status = 200, description = "sent; whether the receiver took it", body = WebhookTest),
        (status = 404, description = "unknown webhook", body = crate::api::schemas::ErrorBody)))]
pub async fn test(
    State(state): State<AppState>,
    ApiPath(id): ApiPath<String>,
) -> Result<impl IntoResponse, ApiError> {
    let Some(endpoint) = webhooks::endpoint(state.store.reader(), &id).await? else {
        return Err(crate::service::ServiceError::UnknownWebhook(id).into());
    };
    let now = chrono::Utc::now();
    let body = crate::webhooks::test_body(endpoint.format, &endpoint.id, now)
        .map_err(|e| ApiError::internal(e.to_string()))?;
    let message_id = format!("msg_test_{}", uuid::Uuid::new_v4().simple());
    let timeout = std::time::Duration::from_secs(state.config.webhook_timeout_secs.max(1));
    let client = crate::webhooks::client(timeout).map_err(|e| ApiError::internal(e.to_string()))?;
    let outcome = crate::webhooks::deliver(
        &client,
        &endpoint.url,
        &endpoint.secret,
        &message_id,
        body.as_bytes(),
        now,
    )
    .await;
    use crate::webhooks::DeliveryOutcome as O;
    let (delivered, status, error) = match outcome {
        O::Delivered { status } => (true, Some(status), None),
        O::Retry { status, reason, .. } => (false, status, Some(reason)),
        O::Gone => (false, Some(410), Some("endpoint gone (410)".to_string())),
        O::Failed { status, reason } => (false, status, Some(reason)),
    };
    Ok(axum::Json(WebhookTest {
        webhook_id: endpoint.id,
        message_id,
        delivered,
        status,
        error,
        enabled: endpoint.enabled,
    }))
}
