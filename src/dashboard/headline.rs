//! The headline at the top of every page of a site: what the person on call reads first. It
//! says in words the worst open alert (level, subject, metric, value ± 1σ at the subject's latest
//! epoch; for a time to failure the date before which failure is likely (the one-sided bound the
//! rule reads) and the forecast failure time with its ±2σ interval, in UTC and the site's zone,
//! counted from that epoch and not from now), how old the last epoch
//! is, and the site's response text and contacts (site settings).
//!
//! [`load`] reads what it needs; [`render`] is pure.

use chrono::{DateTime, Utc};
use maud::{html, Markup};

use super::layout::{level_class, seg};
use super::local_time::{text, when};
use super::page::PageError;
use crate::http::AppState;
pub use crate::service::forecast::{failure_time, FailureTime};
use crate::service::forecast::{stated, ttf};
use crate::store::displacements::Displacement;
use crate::store::sites::Site;
use crate::store::{alerts, block_motions, displacements, epochs, parse_timestamp};
use cliffwatch_core::analysis::AlertLevel;

/// Open alerts read to find the worst (the store lists them newest first).
const ALERTS_READ: i64 = 500;

/// What the headline says, read from the store.
#[derive(Debug, Clone)]
pub struct Headline {
    /// The worst open (unresolved) alert, when there is one.
    pub worst: Option<alerts::Alert>,
    /// Open alerts besides the worst.
    pub others: usize,
    /// The latest row of the worst alert's subject (point or block), when it has one.
    pub latest: Option<Displacement>,
    /// Observation time of the site's last epoch (RFC 3339).
    pub last_epoch: Option<String>,
    /// The time the page is made.
    pub now: DateTime<Utc>,
}

/// Order of the metrics when levels tie: the one nearest to failure first.
fn metric_rank(rule: &str) -> u8 {
    match rule {
        "time_to_failure_hours" => 4,
        "velocity_mm_per_day" => 3,
        "displacement_along_mm" => 2,
        "displacement_mm" => 1,
        _ => 0,
    }
}

/// The worst of `open`: highest level, then the metric nearest to failure, then the newest.
pub fn worst(open: &[alerts::Alert]) -> Option<&alerts::Alert> {
    open.iter()
        .max_by_key(|a| worst_key(a.level, &a.rule, &a.raised_at))
}

/// The key [`worst`] maximises.
fn worst_key<'a>(level: AlertLevel, rule: &str, raised_at: &'a str) -> (AlertLevel, u8, &'a str) {
    (level, metric_rank(rule), raised_at)
}

/// Reads the headline of `site`.
pub async fn load(state: &AppState, site: &Site) -> Result<Headline, PageError> {
    let db = state.store.reader();
    let open: Vec<alerts::Alert> = alerts::list_active(db, &site.id, ALERTS_READ)
        .await?
        .into_iter()
        .map(|(_, a)| a)
        .collect();
    let worst = worst(&open).cloned();
    let latest = match &worst {
        Some(a) if a.group.is_some() => {
            let g = a.group.as_deref().unwrap_or_default();
            block_motions::series(db, &site.id, g, a.observed_at.as_deref(), None, None, None)
                .await?
                .pop()
        }
        Some(a) if a.point.is_some() => {
            let p = a.point.as_deref().unwrap_or_default();
            displacements::latest(&mut *state.store.read().await?, &site.id)
                .await?
                .into_iter()
                .find(|d| d.point == p)
        }
        _ => None,
    };
    let last_epoch = epochs::list(db, &site.id, None, 1)
        .await?
        .into_iter()
        .next()
        .map(|(_, e)| e.observed_at);
    Ok(Headline {
        others: open.len().saturating_sub(1),
        worst,
        latest,
        last_epoch,
        now: Utc::now(),
    })
}

/// The metric of a rule in words.
fn metric_words(rule: &str) -> &str {
    match rule {
        "displacement_mm" => "3-D displacement",
        "displacement_along_mm" => "displacement along the direction of interest",
        "velocity_mm_per_day" => "velocity",
        "time_to_failure_hours" => "time to failure",
        other => other,
    }
}

/// `value ± σ unit` of the alert's metric in `d` (filtered velocity and time to failure where
/// the filter has them, as the rules read them by default).
fn value_words(rule: &str, d: &Displacement) -> Option<String> {
    let (v, s, unit, digits) = match rule {
        "displacement_mm" => (Some(d.d_mm), Some(d.sigma_mm), "mm", 1),
        "displacement_along_mm" => (d.d_along_mm, None, "mm", 1),
        "velocity_mm_per_day" => match d.f_velocity_mm_per_day {
            Some(v) => (Some(v), d.sigma_f_velocity_mm_per_day, "mm/day", 2),
            None => (d.velocity_mm_per_day, None, "mm/day", 2),
        },
        "time_to_failure_hours" => {
            let (h, s) = ttf(d)?;
            if !stated(h, s) {
                return Some(match s {
                    Some(s) => format!("no forecast yet ({h:.0} ± {s:.0} h, 1σ)"),
                    None => format!("no forecast yet ({h:.0} h)"),
                });
            }
            (Some(h), s, "h", 0)
        }
        _ => return None,
    };
    let v = v.filter(|v| v.is_finite())?;
    Some(match s.filter(|s| s.is_finite()) {
        Some(s) => format!("{v:.digits$} ± {s:.digits$} {unit} (1σ)"),
        None => format!("{v:.digits$} {unit}"),
    })
}

/// "95 %": the confidence of the stated bound.
pub fn bound_confidence_words() -> String {
    format!(
        "{:.0} %",
        100.0 * cliffwatch_core::analysis::failure::BOUND_CONFIDENCE
    )
}

/// "3 d 4 h", "5 h 10 min", "12 min": how long ago `t` was at `now`.
fn age(t: DateTime<Utc>, now: DateTime<Utc>) -> String {
    let m = (now - t).num_minutes().max(0);
    let (d, h, min) = (m / 1440, m % 1440 / 60, m % 60);
    if d > 0 {
        format!("{d} d {h} h")
    } else if h > 0 {
        format!("{h} h {min} min")
    } else {
        format!("{min} min")
    }
}

/// The headline of `site` from `h`.
pub fn render(site: &Site, h: &Headline) -> Markup {
    let tz = site.time_zone.as_deref();
    let site_href = format!("/sites/{}", seg(&site.id));
    let level = h.worst.as_ref().map(|a| a.level);
    html! {
        section.headline.(level_class(level)) aria-label="headline" {
            @match &h.worst {
                None => p.what { strong { "No open alert." } }
                Some(a) => p.what { (alert_words(a, h.latest.as_ref(), &site_href, tz)) }
            }
            @if h.others > 0 {
                p.more { a href={ (site_href) "#alerts" } { (h.others) " more open alert" @if h.others > 1 { "s" } } }
            }
            p.last-epoch {
                @match h.last_epoch.as_deref().and_then(|t| parse_timestamp(t).map(|p| (t, p))) {
                    None => "No epoch yet.",
                    Some((t, parsed)) => {
                        "Last epoch " (when(t, tz)) ", " (age(parsed, h.now)) " ago"
                        @if let Some(every) = site.schedule_hours {
                            @if (h.now - parsed).num_minutes() as f64 > every * 60.0 * 1.5 {
                                strong { " — overdue" } " (expected every " (every) " h)"
                            } @else {
                                " (expected every " (every) " h)"
                            }
                        }
                        "."
                    }
                }
            }
            @if let Some(r) = &site.response_text {
                div.response { h2 { "What to do" } p { (r) } }
            }
            @if !site.contacts.is_empty() {
                div.contacts { h2 { "Contacts" } ul { @for c in &site.contacts { li { (c) } } } }
            }
            @if site.response_text.is_none() && site.contacts.is_empty() {
                p.note { "No response plan or contacts are configured for this site (site settings "
                    code { "response_text" } ", " code { "contacts" } ")." }
            }
        }
    }
}

/// The worst alert in words: "ALARM · point T016 · time to failure 46 ± 9 h: failure expected …".
fn alert_words(
    a: &alerts::Alert,
    d: Option<&Displacement>,
    site_href: &str,
    tz: Option<&str>,
) -> Markup {
    let subject_href = match (&a.group, &a.point) {
        (Some(g), _) => Some(format!("{site_href}/groups/{}", seg(g))),
        (None, Some(p)) => Some(format!("{site_href}/points/{}", seg(p))),
        _ => None,
    };
    let subject = match (&a.group, &a.point) {
        (Some(g), _) => format!("block {g}"),
        (None, Some(p)) => format!("point {p}"),
        _ => "site".to_string(),
    };
    let level = a.level.as_str().to_uppercase();
    let value = d.and_then(|d| value_words(&a.rule, d));
    let forecast = (a.rule == "time_to_failure_hours")
        .then(|| d.and_then(|d| failure_time(d).map(|f| (f, d))))
        .flatten();
    html! {
        strong.level { (level) } " · "
        @match subject_href { Some(href) => a href=(href) { (subject) }, None => (subject) }
        " · " (metric_words(&a.rule))
        @if let Some(v) = &value { " " strong.value { (v) } }
        @if let (Some(t), Some(u)) = (a.threshold, &a.unit) { " (threshold " (t) " " (u) ")" }
        @if let Some((f, d)) = forecast {
            ": failure likely before " strong.failure { (text(f.likely_before, tz)) }
            " (" (bound_confidence_words()) ", one-sided); expected " (text(f.at, tz))
            " (±2σ: " (text(f.lower, tz)) " to " (text(f.upper, tz)) "), counted from the last epoch ("
            (when(&d.observed_at, tz)) "), not from now"
        }
        @if value.is_none() && forecast.is_none() { ": " (a.message) }
        ". "
        span.raised { "Raised " (when(&a.raised_at, tz)) " · "
            a href={ (site_href) "/alerts/" (seg(&a.id)) } { "history" } }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ages_read_in_days_hours_and_minutes() {
        let t = DateTime::parse_from_rfc3339("2026-11-01T09:00:00Z")
            .unwrap()
            .with_timezone(&Utc);
        let at = |m: i64| t + chrono::Duration::minutes(m);
        assert_eq!(age(t, at(12)), "12 min");
        assert_eq!(age(t, at(5 * 60 + 10)), "5 h 10 min");
        assert_eq!(age(t, at(3 * 1440 + 4 * 60 + 59)), "3 d 4 h");
        assert_eq!(age(t, at(-5)), "0 min");
    }

    #[test]
    fn the_worst_alert_is_the_highest_level_then_nearest_to_failure() {
        let t = "2026-11-01T09:00:00Z";
        let later = "2026-11-02T09:00:00Z";
        let ttf = worst_key(AlertLevel::Warning, "time_to_failure_hours", t);
        assert!(ttf > worst_key(AlertLevel::Warning, "displacement_mm", later));
        assert!(ttf < worst_key(AlertLevel::Alarm, "displacement_mm", t));
        assert!(
            worst_key(AlertLevel::Watch, "velocity_mm_per_day", later)
                > worst_key(AlertLevel::Watch, "velocity_mm_per_day", t)
        );
    }
}
