//! The page shell every dashboard page shares, and small formatting helpers. maud escapes every
//! value put into the HTML; nothing from the database is written unescaped.

use maud::{html, Markup, DOCTYPE};

use cliffwatch_core::analysis::AlertLevel;

/// What a page needs from the request: the CSRF token of a cookie session (sent by htmx with
/// every change), and whether the visitor may acknowledge alerts.
#[derive(Debug, Clone, Default)]
pub struct Viewer {
    /// CSRF token of the session (None: no tokens configured, or a bearer-token client).
    pub csrf: Option<String>,
    /// May acknowledge (role `upload` or higher, or no tokens configured).
    pub can_acknowledge: bool,
    /// May change the site's settings (role `admin`, or no tokens configured).
    pub can_administer: bool,
    /// Signed in through the sign-in form (shows "sign out").
    pub signed_in: bool,
}

/// The full page: title, breadcrumbs (`(label, href)`; the last one is the page itself), body.
pub fn page(title: &str, crumbs: &[(String, String)], viewer: &Viewer, body: Markup) -> Markup {
    let headers = viewer
        .csrf
        .as_ref()
        .map(|t| serde_json::json!({ "x-csrf-token": t }).to_string());
    html! {
        (DOCTYPE)
        html lang="en" {
            head {
                meta charset="utf-8";
                meta name="viewport" content="width=device-width, initial-scale=1";
                title { (title) " · cliffwatch" }
                link rel="stylesheet" href="/assets/uPlot.min.css";
                link rel="stylesheet" href="/assets/dashboard.css";
                script src="/assets/htmx.min.js" defer {}
                script src="/assets/uPlot.iife.min.js" defer {}
                script src="/assets/plots.js" defer {}
                script src="/assets/forms.js" defer {}
            }
            body hx-headers=[headers] {
                header.top {
                    nav.crumbs {
                        a href="/" { "cliffwatch" }
                        @for (label, href) in crumbs {
                            " / " a href=(href) { (label) }
                        }
                    }
                    @if viewer.signed_in {
                        form.signout method="post" action="/signout" {
                            input type="hidden" name="csrf" value=[viewer.csrf.as_deref()];
                            button type="submit" { "sign out" }
                        }
                    }
                }
                main { (body) }
            }
        }
    }
}

/// CSS class of an alert level (its name; no level: `ok`).
pub fn level_class(level: Option<AlertLevel>) -> &'static str {
    level.map_or("ok", AlertLevel::as_str)
}

/// A badge with the level's colour and word.
pub fn level_badge(level: Option<AlertLevel>) -> Markup {
    let class = level_class(level);
    let word = if class == "ok" { "no alert" } else { class };
    html! { span class={ "badge " (class) } { (word) } }
}

/// A number with `digits` decimals, or "–" when missing or not finite.
pub fn num(v: Option<f64>, digits: usize) -> String {
    match v {
        Some(x) if x.is_finite() => format!("{x:.digits$}"),
        _ => "–".to_string(),
    }
}

/// "v ± σ" with `digits` decimals, "–" when the value is missing.
pub fn with_sigma(v: Option<f64>, sigma: Option<f64>, digits: usize) -> String {
    match (v, sigma) {
        (Some(v), Some(s)) if v.is_finite() && s.is_finite() => {
            format!("{v:.digits$} ± {s:.digits$}")
        }
        (v, _) => num(v, digits),
    }
}

/// A metric or site-level kind in words, short.
pub fn metric_name(rule: &str) -> &str {
    match rule {
        "displacement_mm" => "displacement",
        "displacement_along_mm" => "displacement along its direction",
        "velocity_mm_per_day" => "velocity",
        "time_to_failure_hours" => "time to failure",
        "reference_unstable" => "reference unstable",
        "campaign_overdue" => "campaign overdue",
        "analysis_failed" => "analysis failed",
        other => other,
    }
}

pub use crate::http::seg;

/// A time to failure (h) with its σ, or "no forecast yet" when its one-sided bound lies beyond a
/// week ([`cliffwatch_core::analysis::failure::stated`]; the rules read it through that bound all the same).
pub fn time_to_failure(hours: Option<f64>, sigma: Option<f64>) -> String {
    match (hours, sigma) {
        (Some(h), Some(s)) if !cliffwatch_core::analysis::failure::stated(h, s) => {
            format!("no forecast yet ({h:.0} ± {s:.0})")
        }
        _ => with_sigma(hours, sigma, 0),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn user_text_is_escaped_and_segments_encoded() {
        let v = Viewer::default();
        let p = page(
            "<b>x</b>",
            &[("<i>".into(), "/sites/a".into())],
            &v,
            html! {},
        )
        .into_string();
        assert!(p.contains("&lt;b&gt;x&lt;/b&gt;") && p.contains("&lt;i&gt;"));
        assert!(!p.contains("<b>x"));
        assert_eq!(seg("a b/<c>"), "a%20b%2F%3Cc%3E");
    }
}
