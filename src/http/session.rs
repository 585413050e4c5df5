//! Browser sessions of the dashboard when bearer tokens are configured: the sign-in form takes a
//! token and sets an HttpOnly, SameSite=Strict cookie; forms and htmx requests carry a CSRF token.
//!
//! Stateless, so every node behind a load balancer and every restart accepts the same cookie:
//! the cookie is `<fingerprint>.<expiry>.<mac>`, where the fingerprint (first 16 hex digits of
//! SHA-256 of the token) names the token without revealing it and the mac is HMAC-SHA256 of
//! `session|<expiry>` keyed by the token itself. The CSRF token is HMAC-SHA256 of
//! `csrf|<expiry>` under the same key. Removing a token from the configuration ends its sessions.

use axum::http::{header, HeaderMap};
use hmac::{Hmac, Mac};
use sha2::{Digest, Sha256};

use crate::config::{Role, TokenConfig};

/// Name of the session cookie.
pub const COOKIE: &str = "cliffwatch_session";

/// Lifetime of a session, seconds (12 hours: one shift).
pub const LIFETIME_SECS: i64 = 12 * 3600;

/// A verified session.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Session {
    /// The role of the token signed in with.
    pub role: Role,
    /// The CSRF token every change must carry (`x-csrf-token` header or `csrf` form field).
    pub csrf: String,
}

fn mac(token: &str, message: &str) -> String {
    let mut m = <Hmac<Sha256> as Mac>::new_from_slice(token.as_bytes())
        .expect("HMAC takes keys of any length");
    m.update(message.as_bytes());
    hex::encode(m.finalize().into_bytes())
}

fn fingerprint(token: &str) -> String {
    hex::encode(Sha256::digest(token.as_bytes()))[..16].to_string()
}

/// The cookie value of a new session for `token`, valid until `now + LIFETIME_SECS` (unix s).
pub fn issue(token: &str, now: i64) -> String {
    let exp = now + LIFETIME_SECS;
    format!(
        "{}.{exp}.{}",
        fingerprint(token),
        mac(token, &format!("session|{exp}"))
    )
}

/// The session of a cookie value, if it is intact, unexpired at `now` (unix s) and its token is
/// still configured.
pub fn verify(value: &str, tokens: &[TokenConfig], now: i64) -> Option<Session> {
    let mut parts = value.split('.');
    let (fp, exp, m) = (parts.next()?, parts.next()?, parts.next()?);
    if parts.next().is_some() {
        return None;
    }
    let exp_s: i64 = exp.parse().ok()?;
    if exp_s <= now {
        return None;
    }
    let t = tokens.iter().find(|t| fingerprint(&t.token) == fp)?;
    let expected = mac(&t.token, &format!("session|{exp}"));
    if !constant_time_eq(expected.as_bytes(), m.as_bytes()) {
        return None;
    }
    Some(Session {
        role: t.role,
        csrf: mac(&t.token, &format!("csrf|{exp}"))[..32].to_string(),
    })
}

/// The session cookie's value among the `Cookie` header's pairs.
pub fn cookie_value(cookie_header: &str) -> Option<&str> {
    cookie_header.split(';').find_map(|kv| {
        let (k, v) = kv.trim().split_once('=')?;
        (k == COOKIE).then_some(v)
    })
}

/// The live session carried by a request's `Cookie` headers, if any (see [`verify`]).
pub fn from_headers(headers: &HeaderMap, tokens: &[TokenConfig], now: i64) -> Option<Session> {
    headers
        .get_all(header::COOKIE)
        .iter()
        .filter_map(|v| v.to_str().ok())
        .find_map(cookie_value)
        .and_then(|c| verify(c, tokens, now))
}

/// Compares without an early exit.
pub fn constant_time_eq(a: &[u8], b: &[u8]) -> bool {
    a.len() == b.len() && a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tokens() -> Vec<TokenConfig> {
        vec![
            TokenConfig {
                token: "reader-secret".into(),
                role: Role::Read,
            },
            TokenConfig {
                token: "uploader-secret".into(),
                role: Role::Upload,
            },
        ]
    }

    #[test]
    fn a_session_names_its_role_and_expires() {
        let c = issue("uploader-secret", 1000);
        assert!(!c.contains("uploader-secret"));
        let s = verify(&c, &tokens(), 1001).expect("valid");
        assert_eq!(s.role, Role::Upload);
        assert_eq!(s.csrf.len(), 32);
        assert!(verify(&c, &tokens(), 1000 + LIFETIME_SECS).is_none());
        // A token removed from the configuration ends its sessions.
        assert!(verify(&c, &tokens()[..1], 1001).is_none());
    }

    #[test]
    fn tampered_cookies_are_refused() {
        let c = issue("reader-secret", 1000);
        let (fp, rest) = c.split_once('.').unwrap();
        let (_, m) = rest.split_once('.').unwrap();
        // A later expiry with the old mac, another token's fingerprint, garbage.
        assert!(verify(&format!("{fp}.99999999.{m}"), &tokens(), 1001).is_none());
        let other = issue("uploader-secret", 1000);
        let ofp = other.split('.').next().unwrap();
        assert!(verify(&format!("{ofp}.{rest}"), &tokens(), 1001).is_none());
        assert!(verify("x.y.z", &tokens(), 1001).is_none());
        assert!(verify("", &tokens(), 1001).is_none());
        assert_eq!(
            cookie_value(&format!("a=b; {COOKIE}={c}; d=e")),
            Some(c.as_str())
        );
    }
}
