//! Times as the pages show them: in UTC and, when the site has one, in its time zone; the days
//! of a page's period in that zone.

use chrono::{DateTime, NaiveDate, Utc};
use chrono_tz::Tz;
use maud::{html, Markup};

/// `2026-11-25 09:00 UTC`, followed by ` · 18:00 JST` in the site's zone (`tz`, an IANA name),
/// with the date when it differs from the UTC one; inside a `<time>` element holding the
/// RFC 3339 value. A time that does not parse is shown as it is.
pub fn when(rfc3339: &str, tz: Option<&str>) -> Markup {
    let Ok(t) = DateTime::parse_from_rfc3339(rfc3339) else {
        return html! { (rfc3339) };
    };
    let utc = t.with_timezone(&Utc);
    let local = tz
        .and_then(|z| z.parse::<Tz>().ok())
        .map(|zone| local_text(utc, zone));
    html! {
        time datetime=(rfc3339) {
            (utc.format("%Y-%m-%d %H:%M UTC"))
            @if let Some(l) = local { small.local { " · " (l) } }
        }
    }
}

/// A time (seconds since 1970) as plain text: `2026-11-25 09:00 UTC`, followed by
/// ` · 18:00 JST` in the site's zone as [`when`] shows it.
pub fn text(unix_seconds: f64, tz: Option<&str>) -> String {
    let Some(utc) = DateTime::<Utc>::from_timestamp(unix_seconds.round() as i64, 0) else {
        return format!("{unix_seconds} s");
    };
    let mut out = utc.format("%Y-%m-%d %H:%M UTC").to_string();
    if let Some(zone) = tz.and_then(|z| z.parse::<Tz>().ok()) {
        out.push_str(" · ");
        out.push_str(&local_text(utc, zone));
    }
    out
}

/// `2026-11-26 18:00 JST (09:00 UTC)`: local time first, then UTC (the UTC date added when it
/// differs); without a zone `2026-11-26 09:00 UTC`.
pub fn text_local_first(unix_seconds: f64, tz: Option<&str>) -> String {
    let Some(utc) = DateTime::<Utc>::from_timestamp(unix_seconds.round() as i64, 0) else {
        return format!("{unix_seconds} s");
    };
    match tz.and_then(|z| z.parse::<Tz>().ok()) {
        None => utc.format("%Y-%m-%d %H:%M UTC").to_string(),
        Some(zone) => {
            let local = utc.with_timezone(&zone);
            let u = if local.date_naive() == utc.date_naive() {
                utc.format("%H:%M UTC")
            } else {
                utc.format("%Y-%m-%d %H:%M UTC")
            };
            format!("{} ({u})", local.format("%Y-%m-%d %H:%M %Z"))
        }
    }
}

/// The local part: `18:00 JST`, or `2026-11-26 02:00 JST` across midnight.
fn local_text(utc: DateTime<Utc>, zone: Tz) -> String {
    let local = utc.with_timezone(&zone);
    if local.date_naive() == utc.date_naive() {
        local.format("%H:%M %Z").to_string()
    } else {
        local.format("%Y-%m-%d %H:%M %Z").to_string()
    }
}

/// A `from` / `to` bound of a page as the stored time bound: an RFC 3339 time as it is; a date
/// (`2026-11-01`) from its first instant, or to its last (`end`), in the site's zone `tz` (an IANA
/// name; UTC without one), so that a report "from 1 to 30 November" for a site in Japan holds
/// the epochs of those days in Japan. `Err`: the message naming the text at fault.
pub fn day_bound(s: &str, end: bool, tz: Option<&str>) -> Result<String, String> {
    let zone = tz.and_then(|z| z.parse::<Tz>().ok());
    let (Some(zone), Ok(date)) = (zone, NaiveDate::parse_from_str(s, "%Y-%m-%d")) else {
        return crate::http::time_bound::time_bound(s, end).map_err(|e| e.message);
    };
    let day_start = |d: NaiveDate| -> Option<DateTime<Utc>> {
        // the first hour that exists: a change to summer time may skip midnight
        (0..=3).find_map(|h| {
            d.and_hms_opt(h, 0, 0)?
                .and_local_timezone(zone)
                .earliest()
                .map(|t| t.with_timezone(&Utc))
        })
    };
    let t = if end {
        date.succ_opt()
            .and_then(day_start)
            .map(|next| next - chrono::Duration::microseconds(1))
    } else {
        day_start(date)
    };
    match t {
        Some(t) => Ok(crate::http::time_bound::stored_bound(t)),
        None => crate::http::time_bound::time_bound(s, end).map_err(|e| e.message),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_date_bound_is_a_day_of_the_site_zone() {
        let tokyo = Some("Asia/Tokyo");
        assert_eq!(
            day_bound("2026-11-01", false, tokyo).unwrap(),
            "2026-10-31T15:00:00.000000Z"
        );
        assert_eq!(
            day_bound("2026-11-30", true, tokyo).unwrap(),
            "2026-11-30T14:59:59.999999Z"
        );
        assert_eq!(
            day_bound("2026-11-01", false, None).unwrap(),
            "2026-11-01T00:00:00.000000Z"
        );
        assert_eq!(
            day_bound("2026-11-30", true, None).unwrap(),
            "2026-11-30T23:59:59.999999Z"
        );
        // a time is a time whatever the zone
        assert_eq!(
            day_bound("2026-11-01T03:00:00Z", false, tokyo).unwrap(),
            "2026-11-01T03:00:00.000000Z"
        );
        // a day of 23 hours (summer time begins at 02:00 in Zurich)
        let zurich = Some("Europe/Zurich");
        assert_eq!(
            day_bound("2026-03-29", false, zurich).unwrap(),
            "2026-03-28T23:00:00.000000Z"
        );
        assert_eq!(
            day_bound("2026-03-29", true, zurich).unwrap(),
            "2026-03-29T21:59:59.999999Z"
        );
        assert!(day_bound("yesterday", false, tokyo)
            .unwrap_err()
            .contains("yesterday"));
    }

    #[test]
    fn utc_and_the_site_zone_with_its_date_when_it_differs() {
        let s = when("2026-11-25T09:00:00Z", Some("Asia/Tokyo")).into_string();
        assert!(s.contains("2026-11-25 09:00 UTC"), "{s}");
        assert!(s.contains("18:00 JST"), "{s}");
        let s = when("2026-11-25T20:30:00Z", Some("Asia/Tokyo")).into_string();
        assert!(s.contains("2026-11-26 05:30 JST"), "{s}");
        let s = when("2026-07-01T12:00:00Z", Some("Europe/Zurich")).into_string();
        assert!(s.contains("14:00 CEST"), "{s}");
    }

    #[test]
    fn plain_text_of_seconds_has_the_same_parts() {
        let t = 1_795_597_200.0; // 2026-11-25T09:00:00Z
        assert_eq!(
            text(t, Some("Asia/Tokyo")),
            "2026-11-25 09:00 UTC · 18:00 JST"
        );
        assert_eq!(text(t, None), "2026-11-25 09:00 UTC");
        assert_eq!(text(t, Some("Mars/Olympus")), "2026-11-25 09:00 UTC");
    }

    #[test]
    fn utc_only_without_a_zone_and_raw_text_when_unparsable() {
        let s = when("2026-11-25T09:00:00Z", None).into_string();
        assert!(s.contains("09:00 UTC") && !s.contains('·'), "{s}");
        assert_eq!(
            when("yesterday", Some("Asia/Tokyo")).into_string(),
            "yesterday"
        );
    }
}
