//! Bearer-token authentication with roles read < upload < admin. With no tokens configured every
//! request is allowed (the service then listens on loopback only, see [`crate::config::Config::check`]).
//!
//! The dashboard's pages follow the same roles: a browser signs in with a token through
//! `/signin` and then carries a session cookie ([`crate::dashboard::session`]); a change made
//! with the cookie must carry the session's CSRF token in `x-csrf-token`. A page asked for
//! without credentials redirects to the sign-in form.

use axum::extract::{Request, State};
use axum::http::{header, Method, StatusCode};
use axum::middleware::Next;
use axum::response::{IntoResponse, Redirect, Response};

use super::error::ApiError;
use super::AppState;
use crate::config::Role;
use crate::dashboard::session;

/// What the request was allowed as, for handlers that adapt to it (the dashboard's pages).
#[derive(Debug, Clone, Default)]
pub struct Access {
    /// The role of the credentials (None: no tokens configured, everything allowed).
    pub role: Option<Role>,
    /// CSRF token of a cookie session.
    pub csrf: Option<String>,
    /// Authenticated by the session cookie.
    pub cookie: bool,
}

impl Access {
    /// Whether the request may do what `role` allows.
    pub fn allows(&self, role: Role) -> bool {
        self.role.is_none_or(|r| r >= role)
    }
}

/// The role a request needs: reads `read`; uploads and acknowledgements `upload`; every other
/// change `admin`. `None`: open (liveness, readiness, the dashboard's assets and sign-in).
pub fn required_role(method: &Method, path: &str) -> Option<Role> {
    if path == "/healthz"
        || path == "/readyz"
        || path == "/signin"
        || path == "/signout"
        || path.starts_with("/assets/")
    {
        return None;
    }
    if method == Method::GET || method == Method::HEAD || method == Method::OPTIONS {
        return Some(Role::Read);
    }
    let upload =
        (method == Method::POST && path.starts_with("/api/v1/sites/") && path.ends_with("/epochs"))
            || (method == Method::POST
                && (path.starts_with("/api/v1/alerts/") || path.starts_with("/dashboard/alerts/"))
                && path.ends_with("/ack"));
    Some(if upload { Role::Upload } else { Role::Admin })
}

/// A dashboard page (HTML), as opposed to the API, metrics or assets.
fn is_page(path: &str) -> bool {
    !(path.starts_with("/api/") || path == "/metrics" || path.starts_with("/dashboard/plot"))
}

/// Middleware: 401 for a missing or unknown token, 403 for a token without the role; pages
/// without credentials redirect to `/signin`.
pub async fn authorize(
    State(state): State<AppState>,
    mut req: Request,
    next: Next,
) -> Result<Response, ApiError> {
    let tokens = &state.config.tokens;
    if tokens.is_empty() {
        req.extensions_mut().insert(Access::default());
        return Ok(next.run(req).await);
    }
    let Some(needed) = required_role(req.method(), req.uri().path()) else {
        return Ok(next.run(req).await);
    };
    let bearer = req
        .headers()
        .get(header::AUTHORIZATION)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| {
            v.strip_prefix("Bearer ")
                .or_else(|| v.strip_prefix("bearer "))
        })
        .map(str::trim);
    let access = match bearer {
        Some(presented) => {
            let role = tokens
                .iter()
                .find(|t| session::constant_time_eq(t.token.as_bytes(), presented.as_bytes()))
                .map(|t| t.role);
            let Some(role) = role else {
                return Err(ApiError::new(
                    StatusCode::UNAUTHORIZED,
                    "unauthorized",
                    "unknown bearer token",
                ));
            };
            Access {
                role: Some(role),
                csrf: None,
                cookie: false,
            }
        }
        None => {
            let now = chrono::Utc::now().timestamp();
            let found = req
                .headers()
                .get_all(header::COOKIE)
                .iter()
                .filter_map(|v| v.to_str().ok())
                .find_map(session::cookie_value)
                .and_then(|c| session::verify(c, tokens, now));
            match found {
                Some(s) => {
                    let safe = matches!(*req.method(), Method::GET | Method::HEAD);
                    let sent = req
                        .headers()
                        .get("x-csrf-token")
                        .map(|v| v.as_bytes())
                        .unwrap_or_default();
                    if !safe && !session::constant_time_eq(sent, s.csrf.as_bytes()) {
                        return Err(ApiError::new(
                            StatusCode::FORBIDDEN,
                            "forbidden",
                            "missing or wrong CSRF token (x-csrf-token)",
                        ));
                    }
                    Access {
                        role: Some(s.role),
                        csrf: Some(s.csrf),
                        cookie: true,
                    }
                }
                None if is_page(req.uri().path()) && *req.method() == Method::GET => {
                    let next = req.uri().path().to_string();
                    return Ok(Redirect::to(&format!(
                        "/signin?next={}",
                        crate::dashboard::layout::seg(&next)
                    ))
                    .into_response());
                }
                None => {
                    return Err(ApiError::new(
                        StatusCode::UNAUTHORIZED,
                        "unauthorized",
                        "missing bearer token",
                    ))
                }
            }
        }
    };
    match access.role {
        Some(role) if role < needed => Err(ApiError::new(
            StatusCode::FORBIDDEN,
            "forbidden",
            format!("this token's role {role:?} lacks {needed:?}").to_lowercase(),
        )),
        _ => {
            req.extensions_mut().insert(access);
            Ok(next.run(req).await)
        }
    }
}
