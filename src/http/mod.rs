//! The HTTP layer below the API ([`crate::api`]) and the dashboard ([`crate::dashboard`]): the state
//! every handler shares ([`AppState`]), authentication and browser sessions ([`auth`],
//! [`session`]), errors and extractors in the contract's shape ([`error`]), the time bounds of a
//! query ([`time_bound`]), and the one place where the service's router is composed ([`router`]).
//!
//! The API and the dashboard sit beside each other on this layer and neither imports the other;
//! this layer imports neither: [`router`] takes their routes as arguments (the daemon passes
//! [`crate::api::routes`] and [`crate::dashboard::routes`]).

pub mod auth;
pub mod error;
pub mod session;
pub mod state;
pub mod time_bound;

pub use crate::url_path::seg;
pub use state::AppState;

use std::time::Duration;

use axum::extract::DefaultBodyLimit;
use axum::http::{HeaderName, Request, StatusCode};
use axum::Router;
use tower_http::request_id::{MakeRequestUuid, PropagateRequestIdLayer, SetRequestIdLayer};
use tower_http::trace::TraceLayer;

const REQUEST_ID: HeaderName = HeaderName::from_static("x-request-id");

/// The full service: the API's and the dashboard's routes side by side, a 404 in the error shape
/// for any other path, then auth ([`auth::authorize`]), the body limit, the request timeout,
/// request ids and tracing, and the headers that forbid framing and type sniffing
/// ([`security_headers`]), in that order from the inside out.
pub fn router(state: AppState, api: Router<AppState>, dashboard: Router<AppState>) -> Router {
    let timeout = Duration::from_secs(state.config.request_timeout_secs.max(1));
    let limit = state.config.body_limit_bytes;
    let routes = api
        .merge(dashboard)
        .fallback(|| async { error::ApiError::not_found("no such endpoint") })
        .layer(axum::middleware::from_fn_with_state(
            state.clone(),
            auth::authorize,
        ))
        .layer(DefaultBodyLimit::max(limit))
        .with_state(state);
    routes
        .layer(axum::middleware::from_fn_with_state(timeout, time_limit))
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
        .layer(axum::middleware::from_fn(security_headers))
        .layer(SetRequestIdLayer::new(REQUEST_ID, MakeRequestUuid))
}

/// Middleware: every answer (pages, API, assets, errors) may not be framed by any page
/// (`X-Frame-Options: DENY` and CSP `frame-ancestors 'none'`, against click-jacking of the
/// acknowledge button) nor read as another type than it says (`X-Content-Type-Options: nosniff`).
async fn security_headers(
    req: axum::extract::Request,
    next: axum::middleware::Next,
) -> axum::response::Response {
    use axum::http::header::{CONTENT_SECURITY_POLICY, X_CONTENT_TYPE_OPTIONS, X_FRAME_OPTIONS};
    use axum::http::HeaderValue;
    let mut response = next.run(req).await;
    let h = response.headers_mut();
    h.insert(X_FRAME_OPTIONS, HeaderValue::from_static("DENY"));
    h.insert(X_CONTENT_TYPE_OPTIONS, HeaderValue::from_static("nosniff"));
    h.entry(CONTENT_SECURITY_POLICY)
        .or_insert(HeaderValue::from_static("frame-ancestors 'none'"));
    response
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
