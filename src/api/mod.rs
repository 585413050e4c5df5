//! The HTTP API of the contract (`docs/api.md`): axum routes, auth, errors as JSON,
//! request ids, body limit, timeouts, metrics and the OpenAPI description.
//!
//! Handlers only: each parses its request, calls a use case of [`crate::service`] or a read of
//! [`crate::store`], and answers. [`router`] builds the service from an [`AppState`];
//! [`crate::daemon`] binds and runs it.

pub(crate) mod alerts;
pub(crate) mod auth;
pub(crate) mod cap;
pub(crate) mod epochs;
pub(crate) mod error;
pub(crate) mod groups;
pub(crate) mod health;
pub mod list;
pub(crate) mod openapi;
pub mod points;
pub(crate) mod schemas;
pub(crate) mod sites;
pub(crate) mod webhooks;

use std::sync::Arc;
use std::time::Duration;

use axum::extract::DefaultBodyLimit;
use axum::http::{HeaderName, Request, StatusCode};
use axum::routing::{get, post, put};
use axum::Router;
use metrics_exporter_prometheus::PrometheusHandle;
use tower_http::request_id::{MakeRequestUuid, PropagateRequestIdLayer, SetRequestIdLayer};
use tower_http::trace::TraceLayer;

use crate::config::Config;
use crate::store::Store;

/// What every handler shares. Cheap to clone.
#[derive(Clone)]
pub struct AppState {
    /// The database.
    pub store: Store,
    /// The configuration in force.
    pub config: Arc<Config>,
    /// Renders `/metrics`.
    pub metrics: PrometheusHandle,
    /// The upload slots of this node.
    pub uploads: crate::service::admission::UploadGate,
}

const REQUEST_ID: HeaderName = HeaderName::from_static("x-request-id");

/// The full router: API routes, auth, request ids, tracing, body limit, timeout.
pub fn router(state: AppState) -> Router {
    let timeout = Duration::from_secs(state.config.request_timeout_secs.max(1));
    let limit = state.config.body_limit_bytes;
    let api = Router::new()
        .route("/healthz", get(health::healthz))
        .route("/readyz", get(health::readyz))
        .route("/metrics", get(health::metrics))
        .route("/api/v1/openapi.json", get(openapi::openapi_json))
        .route("/api/v1/sites", post(sites::create).get(sites::list))
        .route("/api/v1/sites/{site}", get(sites::get_one))
        .route(
            "/api/v1/sites/{site}/epochs",
            post(epochs::upload).get(epochs::list),
        )
        .route("/api/v1/sites/{site}/epochs/{epoch}", get(epochs::get_one))
        .route("/api/v1/sites/{site}/reference", put(sites::set_reference))
        .route("/api/v1/sites/{site}/points", get(points::list))
        .route("/api/v1/sites/{site}/groups", get(groups::list))
        .route(
            "/api/v1/sites/{site}/groups/{group}",
            put(groups::put).get(groups::get_one),
        )
        .route(
            "/api/v1/sites/{site}/groups/{group}/motion",
            get(groups::motion),
        )
        .route("/api/v1/sites/{site}/points/{point}", put(points::update))
        .route(
            "/api/v1/sites/{site}/points/{point}/displacements",
            get(points::displacements),
        )
        .route("/api/v1/alerts", get(alerts::list))
        .route("/api/v1/cap/feed.atom", get(cap::feed))
        .route("/api/v1/cap/alerts/{file}", get(cap::message))
        .route("/api/v1/alerts/{id}/ack", post(alerts::acknowledge))
        .route("/api/v1/alerts/{id}/events", get(alerts::events))
        .route(
            "/api/v1/webhooks",
            post(webhooks::create).get(webhooks::list),
        )
        .route(
            "/api/v1/webhooks/{id}",
            axum::routing::delete(webhooks::delete),
        )
        .merge(crate::dashboard::routes())
        .fallback(|| async { error::ApiError::not_found("no such endpoint") })
        .layer(axum::middleware::from_fn_with_state(
            state.clone(),
            auth::authorize,
        ))
        .layer(DefaultBodyLimit::max(limit))
        .with_state(state);
    api.layer(axum::middleware::from_fn_with_state(timeout, time_limit))
        .layer(PropagateRequestIdLayer::new(REQUEST_ID))
        .layer(
            TraceLayer::new_for_http().make_span_with(|req: &Request<_>| {
                let id = req
                    .headers()
                    .get(REQUEST_ID)
                    .and_then(|v| v.to_str().ok())
                    .unwrap_or("-");
                tracing::info_span!("request", method = %req.method(), path = %req.uri().path(), request_id = %id)
            }),
        )
        .layer(SetRequestIdLayer::new(REQUEST_ID, MakeRequestUuid))
}

/// Middleware: 408 with the error body when the handler has not answered within the request
/// timeout (`request_timeout_secs`); the handler's future is dropped.
async fn time_limit(
    axum::extract::State(limit): axum::extract::State<Duration>,
    req: axum::extract::Request,
    next: axum::middleware::Next,
) -> axum::response::Response {
    use axum::response::IntoResponse;
    match tokio::time::timeout(limit, next.run(req)).await {
        Ok(response) => response,
        Err(_) => error::ApiError::new(
            StatusCode::REQUEST_TIMEOUT,
            "timeout",
            format!(
                "no answer within the request timeout of {} s",
                limit.as_secs()
            ),
        )
        .into_response(),
    }
}
