//! Time bounds of a query (`from`, `to`): RFC 3339 or a date, read into the store's text format,
//! for the API's series and the dashboard's report alike.

use super::error::ApiError;
use crate::store::{parse_timestamp, timestamp};

/// Parses a time bound of a query (RFC 3339 or a date) into the store's format. A bound beyond
/// the years 0000–9999 in UTC (which the store's four-digit years cannot write) is moved to the
/// nearest end of that range, where it excludes no stored time, as its true value would not.
pub fn time_bound(s: &str, end_of_day: bool) -> Result<String, ApiError> {
    Ok(stored_bound(parse_time_bound(s, end_of_day)?))
}

/// `t` as a time bound in the store's format, moved into the years 0000–9999 as
/// [`time_bound`] does.
pub fn stored_bound(t: chrono::DateTime<chrono::Utc>) -> String {
    timestamp(t.clamp(stored_time_min(), stored_time_max()))
}

/// The earliest time the store can write: 0000-01-01T00:00:00Z.
fn stored_time_min() -> chrono::DateTime<chrono::Utc> {
    chrono::NaiveDate::from_ymd_opt(0, 1, 1)
        .and_then(|d| d.and_hms_opt(0, 0, 0))
        .expect("a valid time")
        .and_utc()
}

/// The latest time the store can write: 9999-12-31T23:59:59.999999Z.
fn stored_time_max() -> chrono::DateTime<chrono::Utc> {
    chrono::NaiveDate::from_ymd_opt(9999, 12, 31)
        .and_then(|d| d.and_hms_micro_opt(23, 59, 59, 999_999))
        .expect("a valid time")
        .and_utc()
}

fn parse_time_bound(s: &str, end_of_day: bool) -> Result<chrono::DateTime<chrono::Utc>, ApiError> {
    if let Some(t) = parse_timestamp(s) {
        return Ok(t);
    }
    let date = chrono::NaiveDate::parse_from_str(s, "%Y-%m-%d").map_err(|_| {
        ApiError::bad_request(format!(
            "'{}' is not an RFC 3339 time or a date",
            cliffwatch_core::contract::truncate_for_message(s)
        ))
    })?;
    let t = if end_of_day {
        date.and_hms_micro_opt(23, 59, 59, 999_999)
    } else {
        date.and_hms_opt(0, 0, 0)
    }
    .expect("valid time of day");
    Ok(t.and_utc())
}
