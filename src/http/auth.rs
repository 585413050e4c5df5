//! Bearer-token authentication with roles read < upload < admin. With no tokens configured every
//! request is allowed (the service then listens on loopback only, see [`crate::config::Config::check`]).
//!
//! The dashboard's pages follow the same roles: a browser signs in with a token through
//! `/signin` and then carries a session cookie ([`super::session`]); a change made
//! with the cookie must carry the session's CSRF token in `x-csrf-token` (htmx) or in the form's
//! `csrf` field (a form posted without JavaScript). A page asked for
//! without credentials redirects to the sign-in form. A change sent by a browser from another
//! site's page is refused in every mode ([`is_cross_site_change`]).

use axum::extract::{Request, State};
use axum::http::{header, Method, StatusCode};
use axum::middleware::Next;
use axum::response::{IntoResponse, Redirect, Response};

use super::error::ApiError;
use super::session;
use super::AppState;
use crate::config::Role;

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

/// The role a request needs: reads `read`, except the webhook endpoints' list, `admin` (their
/// URLs are often capabilities, such as a chat service's incoming-webhook URL); uploads and
/// acknowledgements `upload`; every other change `admin`. `None`: open (liveness, readiness,
/// the dashboard's assets and sign-in).
pub fn required_role(method: &Method, path: &str) -> Option<Role> {
    if path == "/healthz"
        || path == "/readyz"
        || path == "/signin"
        || path == "/signout"
        || path.starts_with("/assets/")
    {
        return None;
    }
    if path == "/api/v1/webhooks" || path.starts_with("/api/v1/webhooks/") {
        return Some(Role::Admin);
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

/// A change (not GET, HEAD or OPTIONS) that a browser sent from another site's page without a
/// bearer token: `Sec-Fetch-Site` says `cross-site` or `same-site`, or `Origin` names neither
/// this request's `Host` nor the configured `public_url` (a proxy may rewrite `Host`), or is
/// `null`. A page elsewhere could otherwise make the browser of someone on the service's machine
/// acknowledge an alarm (forms are sent without a preflight), even with no tokens configured.
/// Clients that are not browsers send neither header; a bearer token cannot be set by a form.
fn is_cross_site_change(req: &Request, public_url: Option<&str>) -> bool {
    if matches!(*req.method(), Method::GET | Method::HEAD | Method::OPTIONS)
        || req.headers().contains_key(header::AUTHORIZATION)
    {
        return false;
    }
    let h = req.headers();
    if let Some(site) = h.get("sec-fetch-site").and_then(|v| v.to_str().ok()) {
        return matches!(site, "cross-site" | "same-site");
    }
    let Some(origin) = h.get(header::ORIGIN) else {
        return false;
    };
    let origin = origin.to_str().unwrap_or("").to_ascii_lowercase();
    let origin_host = origin.split_once("://").map(|(_, rest)| rest).unwrap_or("");
    let host = h
        .get(header::HOST)
        .and_then(|v| v.to_str().ok())
        .map(str::to_ascii_lowercase);
    let public = public_url.and_then(origin_of);
    let same = host.as_deref() == Some(origin_host) || public.as_deref() == Some(origin.as_str());
    origin == "null" || !same
}

/// Whether the request's `Host` names this machine's loopback (`localhost`, `*.localhost`, a
/// loopback address) or `public_url`'s host; a request without `Host` (not a browser) passes.
/// Without tokens the server listens on loopback only, and this check stops DNS rebinding: a page
/// of `attacker.example` whose name is re-pointed at 127.0.0.1 sends same-origin requests with
/// `Host: attacker.example`, which the Origin check alone would let through.
fn is_local_host(req: &Request, public_url: Option<&str>) -> bool {
    let Some(host) = req.headers().get(header::HOST) else {
        return true;
    };
    let Ok(host) = host.to_str() else {
        return false;
    };
    let name = host_name(host).to_ascii_lowercase();
    let public = public_url
        .and_then(|u| url::Url::parse(u).ok())
        .and_then(|u| {
            u.host_str()
                .map(|h| h.trim_matches(['[', ']']).to_ascii_lowercase())
        });
    name == "localhost"
        || name.ends_with(".localhost")
        || name
            .parse::<std::net::IpAddr>()
            .is_ok_and(|ip| ip.is_loopback())
        || public.is_some_and(|p| p == name)
}

/// The name in a `Host` header value: without its port, and an IPv6 address without brackets.
fn host_name(host: &str) -> &str {
    if let Some(rest) = host.strip_prefix('[') {
        return rest.split(']').next().unwrap_or("");
    }
    match host.rsplit_once(':') {
        Some((name, port)) if port.bytes().all(|b| b.is_ascii_digit()) => name,
        _ => host,
    }
}

/// The origin (`scheme://host[:port]`, lower case, default port left out) of a URL, as browsers
/// send it in `Origin`.
fn origin_of(u: &str) -> Option<String> {
    let u = url::Url::parse(u).ok()?;
    Some(u.origin().ascii_serialization().to_ascii_lowercase())
}

/// Largest url-encoded form whose `csrf` field the middleware reads (bytes); the dashboard's
/// forms are far smaller.
const FORM_CSRF_LIMIT: usize = 64 * 1024;

/// The CSRF token a change carries: the `x-csrf-token` header (htmx), or else the `csrf` field
/// of a url-encoded form (a plain form post, without JavaScript). The form's body is read and
/// put back for the handler; a body over [`FORM_CSRF_LIMIT`] carries none.
async fn sent_csrf(req: Request) -> (Request, Option<String>) {
    if let Some(t) = req.headers().get("x-csrf-token") {
        let t = String::from_utf8_lossy(t.as_bytes()).into_owned();
        return (req, Some(t));
    }
    let is_form = req
        .headers()
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|v| v.starts_with("application/x-www-form-urlencoded"));
    if !is_form {
        return (req, None);
    }
    let (parts, body) = req.into_parts();
    let Ok(bytes) = axum::body::to_bytes(body, FORM_CSRF_LIMIT).await else {
        return (Request::from_parts(parts, axum::body::Body::empty()), None);
    };
    let token = url::form_urlencoded::parse(&bytes)
        .find(|(k, _)| k == "csrf")
        .map(|(_, v)| v.into_owned());
    (
        Request::from_parts(parts, axum::body::Body::from(bytes)),
        token,
    )
}

/// The request back if it carries the CSRF token of session `s` ([`sent_csrf`]); 403 if not.
async fn with_csrf_of(req: Request, s: &session::Session) -> Result<Request, ApiError> {
    let (req, sent) = sent_csrf(req).await;
    let sent = sent.unwrap_or_default();
    if session::constant_time_eq(sent.as_bytes(), s.csrf.as_bytes()) {
        Ok(req)
    } else {
        Err(ApiError::new(
            StatusCode::FORBIDDEN,
            "forbidden",
            "missing or wrong CSRF token (x-csrf-token header or csrf field)",
        ))
    }
}

/// Middleware: 401 for a missing or unknown token, 403 for a token without the role; pages
/// without credentials redirect to `/signin`.
pub async fn authorize(
    State(state): State<AppState>,
    mut req: Request,
    next: Next,
) -> Result<Response, ApiError> {
    if is_cross_site_change(&req, state.config.public_url.as_deref()) {
        return Err(ApiError::new(
            StatusCode::FORBIDDEN,
            "forbidden",
            "a change sent from another site's page is refused (Origin / Sec-Fetch-Site)",
        ));
    }
    let tokens = &state.config.tokens;
    if tokens.is_empty() {
        let open = required_role(req.method(), req.uri().path()).is_none();
        if !open && !is_local_host(&req, state.config.public_url.as_deref()) {
            return Err(ApiError::new(
                StatusCode::FORBIDDEN,
                "forbidden",
                "without tokens the server answers only requests addressed to a loopback name \
                 (localhost, 127.0.0.1, [::1]) or to public_url's host (Host header)",
            ));
        }
        req.extensions_mut().insert(Access::default());
        return Ok(next.run(req).await);
    }
    let Some(needed) = required_role(req.method(), req.uri().path()) else {
        // Signing out ends a live session, so it carries the session's CSRF token like any other
        // change and no other page can sign staff out; an expired or unknown cookie needs none.
        if req.uri().path() == "/signout" && *req.method() == Method::POST {
            let now = chrono::Utc::now().timestamp();
            if let Some(s) = session::from_headers(req.headers(), tokens, now) {
                req = with_csrf_of(req, &s).await?;
            }
        }
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
            match session::from_headers(req.headers(), tokens, now) {
                Some(s) => {
                    if !matches!(*req.method(), Method::GET | Method::HEAD) {
                        req = with_csrf_of(req, &s).await?;
                    }
                    Access {
                        role: Some(s.role),
                        csrf: Some(s.csrf),
                        cookie: true,
                    }
                }
                None if is_page(req.uri().path()) && *req.method() == Method::GET => {
                    let next = req.uri().path().to_string();
                    return Ok(Redirect::to(&format!("/signin?next={}", super::seg(&next)))
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
