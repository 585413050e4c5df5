//! Times as the pages show them: in UTC and, when the site has one, in its time zone.

use chrono::{DateTime, Utc};
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

/// The local part: `18:00 JST`, or `2026-11-26 02:00 JST` across midnight.
fn local_text(utc: DateTime<Utc>, zone: Tz) -> String {
    let local = utc.with_timezone(&zone);
    if local.date_naive() == utc.date_naive() {
        local.format("%H:%M %Z").to_string()
    } else {
        local.format("%Y-%m-%d %H:%M %Z").to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
