//! Browser sessions of the dashboard when bearer tokens are configured: the sign-in form takes a
//! token and sets an HttpOnly, SameSite=Strict cookie; forms and htmx requests carry a CSRF token.
//!
//! Kept in the database ([`crate::store::sessions`]), so that every node behind a load balancer
//! and every restart accepts a live session and no node accepts an ended one. The cookie is a
//! random id of 256 bits from the operating system's CSPRNG, new at every sign-in; the database
//! holds only its SHA-256, with the name of the token signed in with ([`token_name`]: a
//! fingerprint, never the token) and its role. A session ends when it is signed out (its row is
//! deleted), when its token is no longer configured with the same role (checked at every
//! request), after `session_idle_minutes` without a request and `session_lifetime_hours` after
//! its sign-in. The CSRF token is HMAC-SHA256 of `csrf` keyed by the session id, so it is the
//! session's own and is stored nowhere.

use axum::http::{header, HeaderMap};
use chrono::{DateTime, TimeDelta, Utc};
use hmac::{Hmac, Mac};
use rand::RngCore;
use sha2::{Digest, Sha256};

use crate::config::{Config, Role, TokenConfig};
use crate::store::{sessions, Store, StoreError};

/// Name of the session cookie.
pub const COOKIE: &str = "cliffwatch_session";

/// Bytes of a session id (256 bits; 64 hex digits in the cookie).
const ID_BYTES: usize = 32;

/// Longest time a session is allowed to live or idle (ten years, in milliseconds): the bound
/// [`Config::check`] enforces, applied again so that no configuration overflows a time.
const MAX_MS: i64 = 10 * 366 * 24 * 3600 * 1000;

/// Last use is written at most this often per session (milliseconds), or half the idle timeout
/// when that is shorter: reading a page does not cost a write each time.
const TOUCH_EVERY_MS: i64 = 60_000;

/// A verified session.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Session {
    /// The role of the token signed in with.
    pub role: Role,
    /// The name of the token signed in with ([`token_name`]).
    pub token_name: String,
    /// The CSRF token every change must carry (`x-csrf-token` header or `csrf` form field).
    pub csrf: String,
}

/// When sessions end by time (from `session_idle_minutes` and `session_lifetime_hours`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Limits {
    /// Longest time without a request, milliseconds.
    pub idle_ms: i64,
    /// Longest time after sign-in, milliseconds.
    pub lifetime_ms: i64,
}

impl Limits {
    /// The limits `config` sets, each clamped to 0 … ten years.
    pub fn of(config: &Config) -> Limits {
        let ms = |v: f64| {
            if v.is_nan() {
                0
            } else {
                (v.clamp(0.0, MAX_MS as f64)) as i64
            }
        };
        Limits {
            idle_ms: ms(config.session_idle_minutes * 60_000.0),
            lifetime_ms: ms(config.session_lifetime_hours * 3_600_000.0),
        }
    }

    /// The cookie's `Max-Age`, seconds: the lifetime.
    pub fn max_age_secs(&self) -> i64 {
        self.lifetime_ms / 1000
    }
}

/// `t` moved back by `ms` milliseconds (the earliest time when that is out of range).
fn before(t: DateTime<Utc>, ms: i64) -> DateTime<Utc> {
    TimeDelta::try_milliseconds(ms)
        .and_then(|d| t.checked_sub_signed(d))
        .unwrap_or(DateTime::<Utc>::MIN_UTC)
}

fn mac(key: &str, message: &str) -> String {
    // HMAC accepts a key of any length, so this never fails.
    let mut m = match <Hmac<Sha256> as Mac>::new_from_slice(key.as_bytes()) {
        Ok(m) => m,
        Err(_) => return String::new(),
    };
    m.update(message.as_bytes());
    hex::encode(m.finalize().into_bytes())
}

/// The name a token is stored under: the first 16 hex digits of its SHA-256, which tells the
/// configured tokens apart without revealing one.
pub fn token_name(token: &str) -> String {
    hex::encode(Sha256::digest(token.as_bytes()))[..16].to_string()
}

fn role_name(role: Role) -> &'static str {
    match role {
        Role::Read => "read",
        Role::Upload => "upload",
        Role::Admin => "admin",
    }
}

fn role_of(name: &str) -> Option<Role> {
    [Role::Read, Role::Upload, Role::Admin]
        .into_iter()
        .find(|r| role_name(*r) == name)
}

/// A new session id: [`ID_BYTES`] from the operating system's CSPRNG, in hex.
fn new_id() -> String {
    let mut bytes = [0u8; ID_BYTES];
    rand::rngs::OsRng.fill_bytes(&mut bytes);
    hex::encode(bytes)
}

/// What the database keeps of a session id: its SHA-256, in hex.
pub fn id_hash(id: &str) -> String {
    hex::encode(Sha256::digest(id.as_bytes()))
}

/// Whether `value` can be a session id (64 lower-case hex digits): anything else is refused
/// before the database is asked.
fn well_formed(value: &str) -> bool {
    value.len() == 2 * ID_BYTES
        && value
            .bytes()
            .all(|b| matches!(b, b'0'..=b'9' | b'a'..=b'f'))
}

fn csrf_of(id: &str) -> String {
    mac(id, "csrf").chars().take(32).collect()
}

/// Signs in with the configured `token` at `now`: stores a new session and answers the cookie's
/// value (the session id). Sessions ended by time are deleted on the way.
pub async fn start(
    store: &Store,
    token: &TokenConfig,
    limits: &Limits,
    now: DateTime<Utc>,
) -> Result<String, StoreError> {
    let id = new_id();
    let mut tx = store.begin_write_rows().await?;
    sessions::delete_expired(
        &mut tx,
        before(now, limits.idle_ms),
        before(now, limits.lifetime_ms),
    )
    .await?;
    sessions::insert(
        &mut tx,
        &id_hash(&id),
        &token_name(&token.token),
        role_name(token.role),
        now,
    )
    .await?;
    tx.commit().await?;
    Ok(id)
}

/// The session of a cookie value, if it is stored, neither idle nor older than its lifetime at
/// `now`, and its token is still configured with the same role. Records its use.
pub async fn verify(
    store: &Store,
    value: &str,
    tokens: &[TokenConfig],
    limits: &Limits,
    now: DateTime<Utc>,
) -> Result<Option<Session>, StoreError> {
    if !well_formed(value) {
        return Ok(None);
    }
    let hash = id_hash(value);
    let Some(s) = sessions::find(store.reader(), &hash).await? else {
        return Ok(None);
    };
    let idle = (now - s.last_seen_at).num_milliseconds();
    let age = (now - s.created_at).num_milliseconds();
    if idle >= limits.idle_ms || age >= limits.lifetime_ms {
        return Ok(None);
    }
    let Some(role) = role_of(&s.role) else {
        return Ok(None);
    };
    let configured = tokens
        .iter()
        .any(|t| t.role == role && token_name(&t.token) == s.token_name);
    if !configured {
        return Ok(None);
    }
    if idle >= TOUCH_EVERY_MS.min(limits.idle_ms / 2) {
        let mut tx = store.begin_write_rows().await?;
        sessions::touch(&mut tx, &hash, now).await?;
        tx.commit().await?;
    }
    Ok(Some(Session {
        role,
        token_name: s.token_name.clone(),
        csrf: csrf_of(value),
    }))
}

/// Ends the session whose cookie value is `value` (signing out): its row is deleted, so no copy
/// of the cookie is a session any more.
pub async fn end(store: &Store, value: &str) -> Result<(), StoreError> {
    if !well_formed(value) {
        return Ok(());
    }
    let mut tx = store.begin_write_rows().await?;
    sessions::delete(&mut tx, &id_hash(value)).await?;
    tx.commit().await?;
    Ok(())
}

/// The session cookie's value among the `Cookie` header's pairs.
pub fn cookie_value(cookie_header: &str) -> Option<&str> {
    cookie_header.split(';').find_map(|kv| {
        let (k, v) = kv.trim().split_once('=')?;
        (k == COOKIE).then_some(v)
    })
}

/// The session cookie's value in a request's `Cookie` headers, if any.
pub fn cookie_of(headers: &HeaderMap) -> Option<&str> {
    headers
        .get_all(header::COOKIE)
        .iter()
        .filter_map(|v| v.to_str().ok())
        .find_map(cookie_value)
}

/// The live session carried by a request's `Cookie` headers, if any (see [`verify`]).
pub async fn from_headers(
    store: &Store,
    headers: &HeaderMap,
    tokens: &[TokenConfig],
    limits: &Limits,
    now: DateTime<Utc>,
) -> Result<Option<Session>, StoreError> {
    match cookie_of(headers) {
        Some(c) => verify(store, c, tokens, limits, now).await,
        None => Ok(None),
    }
}

/// Compares without an early exit.
pub fn constant_time_eq(a: &[u8], b: &[u8]) -> bool {
    a.len() == b.len() && a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_are_random_and_only_well_formed_ones_are_looked_up() {
        let (a, b) = (new_id(), new_id());
        assert_ne!(a, b);
        assert!(well_formed(&a) && well_formed(&b));
        assert_ne!(id_hash(&a), a);
        assert_ne!(csrf_of(&a), csrf_of(&b));
        assert_eq!(csrf_of(&a).len(), 32);
        for bad in ["", "x.y.z", &a[..63], &a.to_uppercase(), &format!("{a}0")] {
            assert!(!well_formed(bad), "{bad}");
        }
        assert_eq!(
            cookie_value(&format!("a=b; {COOKIE}={a}; d=e")),
            Some(a.as_str())
        );
        for r in [Role::Read, Role::Upload, Role::Admin] {
            assert_eq!(role_of(role_name(r)), Some(r));
        }
        assert_eq!(role_of("root"), None);
    }

    #[test]
    fn limits_never_overflow() {
        let mut c = Config::with_data_dir("/nonexistent");
        c.session_idle_minutes = f64::NAN;
        c.session_lifetime_hours = 1e300;
        let l = Limits::of(&c);
        assert_eq!(l.idle_ms, 0);
        assert_eq!(l.lifetime_ms, MAX_MS);
        let now = Utc::now();
        assert!(before(now, l.lifetime_ms) < now);
        assert_eq!(
            before(DateTime::<Utc>::MIN_UTC, 1),
            DateTime::<Utc>::MIN_UTC
        );
    }
}
