//! `GET /signin`, `POST /signin`, `POST /signout`: a browser signs in with one of the configured
//! bearer tokens and gets a session cookie ([`crate::http::session`]: HttpOnly, SameSite=Strict, a
//! random id stored hashed, ended by signing out, by removing its token, and by the configured
//! idle timeout and lifetime). Without configured tokens everything is open and the form is not
//! needed.

use axum::extract::{Query, State};
use axum::http::{header, HeaderMap, StatusCode};
use axum::response::{Html, IntoResponse, Redirect, Response};
use axum::Form;
use maud::html;
use serde::Deserialize;

use super::layout::{page, Viewer};
use crate::http::error::ApiError;
use crate::http::session;
use crate::http::AppState;

/// Where to go after signing in.
#[derive(Debug, Deserialize)]
pub struct NextParam {
    /// A path of this site (starting with one `/`); anything else goes to `/`.
    pub next: Option<String>,
}

/// The sign-in form's fields.
#[derive(Debug, Deserialize)]
pub struct SignInForm {
    /// A configured bearer token.
    pub token: String,
    /// Where to go afterwards.
    #[serde(default)]
    pub next: Option<String>,
}

/// Where to go after signing in: a path on this service, else `/`. Browsers drop tabs and line
/// breaks and read `\\` as `/` when they parse a URL, so `/\t/host` would leave the service.
fn safe_next(next: Option<&str>) -> String {
    match next {
        Some(n)
            if n.starts_with('/')
                && !n.starts_with("//")
                && !n
                    .chars()
                    .any(|c| c == '\\' || c.is_whitespace() || c.is_control()) =>
        {
            n.to_string()
        }
        _ => "/".to_string(),
    }
}

fn form_page(next: &str, failed: bool) -> String {
    page(
        "Sign in",
        &[],
        &Viewer::default(),
        html! {
            h1 { "Sign in" }
            @if failed { p.error { "That token is not valid." } }
            form.signin method="post" action="/signin" {
                label { "Token " input type="password" name="token" autocomplete="current-password" required; }
                input type="hidden" name="next" value=(next);
                button type="submit" { "sign in" }
            }
        },
    )
    .into_string()
}

/// `GET /signin`.
pub async fn form(State(state): State<AppState>, Query(q): Query<NextParam>) -> Response {
    let next = safe_next(q.next.as_deref());
    if state.config.tokens.is_empty() {
        return Redirect::to(&next).into_response();
    }
    Html(form_page(&next, false)).into_response()
}

/// `POST /signin`: a valid token sets the session cookie and redirects; another answers 401
/// with the form again.
pub async fn sign_in(State(state): State<AppState>, Form(f): Form<SignInForm>) -> Response {
    let next = safe_next(f.next.as_deref());
    let known = state
        .config
        .tokens
        .iter()
        .find(|t| session::constant_time_eq(t.token.as_bytes(), f.token.trim().as_bytes()));
    let Some(token) = known else {
        return (StatusCode::UNAUTHORIZED, Html(form_page(&next, true))).into_response();
    };
    let limits = session::Limits::of(&state.config);
    let value = match session::start(&state.store, token, &limits, chrono::Utc::now()).await {
        Ok(v) => v,
        Err(e) => return ApiError::from(e).into_response(),
    };
    // Behind HTTPS (as `public_url` says) the cookie is never sent over plain HTTP.
    let secure = state
        .config
        .public_url
        .as_deref()
        .is_some_and(|u| u.starts_with("https://"));
    let cookie = format!(
        "{}={value}; Path=/; HttpOnly; SameSite=Strict; Max-Age={}{}",
        session::COOKIE,
        limits.max_age_secs(),
        if secure { "; Secure" } else { "" }
    );
    (
        StatusCode::SEE_OTHER,
        [(header::SET_COOKIE, cookie), (header::LOCATION, next)],
    )
        .into_response()
}

/// `POST /signout`: ends the session in the database, so that no copy of the cookie is a session
/// any more, and clears the cookie. The auth middleware has checked the form's `csrf` field when
/// the cookie is a live session ([`crate::http::auth`]); a cookie that is no live session has
/// nothing left to end.
pub async fn sign_out(State(state): State<AppState>, headers: HeaderMap) -> Response {
    if let Some(value) = session::cookie_of(&headers) {
        if let Err(e) = session::end(&state.store, value).await {
            return ApiError::from(e).into_response();
        }
    }
    let cookie = format!(
        "{}=; Path=/; HttpOnly; SameSite=Strict; Max-Age=0",
        session::COOKIE
    );
    (
        StatusCode::SEE_OTHER,
        [
            (header::SET_COOKIE, cookie),
            (header::LOCATION, "/signin".to_string()),
        ],
    )
        .into_response()
}
