//! Time as the store keeps it (fixed-width RFC 3339 text, UTC, microseconds), the store's clock,
//! and the API's shorter form of a stored time.

use chrono::{DateTime, SecondsFormat, Utc};
use sqlx::AnyConnection;

use super::dialect::is_postgres;
use super::error::StoreError;

/// Formats a time the way the store keeps it: RFC 3339, UTC, microseconds (sorts as text).
pub fn timestamp(t: DateTime<Utc>) -> String {
    t.to_rfc3339_opts(SecondsFormat::Micros, true)
}

/// The current time in the store's format, on the store's [`clock`], so that the times rows
/// record (`created_at`, `updated_at`, …) keep their order whichever node wrote them.
pub async fn now(db: &mut AnyConnection) -> Result<String, StoreError> {
    Ok(timestamp(clock(db).await?))
}

/// The clock that webhook deliveries' due times and leases are written and compared with, the
/// same for every node: on PostgreSQL the database server's (`clock_timestamp()`), so nodes
/// whose clocks disagree never read a live claim as expired nor a new delivery as not yet due;
/// on SQLite (one node) this node's.
pub async fn clock(db: &mut AnyConnection) -> Result<DateTime<Utc>, StoreError> {
    if !is_postgres(db) {
        return Ok(Utc::now());
    }
    let micros: i64 = sqlx::query_scalar(
        "SELECT CAST(EXTRACT(EPOCH FROM clock_timestamp()) * 1000000 AS BIGINT)",
    )
    .fetch_one(&mut *db)
    .await?;
    DateTime::from_timestamp_micros(micros)
        .ok_or_else(|| StoreError::Corrupt(format!("database clock out of range: {micros} µs")))
}

/// Parses a stored time.
pub fn parse_timestamp(s: &str) -> Option<DateTime<Utc>> {
    DateTime::parse_from_rfc3339(s)
        .ok()
        .map(|t| t.with_timezone(&Utc))
}

/// Formats a stored time for the API: RFC 3339 with `Z`, seconds unless sub-second.
pub fn display_timestamp(s: &str) -> String {
    if let Some(short) = shortened(s.as_bytes()) {
        let mut out = String::with_capacity(short.len() + 1);
        out.push_str(std::str::from_utf8(short).unwrap_or_default());
        out.push('Z');
        return out;
    }
    parse_timestamp(s)
        .map(|t| t.to_rfc3339_opts(SecondsFormat::AutoSi, true))
        .unwrap_or_else(|| s.to_string())
}

/// The API form of a time kept in the store's own form (`YYYY-MM-DDTHH:MM:SS.ffffffZ`, as
/// [`timestamp`] writes it), without its final `Z`: the fraction dropped when zero, cut to
/// milliseconds when whole, as chrono's `AutoSi` prints it. `None` for any other text.
pub fn shortened(stored: &[u8]) -> Option<&[u8]> {
    let digits = |r: std::ops::Range<usize>| stored[r].iter().all(u8::is_ascii_digit);
    let store_form = stored.len() == 27
        && digits(0..4)
        && stored[4] == b'-'
        && digits(5..7)
        && stored[7] == b'-'
        && digits(8..10)
        && stored[10] == b'T'
        && digits(11..13)
        && stored[13] == b':'
        && digits(14..16)
        && stored[16] == b':'
        && digits(17..19)
        && stored[19] == b'.'
        && digits(20..26)
        && stored[26] == b'Z';
    if !store_form {
        return None;
    }
    let end = if &stored[20..26] == b"000000" {
        19
    } else if &stored[23..26] == b"000" {
        23
    } else {
        26
    };
    Some(&stored[..end])
}
