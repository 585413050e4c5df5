//! Bearer-token authentication with roles read < upload < admin. With no tokens configured every
//! request is allowed (the service then listens on loopback only, see [`crate::config::Config::check`]).
//!
//! The dashboard's pages follow the same roles: a browser signs in with a token through
//! `/signin` and then carries a session cookie ([`super::session`]); a change made
//! with the cookie must carry the session's CSRF token in `x-csrf-token` (htmx) or in the form's
//! `csrf` field (a form posted without JavaScript). A page asked for
//! without credentials redirects to the sign-in form. A change sent by a browser from another
//! site's page is refused in every mode, with or without a token ([`is_cross_site_change`]).

use axum::extract::{Request, State};
use axum::http::{header, Method, StatusCode};
use axum::middleware::Next;
use axum::response::{IntoResponse, Redirect, Response};

use super::error::ApiError;
use super::session;
use super::state::AppState;
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
    /// Who, for the audit trail: `token <first 16 hex digits of its SHA-256> (<role>)` (never
    /// the token); `None` without tokens configured.
    pub who: Option<String>,
}

impl Access {
    /// The actor of a change made with these credentials through `source` (`api`, `page`).
    pub fn actor(&self, source: &'static str) -> crate::service::site_admin::Actor {
        crate::service::site_admin::Actor {
            who: self.who.clone().unwrap_or_else(|| "anonymous".to_string()),
            source,
        }
    }
}

impl Access {
    /// Whether the request may do what `role` allows.
    pub fn allows(&self, role: Role) -> bool {
        self.role.is_none_or(|r| r >= role)
    }
}

/// The role a request needs: reads and the pre-analyses (`POST /api/v1/plan`, `POST
/// /api/v1/sites/{site}/plan`) `read`, except the webhook endpoints' list, `admin` (their
/// URLs are often capabilities, such as a chat service's incoming-webhook URL), and a site's
/// export, `admin` (it is recorded and opens the way to the site's deletion); uploads and
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
    // A site's export records itself (and opens the way to its deletion): admin, as the deletion.
    if path == "/api/v1/webhooks"
        || path.starts_with("/api/v1/webhooks/")
        || (path.starts_with("/api/v1/sites/") && path.ends_with("/export"))
    {
        return Some(Role::Admin);
    }
    if method == Method::GET || method == Method::HEAD || method == Method::OPTIONS {
        return Some(Role::Read);
    }
    // The pre-analyses compute and store nothing: a reader may ask them.
    if method == Method::POST
        && (path == "/api/v1/plan"
            || (path.starts_with("/api/v1/sites/")
                && path.ends_with("/plan")
                && path.split('/').count() == 6))
    {
        return Some(Role::Read);
    }
    let upload =
        (method == Method::POST && path.starts_with("/api/v1/sites/") && path.ends_with("/epochs"))
            || (method == Method::POST
                && (path.starts_with("/api/v1/alerts/")
                    || path.starts_with("/dashboard/alerts/")
                    || (path.starts_with("/api/v1/sites/") && path.contains("/incidents/"))
                    || (path.starts_with("/dashboard/sites/") && path.contains("/incidents/")))
                && path.ends_with("/ack"));
    Some(if upload { Role::Upload } else { Role::Admin })
}

/// A dashboard page (HTML), as opposed to the API, metrics or assets.
fn is_page(path: &str) -> bool {
    !(path.starts_with("/api/") || path == "/metrics" || path.starts_with("/dashboard/plot"))
}

/// A change (not GET, HEAD or OPTIONS) that a browser sent from another site's page, with or
/// without a bearer token: `Sec-Fetch-Site` says `cross-site` or `same-site`, or `Origin` is
/// `null` or is neither this service's own origin (`http://` and the request's `Host`: the
/// service speaks plain HTTP) nor the configured `public_url`'s (a proxy may rewrite `Host` and
/// end TLS). Origins are compared whole, scheme, host and port (a default port written or not),
/// as browsers define them. A page elsewhere could otherwise make the browser of someone on the
/// service's machine acknowledge an alarm (forms are sent without a preflight), even with no
/// tokens configured. Clients that are not browsers send neither header.
fn is_cross_site_change(req: &Request, public_url: Option<&str>) -> bool {
    if matches!(*req.method(), Method::GET | Method::HEAD | Method::OPTIONS) {
        return false;
    }
    let h = req.headers();
    if let Some(site) = h.get("sec-fetch-site").and_then(|v| v.to_str().ok()) {
        if matches!(site, "cross-site" | "same-site") {
            return true;
        }
    }
    let Some(origin) = h.get(header::ORIGIN) else {
        return false;
    };
    let Some(origin) = origin.to_str().ok().and_then(origin_of) else {
        // `null` (a sandboxed or opaque page) and anything that is not an origin
        return true;
    };
    let own = h
        .get(header::HOST)
        .and_then(|v| v.to_str().ok())
        .and_then(|host| origin_of(&format!("http://{host}")));
    let public = public_url.and_then(origin_of);
    own.as_deref() != Some(origin.as_str()) && public.as_deref() != Some(origin.as_str())
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
/// `None` for a URL without a host (an opaque origin such as `null` or `data:`).
fn origin_of(u: &str) -> Option<String> {
    let u = url::Url::parse(u).ok()?;
    let origin = u.origin();
    origin
        .is_tuple()
        .then(|| origin.ascii_serialization().to_ascii_lowercase())
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
            let limits = session::Limits::of(&state.config);
            let now = chrono::Utc::now();
            let live =
                session::from_headers(&state.store, req.headers(), tokens, &limits, now).await?;
            if let Some(s) = live {
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
                who: Some(format!(
                    "token {} ({})",
                    session::token_name(presented),
                    format!("{role:?}").to_lowercase()
                )),
            }
        }
        None => {
            let limits = session::Limits::of(&state.config);
            let now = chrono::Utc::now();
            let live =
                session::from_headers(&state.store, req.headers(), tokens, &limits, now).await?;
            match live {
                Some(s) => {
                    if !matches!(*req.method(), Method::GET | Method::HEAD) {
                        req = with_csrf_of(req, &s).await?;
                    }
                    Access {
                        who: Some(format!(
                            "token {} ({})",
                            s.token_name,
                            format!("{:?}", s.role).to_lowercase()
                        )),
                        role: Some(s.role),
                        csrf: Some(s.csrf),
                        cookie: true,
                    }
                }
                None if is_page(req.uri().path()) && *req.method() == Method::GET => {
                    let next = req.uri().path().to_string();
                    return Ok(Redirect::to(&format!(
                        "/signin?next={}",
                        crate::url_path::seg(&next)
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

#[cfg(test)]
mod tests {
    use super::*;

    fn change(headers: &[(&str, &str)]) -> Request {
        let mut b = axum::http::Request::builder()
            .method(Method::POST)
            .uri("/dashboard/alerts/a/ack");
        for (k, v) in headers {
            b = b.header(*k, *v);
        }
        b.body(axum::body::Body::empty()).unwrap()
    }

    /// The Origin must equal the service's own origin or `public_url`'s in scheme, host and port;
    /// a bearer token does not exempt a browser's change from another page.
    #[test]
    fn origins_compare_scheme_host_and_port() {
        let host = ("host", "127.0.0.1:8080");
        let cases = [
            ("http://127.0.0.1:8080", false),
            ("HTTP://127.0.0.1:8080", false),
            ("https://127.0.0.1:8080", true),
            ("http://127.0.0.1:8081", true),
            ("http://127.0.0.1", true),
            ("http://localhost:8080", true),
            ("null", true),
            ("not a url", true),
        ];
        for (origin, refused) in cases {
            let req = change(&[host, ("origin", origin)]);
            assert_eq!(is_cross_site_change(&req, None), refused, "{origin}");
            let req = change(&[host, ("origin", origin), ("authorization", "Bearer t")]);
            assert_eq!(
                is_cross_site_change(&req, None),
                refused,
                "{origin} with a token"
            );
        }
        // A default port is the same origin written or not.
        let req = change(&[
            ("host", "cliff.example:80"),
            ("origin", "http://cliff.example"),
        ]);
        assert!(!is_cross_site_change(&req, None));
        // Behind a TLS proxy: the public URL's origin, and only with its scheme.
        let public = Some("https://cliff.example/");
        let req = change(&[host, ("origin", "https://cliff.example")]);
        assert!(!is_cross_site_change(&req, public));
        let req = change(&[host, ("origin", "http://cliff.example")]);
        assert!(is_cross_site_change(&req, public));
        // Fetch metadata decides first; reads are never refused; non-browsers send neither.
        let req = change(&[host, ("sec-fetch-site", "cross-site")]);
        assert!(is_cross_site_change(&req, None));
        assert!(!is_cross_site_change(&change(&[host]), None));
        let mut get = change(&[host, ("origin", "http://evil.example")]);
        *get.method_mut() = Method::GET;
        assert!(!is_cross_site_change(&get, None));
    }
}
