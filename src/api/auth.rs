//! Bearer-token authentication with roles read < upload < admin. With no tokens configured every
//! request is allowed (the service then listens on loopback only, see [`crate::config::Config::check`]).

use axum::extract::{Request, State};
use axum::http::{header, Method, StatusCode};
use axum::middleware::Next;
use axum::response::Response;

use super::error::ApiError;
use super::AppState;
use crate::config::Role;

/// The role a request needs: reads `read`; uploads and acknowledgements `upload`; every other
/// change `admin`. `None`: open (liveness and readiness).
pub fn required_role(method: &Method, path: &str) -> Option<Role> {
    if path == "/healthz" || path == "/readyz" {
        return None;
    }
    if method == Method::GET || method == Method::HEAD || method == Method::OPTIONS {
        return Some(Role::Read);
    }
    let upload =
        (method == Method::POST && path.starts_with("/api/v1/sites/") && path.ends_with("/epochs"))
            || (method == Method::POST
                && path.starts_with("/api/v1/alerts/")
                && path.ends_with("/ack"));
    Some(if upload { Role::Upload } else { Role::Admin })
}

/// Middleware: 401 for a missing or unknown token, 403 for a token without the role.
pub async fn authorize(
    State(state): State<AppState>,
    req: Request,
    next: Next,
) -> Result<Response, ApiError> {
    let tokens = &state.config.tokens;
    if tokens.is_empty() {
        return Ok(next.run(req).await);
    }
    let Some(needed) = required_role(req.method(), req.uri().path()) else {
        return Ok(next.run(req).await);
    };
    let presented = req
        .headers()
        .get(header::AUTHORIZATION)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| {
            v.strip_prefix("Bearer ")
                .or_else(|| v.strip_prefix("bearer "))
        })
        .map(str::trim);
    let Some(presented) = presented else {
        return Err(ApiError::new(
            StatusCode::UNAUTHORIZED,
            "unauthorized",
            "missing bearer token",
        ));
    };
    let role = tokens
        .iter()
        .find(|t| constant_time_eq(t.token.as_bytes(), presented.as_bytes()))
        .map(|t| t.role);
    match role {
        None => Err(ApiError::new(
            StatusCode::UNAUTHORIZED,
            "unauthorized",
            "unknown bearer token",
        )),
        Some(role) if role < needed => Err(ApiError::new(
            StatusCode::FORBIDDEN,
            "forbidden",
            format!("this token's role {role:?} lacks {needed:?}").to_lowercase(),
        )),
        Some(_) => Ok(next.run(req).await),
    }
}

fn constant_time_eq(a: &[u8], b: &[u8]) -> bool {
    a.len() == b.len() && a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}
