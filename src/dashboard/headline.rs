//! The headline at the top of every page of a site: what the person on call reads first. It
//! names the most urgent incident ([`crate::service::incidents`]: a declared block with its
//! points, or a point outside blocks), its level, its velocity ± 1σ, and when a forecast is
//! stated the date before which failure is likely (the one-sided bound the rules read), local
//! time first then UTC, with "≈ N h from now" or "passed N h ago", the forecast failure time
//! and its ±2σ interval counted from the epoch it comes from; else the worst alert's value. Then
//! how old the last epoch is, and the site's response text and contacts (site settings). The
//! block page, point pages, alert pages and the report quote the same incident.
//!
//! [`load`] reads what it needs; [`render`] is pure.

use chrono::{DateTime, Utc};
use maud::{html, Markup};

use super::layout::{level_class, seg};
use super::local_time::{text_local_first, when};
use super::page::PageError;
use crate::http::AppState;
pub use crate::service::forecast::{failure_time, FailureTime};
use crate::service::forecast::{stated, ttf};
use crate::service::incidents::{self, Incident, IncidentForecast};
use crate::store::displacements::Displacement;
use crate::store::sites::Site;
use crate::store::{alerts, block_motions, displacements, epochs, parse_timestamp};
use cliffwatch_core::analysis::AlertLevel;

/// What the headline says, read from the store.
#[derive(Debug, Clone)]
pub struct Headline {
    /// The most urgent incident, when there is one.
    pub incident: Option<Incident>,
    /// Its worst alert.
    pub worst: Option<alerts::Alert>,
    /// How many incidents the site has in all.
    pub incidents: usize,
    /// The latest row of the incident's subject (the block's motion or the point's), when it
    /// has one.
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
    let all = incidents::list(&state.store, &site.id).await?;
    let incident = all.first().cloned();
    let worst = match &incident {
        Some(i) => {
            let mut of: Vec<alerts::Alert> = vec![];
            for id in &i.alert_ids {
                if let Some(a) = alerts::get(db, id).await? {
                    of.push(a);
                }
            }
            worst(&of).cloned()
        }
        None => None,
    };
    let latest = match incident.as_ref().map(|i| (i.kind.as_str(), &i.subject)) {
        Some(("block", Some(g))) => block_motions::latest(db, &site.id, g).await?,
        Some(("point", Some(p))) => {
            displacements::latest(&mut *state.store.read().await?, &site.id)
                .await?
                .into_iter()
                .find(|d| &d.point == p)
        }
        _ => None,
    };
    let last_epoch = epochs::list(db, &site.id, None, 1)
        .await?
        .into_iter()
        .next()
        .map(|(_, e)| e.observed_at);
    Ok(Headline {
        incidents: all.len(),
        incident,
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
    let level = h.incident.as_ref().map(|i| i.level);
    html! {
        section.headline.(level_class(level)) aria-label="headline" {
            @if let Some(at) = &site.retired_at {
                p.retired {
                    strong { "Retired on " (when(at, tz)) } ": " (site.retired_reason.as_deref().unwrap_or(""))
                    " — it takes no more epochs; its record stays here."
                }
            }
            @match (&h.incident, &h.worst) {
                (Some(i), Some(a)) => p.what { (incident_words(i, a, h.latest.as_ref(), h.now, &site_href, tz)) }
                _ => p.what { strong { "No open alert." } }
            }
            @if h.incidents > 1 {
                p.more { a href={ (site_href) "#alerts" } { (h.incidents - 1) " more incident" @if h.incidents > 2 { "s" } } }
            }
            p.last-epoch {
                @match h.last_epoch.as_deref().and_then(|t| parse_timestamp(t).map(|p| (t, p))) {
                    None => "No epoch yet.",
                    Some((t, parsed)) => {
                        "Last epoch " (when(t, tz)) ", " (age(parsed, h.now)) " ago"
                        @if let Some(every) = site.schedule_hours {
                            @if site.retired_at.is_none() && (h.now - parsed).num_minutes() as f64 > every * 60.0 * 1.5 {
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

/// "≈ 14 h from now", "≈ 3 d 2 h from now", "passed 5 h ago": how far `t` (s since 1970) is
/// from `now`.
fn from_now(t: f64, now: DateTime<Utc>) -> String {
    let h = (t - now.timestamp() as f64) / 3600.0;
    let span = |h: f64| {
        let h = h.round() as i64;
        if h >= 48 {
            format!("{} d {} h", h / 24, h % 24)
        } else {
            format!("{h} h")
        }
    };
    if h >= 0.0 {
        format!("≈ {} from now", span(h))
    } else {
        format!("passed {} ago", span(-h))
    }
}

/// The subject's velocity in words: `velocity 3.21 ± 0.40 mm/day (1σ)` (the filtered one, as the
/// rules read it by default, else the raw one).
fn velocity_words(d: &Displacement) -> Option<String> {
    let (v, s) = match d.f_velocity_mm_per_day.filter(|v| v.is_finite()) {
        Some(v) => (v, d.sigma_f_velocity_mm_per_day),
        None => (d.velocity_mm_per_day.filter(|v| v.is_finite())?, None),
    };
    Some(match s.filter(|s| s.is_finite()) {
        Some(s) => format!("velocity {v:.2} ± {s:.2} mm/day (1σ)"),
        None => format!("velocity {v:.2} mm/day"),
    })
}

/// The ±2σ interval and the expected time of forecast `f` (s since 1970).
fn expected(f: &IncidentForecast) -> Option<(f64, f64, f64)> {
    let t0 = parse_timestamp(&f.observed_at)?.timestamp() as f64;
    let s = f.sigma_hours.unwrap_or(0.0);
    let at = t0 + f.hours * 3600.0;
    Some((at, (at - 2.0 * s * 3600.0).max(t0), at + 2.0 * s * 3600.0))
}

/// The incident in words: "ALARM · block B1 · velocity 3.21 ± 0.40 mm/day (1σ) · failure likely
/// before 2026-06-21 09:27 JST (00:27 UTC), ≈ 14 h from now (95 %, one-sided); time to failure
/// 12 ± 2 h (1σ), expected …", or without a forecast the worst alert's metric and value.
fn incident_words(
    i: &Incident,
    a: &alerts::Alert,
    d: Option<&Displacement>,
    now: DateTime<Utc>,
    site_href: &str,
    tz: Option<&str>,
) -> Markup {
    let subject = match (i.kind.as_str(), &i.subject) {
        ("block", Some(b)) => format!("block {b}"),
        ("point", Some(p)) => format!("point {p}"),
        _ => "site".to_string(),
    };
    let level = i.level.as_str().to_uppercase();
    let velocity = d.and_then(velocity_words);
    let forecast = i.forecast.as_ref().and_then(|f| {
        let likely = parse_timestamp(&f.likely_before)?.timestamp() as f64;
        Some((f, likely, expected(f)?))
    });
    let value = d.and_then(|d| value_words(&a.rule, d));
    let alerts = i.alert_ids.len();
    html! {
        strong.level { (level) } " · "
        @if i.kind == "site" { (subject) } @else { a.subject href=(i.page) { (subject) } }
        @if let Some(v) = &velocity { " · " strong.velocity { (v) } }
        @if let Some((f, likely, (at, lower, upper))) = forecast {
            " · failure likely before " strong.failure { (text_local_first(likely, tz)) } ", "
            strong.eta { (from_now(likely, now)) }
            " (" (bound_confidence_words()) ", one-sided); time to failure " (format!("{:.0}", f.hours))
            @if let Some(s) = f.sigma_hours { " ± " (format!("{s:.0}")) } " h (1σ), expected "
            (text_local_first(at, tz)) " (±2σ: " (text_local_first(lower, tz)) " to " (text_local_first(upper, tz))
            "), the forecast of " (f.from) " counted from its last epoch ("
            (text_local_first(parse_timestamp(&f.observed_at).map_or(0.0, |t| t.timestamp() as f64), tz)) ")"
        } @else {
            " · " (metric_words(&a.rule))
            @if let Some(v) = &value { " " strong.value { (v) } }
            @if let (Some(t), Some(u)) = (a.threshold, &a.unit) { " (threshold " (t) " " (u) ")" }
            @if value.is_none() { ": " (a.message) }
        }
        ". "
        span.raised {
            @if alerts > 1 { a href={ (site_href) "#alerts" } { (alerts) " alerts" } " in this incident · " }
            "Raised " (when(&a.raised_at, tz)) " · "
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
    fn a_time_reads_from_now_or_as_passed() {
        let now = DateTime::parse_from_rfc3339("2026-11-01T09:00:00Z")
            .unwrap()
            .with_timezone(&Utc);
        let t = now.timestamp() as f64;
        assert_eq!(from_now(t + 14.2 * 3600.0, now), "≈ 14 h from now");
        assert_eq!(from_now(t + 74.0 * 3600.0, now), "≈ 3 d 2 h from now");
        assert_eq!(from_now(t - 5.0 * 3600.0, now), "passed 5 h ago");
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
