//! `POST/GET /api/v1/webhooks`, `DELETE /api/v1/webhooks/{id}`, `POST /api/v1/webhooks/{id}/test`
//! (admin).

use axum::extract::State;
use axum::http::StatusCode;
use axum::response::IntoResponse;

use super::list::Page;
use crate::http::error::{ApiError, ApiJson, ApiPath};
use crate::http::AppState;
use crate::store::webhooks::{self, NewWebhook};
use crate::store::StoreError;

/// Checks a webhook endpoint: an http(s) URL that parses and names a host, and a `whsec_` secret whose base64 decodes to the
/// signing key (a secret that does not would fail every delivery, silently, at 3 a.m.).
pub fn check_webhook(h: &NewWebhook) -> Result<(), ApiError> {
    let parsed = url::Url::parse(&h.url).ok().filter(|u| {
        (u.scheme() == "http" || u.scheme() == "https")
            && u.host_str().is_some_and(|h| !h.is_empty())
    });
    // The host must be written after `//` (`http:///x` would be read as host `x`).
    let after = h
        .url
        .strip_prefix("http://")
        .or_else(|| h.url.strip_prefix("https://"));
    if parsed.is_none() || after.is_none_or(|rest| rest.starts_with('/')) {
        return Err(ApiError::unprocessable(
            "invalid_webhook",
            format!("url '{}': an absolute http or https URL with a host", h.url),
        ));
    }
    let decoded = h
        .secret
        .strip_prefix("whsec_")
        .map(|_| crate::webhooks::signing_key(&h.secret));
    match decoded {
        Some(Ok(key)) if key.len() >= 3 => Ok(()),
        Some(Err(e)) => Err(ApiError::unprocessable(
            "invalid_webhook",
            format!("secret: whsec_ followed by standard base64, padded or not ({e})"),
        )),
        _ => Err(ApiError::unprocessable(
            "invalid_webhook",
            "secret: whsec_<base64> of at least 3 bytes",
        )),
    }
}

/// `POST /api/v1/webhooks`.
#[utoipa::path(post, path = "/api/v1/webhooks", operation_id = "create_webhook", request_body = NewWebhook,
    responses((status = 201, body = crate::store::webhooks::Webhook), (status = 422, description = "invalid", body = crate::api::schemas::ErrorBody)))]
pub async fn create(
    State(state): State<AppState>,
    ApiJson(hook): ApiJson<NewWebhook>,
) -> Result<impl IntoResponse, ApiError> {
    check_webhook(&hook)?;
    let mut tx = state.store.begin_write().await?;
    let id = webhooks::insert(&mut tx, &hook, webhooks::WebhookSource::Api).await?;
    tx.commit().await.map_err(StoreError::from)?;
    let stored = webhooks::list(state.store.reader())
        .await?
        .into_iter()
        .find(|w| w.id == id);
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
    let mut tx = state.store.begin_write().await?;
    if webhooks::delete(&mut tx, &id).await?.is_none() {
        return Err(ApiError::not_found(format!("unknown webhook '{id}'")));
    }
    tx.commit().await.map_err(StoreError::from)?;
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
        return Err(ApiError::not_found(format!("unknown webhook '{id}'")));
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
