//! The alert filter of the site page: `?level=` (at least `watch` | `warning` | `alarm`),
//! `?state=` (`active`, the default: open or acknowledged; `open`; `acknowledged`; `resolved`;
//! `all`) and `?subject=` (part of a point's or group's name, any case). The form works as a plain
//! GET without script; with htmx a change swaps only the alert section and pushes the URL.

use maud::{html, Markup};
use serde::Deserialize;

use crate::store::alerts::Alert;
use cliffwatch_core::analysis::{AlertLevel, AlertStatus};

/// The query of the site page, as sent.
#[derive(Debug, Default, Clone, Deserialize)]
pub struct AlertQuery {
    /// Lowest level shown.
    #[serde(default)]
    pub level: Option<String>,
    /// Which states are shown.
    #[serde(default)]
    pub state: Option<String>,
    /// Part of the subject's name.
    #[serde(default)]
    pub subject: Option<String>,
    /// The epochs table's page: epochs observed before this instant (RFC 3339); none: the newest.
    #[serde(default)]
    pub epochs_before: Option<String>,
    /// The alert list's page: alerts raised before this instant (the store's `raised_at` of the
    /// previous page's last alert), with [`AlertQuery::alerts_before_id`]; none: the newest.
    #[serde(default)]
    pub alerts_before: Option<String>,
    /// The id of the previous page's last alert (ties of `raised_at` break by id).
    #[serde(default)]
    pub alerts_before_id: Option<String>,
}

/// States a filter may ask for; `active` is open or acknowledged.
const STATES: [&str; 5] = ["active", "open", "acknowledged", "resolved", "all"];

/// A checked filter.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct AlertFilter {
    /// Lowest level shown (`None`: every level).
    pub level: Option<AlertLevel>,
    /// `active`, `open`, `acknowledged`, `resolved` or `all`.
    pub state: &'static str,
    /// Lower-case part of the subject's name (empty: any).
    pub subject: String,
    /// The page: alerts before this `(raised_at, id)` (`None`: the newest).
    pub before: Option<(String, String)>,
}

impl AlertFilter {
    /// Checks the query; the message names the parameter at fault and what it may be.
    pub fn parse(q: &AlertQuery) -> Result<AlertFilter, String> {
        let level = match q.level.as_deref().filter(|s| !s.is_empty()) {
            None => None,
            Some(l) => Some(
                l.parse::<AlertLevel>()
                    .map_err(|_| format!("level '{l}' is not one of watch, warning, alarm"))?,
            ),
        };
        let state = match q.state.as_deref().filter(|s| !s.is_empty()) {
            None => "active",
            Some(s) => STATES.iter().find(|k| **k == s).ok_or_else(|| {
                format!("state '{s}' is not one of active, open, acknowledged, resolved, all")
            })?,
        };
        let subject = q.subject.as_deref().unwrap_or("").trim().to_lowercase();
        if subject.chars().count() > 200 {
            return Err("subject is longer than 200 characters".into());
        }
        let before = match (&q.alerts_before, &q.alerts_before_id) {
            (Some(t), Some(id)) if !t.is_empty() => {
                if t.chars().count() > 40 || id.chars().count() > 200 {
                    return Err("alerts_before or alerts_before_id is too long".into());
                }
                Some((t.clone(), id.clone()))
            }
            (None, None) => None,
            _ => return Err("alerts_before and alerts_before_id go together".into()),
        };
        Ok(AlertFilter {
            level,
            state,
            subject,
            before,
        })
    }

    /// The query of this filter's first page (state, level, subject), percent-encoded: the
    /// "newest alerts" link.
    pub fn newest_query(&self) -> String {
        let mut q = format!("state={}", self.state);
        if let Some(l) = self.level {
            q.push_str(&format!("&level={l}"));
        }
        if !self.subject.is_empty() {
            q.push_str(&format!("&subject={}", super::layout::seg(&self.subject)));
        }
        q
    }

    /// The query of this filter's page after the alert `(raised_at, id)` (raw store
    /// `raised_at`), for the "older alerts" link, percent-encoded.
    pub fn older_query(&self, raised_at: &str, id: &str) -> String {
        let enc = super::layout::seg;
        format!(
            "{}&alerts_before={}&alerts_before_id={}",
            self.newest_query(),
            enc(raised_at),
            enc(id)
        )
    }

    /// Whether the filter shows the alerts not resolved (the default), which the store reads
    /// apart ([`crate::store::alerts::list_active`]).
    pub fn is_active(&self) -> bool {
        self.state == "active"
    }

    /// The state the store can select by (`None`: all states, filtered here).
    pub fn store_state(&self) -> Option<AlertStatus> {
        self.state.parse().ok()
    }

    /// Whether alert `a` is shown.
    pub fn matches(&self, a: &Alert) -> bool {
        let state = match self.state {
            "active" => a.state != AlertStatus::Resolved,
            "all" => true,
            s => a.state.as_str() == s,
        };
        let level = self.level.is_none_or(|l| a.level >= l);
        let subject = self.subject.is_empty()
            || [a.point.as_deref(), a.group.as_deref()]
                .into_iter()
                .flatten()
                .any(|n| n.to_lowercase().contains(&self.subject));
        state && level && subject
    }

    /// The section's heading.
    pub fn heading(&self) -> &'static str {
        match self.state {
            "active" => "Open alerts",
            "open" => "Alerts not acknowledged",
            "acknowledged" => "Acknowledged alerts",
            "resolved" => "Resolved alerts",
            _ => "Alerts",
        }
    }

    /// The filter form: a GET to `action` (the site page); htmx swaps `#alerts` on any change.
    pub fn form(&self, action: &str) -> Markup {
        html! {
            form.filters method="get" action=(action) hx-get=(action) hx-select="#alerts"
                hx-target="#alerts" hx-swap="outerHTML" hx-push-url="true" hx-trigger="change, submit" {
                label { "level ≥ "
                    select name="level" {
                        option value="" selected[self.level.is_none()] { "any" }
                        @for l in AlertLevel::ALL { option value=(l) selected[self.level == Some(*l)] { (l) } }
                    }
                }
                " "
                label { "state "
                    select name="state" {
                        @for s in STATES { option value=(s) selected[self.state == s] { (s) } }
                    }
                }
                " "
                label { "subject "
                    input type="search" name="subject" value=(self.subject) maxlength="200" placeholder="point or group";
                }
                " "
                button type="submit" { "filter" }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn q(level: Option<&str>, state: Option<&str>, subject: Option<&str>) -> AlertQuery {
        AlertQuery {
            level: level.map(str::to_string),
            state: state.map(str::to_string),
            subject: subject.map(str::to_string),
            ..AlertQuery::default()
        }
    }

    fn alert(level: &str, state: &str, point: Option<&str>, group: Option<&str>) -> Alert {
        let mut a = Alert::default();
        a.level = level.parse().unwrap();
        a.state = state.parse().unwrap();
        a.point = point.map(str::to_string);
        a.group = group.map(str::to_string);
        a
    }

    /// Unknown values are refused with the parameter named; empty ones mean "any".
    #[test]
    fn bad_parameters_are_named() {
        let e = AlertFilter::parse(&q(Some("severe"), None, None)).unwrap_err();
        assert!(e.starts_with("level 'severe'"), "{e}");
        let e = AlertFilter::parse(&q(None, Some("closed"), None)).unwrap_err();
        assert!(e.starts_with("state 'closed'"), "{e}");
        let long = "x".repeat(201);
        assert!(AlertFilter::parse(&q(None, None, Some(&long))).is_err());
        let f = AlertFilter::parse(&q(Some(""), Some(""), Some("  "))).unwrap();
        assert_eq!(
            f,
            AlertFilter {
                level: None,
                state: "active",
                subject: String::new(),
                before: None,
            }
        );
    }

    /// Level is "at least", state `active` leaves resolved ones out, subject matches point or
    /// group names in any case.
    #[test]
    fn filters_select_what_they_say() {
        let alerts = [
            alert("watch", "open", Some("P7"), None),
            alert("warning", "acknowledged", Some("P12"), None),
            alert("alarm", "resolved", None, Some("Block-B1")),
            alert("alarm", "open", Some("P1"), None),
        ];
        let shown = |l, s, sub| {
            let f = AlertFilter::parse(&q(l, s, sub)).unwrap();
            alerts
                .iter()
                .enumerate()
                .filter(|(_, a)| f.matches(a))
                .map(|(k, _)| k)
                .collect::<Vec<_>>()
        };
        assert_eq!(shown(None, None, None), vec![0, 1, 3]);
        assert_eq!(shown(Some("warning"), None, None), vec![1, 3]);
        assert_eq!(shown(Some("alarm"), Some("all"), None), vec![2, 3]);
        assert_eq!(shown(None, Some("resolved"), None), vec![2]);
        assert_eq!(shown(None, Some("open"), None), vec![0, 3]);
        assert_eq!(shown(None, Some("all"), Some("b1")), vec![2]);
        assert_eq!(shown(None, None, Some("p1")), vec![1, 3]);
    }

    /// The form keeps the chosen values and swaps only the alert section.
    #[test]
    fn form_keeps_the_choice() {
        let f = AlertFilter::parse(&q(Some("warning"), Some("resolved"), Some("<b>"))).unwrap();
        let html = f.form("/sites/s").into_string();
        assert!(
            html.contains("<option value=\"warning\" selected>"),
            "{html}"
        );
        assert!(
            html.contains("<option value=\"resolved\" selected>"),
            "{html}"
        );
        assert!(html.contains("value=\"&lt;b&gt;\""), "{html}");
        assert!(html.contains("hx-select=\"#alerts\""), "{html}");
    }
}
