//! What Alertmanager is told, as its clients are meant to talk to it: every open alert posted
//! again on a short period with `endsAt` a few periods ahead (as Prometheus does), a resolved
//! one posted resolved until the `endsAt` Alertmanager held has passed, and the level as one
//! alert per level at or below the current one (lower levels stay firing while a higher one is
//! active; an inhibit rule mutes them, README "Alertmanager"), so no receiver sees a resolution
//! at the moment things got worse. Pure: the re-post loop ([`crate::workers::alertmanager_resend`])
//! reads the alerts from the store and sends what these functions build.

use std::collections::BTreeMap;

use chrono::{DateTime, Duration, SecondsFormat, Utc};

use serde::{Deserialize, Serialize};

use crate::url_path::seg;
use cliffwatch_core::analysis::AlertLevel;

/// How many re-post periods an alert posted firing stays firing in Alertmanager without news
/// (`endsAt` = now + this × period): Prometheus uses 4 × its resend delay, so that a couple of
/// lost posts do not resolve an alert.
pub const HOLD_PERIODS: i32 = 4;

/// The levels, lowest first.
const LEVELS: [AlertLevel; 3] = [AlertLevel::Watch, AlertLevel::Warning, AlertLevel::Alarm];

/// One cliffwatch alert as it is now, as Alertmanager needs it.
#[derive(Debug, Clone, PartialEq)]
pub struct CurrentAlert {
    /// cliffwatch's alert id (an annotation, and the dashboard page's path).
    pub id: String,
    /// Site id.
    pub site: String,
    /// The point of a point alert.
    pub point: Option<String>,
    /// The block group of a group alert.
    pub group: Option<String>,
    /// Points concerned by a site-level or group alert.
    pub points: Vec<String>,
    /// The rule's metric or site-level kind (`displacement_mm`, `reference_unstable`, …).
    pub rule: String,
    /// Its level now (at resolution, the level it had).
    pub level: AlertLevel,
    /// The highest level it ever reached.
    pub peak_level: AlertLevel,
    /// Latest value, in `unit`.
    pub value: Option<f64>,
    /// Threshold of the rule behind the level, in `unit`.
    pub threshold: Option<f64>,
    /// Unit of value and threshold (may be empty).
    pub unit: String,
    /// Latest epoch that evaluated it.
    pub epoch: Option<i64>,
    /// That epoch's observation time.
    pub observed_at: Option<DateTime<Utc>>,
    /// Human-readable summary.
    pub message: String,
    /// When it was raised (`startsAt`).
    pub raised_at: DateTime<Utc>,
    /// Its latest change (on the store's clock): the resolution's time once resolved, the
    /// de-escalation's while lower than its peak.
    pub changed_at: DateTime<Utc>,
    /// Whether it is resolved.
    pub resolved: bool,
    /// The incident it belongs to (its block, its point or the site), when known: its page is
    /// the link Alertmanager carries (`generatorURL`).
    pub incident: Option<IncidentLink>,
}

/// The incident an alert belongs to, as its links name it: its id within the site
/// (`block:B1`, `point:T203`, `site`) and its dashboard page (a path, `/sites/s1/groups/B1`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct IncidentLink {
    /// The incident's id within its site.
    pub key: String,
    /// Its dashboard page, a path from the dashboard's root.
    pub page: String,
}

/// The incident's page under `public_url` (`{public_url}{page}`), or `None` without a public
/// URL.
pub fn incident_page_url(public_url: Option<&str>, incident: &IncidentLink) -> Option<String> {
    let base = public_url?.trim_end_matches('/');
    if base.is_empty() {
        return None;
    }
    Some(format!("{base}{}", incident.page))
}

/// The page a receiver links to: the incident's when known (staff act on incidents), else the
/// alert's; `None` without a public URL.
pub fn link_of(
    public_url: Option<&str>,
    site: &str,
    alert_id: &str,
    incident: Option<&IncidentLink>,
) -> Option<String> {
    match incident {
        Some(i) => incident_page_url(public_url, i),
        None => alert_page_url(public_url, site, alert_id),
    }
}

fn t(x: DateTime<Utc>) -> String {
    x.to_rfc3339_opts(SecondsFormat::Secs, true)
}

/// A number as an annotation: at most 3 decimals, no trailing zeros (`2.1`, `12`).
pub fn number(v: f64) -> String {
    let r = (v * 1000.0).round() / 1000.0;
    if r == 0.0 {
        "0".into()
    } else {
        format!("{r}")
    }
}

/// The alert's dashboard page (`{public_url}/sites/{site}/alerts/{id}`), or `None` without a
/// public URL: a link relative to cliffwatch means nothing in a receiver.
pub fn alert_page_url(public_url: Option<&str>, site: &str, alert_id: &str) -> Option<String> {
    let base = public_url?.trim_end_matches('/');
    if base.is_empty() {
        return None;
    }
    Some(format!(
        "{base}/sites/{}/alerts/{}",
        seg(site),
        seg(alert_id)
    ))
}

/// Alertmanager's fingerprint of a label set (`model.LabelSet.Fingerprint` of
/// prometheus/common): FNV-1a 64 over the label names in byte order, each name and value
/// followed by the separator byte 0xFF, printed as 16 lower-case hex digits.
pub fn fingerprint(labels: &BTreeMap<String, String>) -> String {
    const OFFSET: u64 = 14_695_981_039_346_656_037;
    const PRIME: u64 = 1_099_511_628_211;
    let mut h = OFFSET;
    let mut add = |bytes: &[u8]| {
        for &b in bytes {
            h ^= u64::from(b);
            h = h.wrapping_mul(PRIME);
        }
    };
    // BTreeMap iterates in byte order of the names, as Go's sort of strings does.
    for (name, value) in labels {
        add(name.as_bytes());
        add(&[0xFF]);
        add(value.as_bytes());
        add(&[0xFF]);
    }
    format!("{h:016x}")
}

/// The labels of the alert at `level`: `alertname` (`cliffwatch_{rule}`), `site`, `point`
/// (point alerts), `group` (group alerts), `rule` and `severity` (the level). Together they
/// are the alert's identity in Alertmanager: one per subject, rule and level.
pub fn labels(
    rule: &str,
    site: &str,
    point: Option<&str>,
    group: Option<&str>,
    level: AlertLevel,
) -> BTreeMap<String, String> {
    let mut l = BTreeMap::new();
    l.insert("alertname".to_string(), format!("cliffwatch_{rule}"));
    l.insert("site".to_string(), site.to_string());
    if let Some(p) = point {
        l.insert("point".to_string(), p.to_string());
    }
    if let Some(g) = group {
        l.insert("group".to_string(), g.to_string());
    }
    l.insert("rule".to_string(), rule.to_string());
    l.insert("severity".to_string(), level.as_str().to_string());
    l
}

/// `summary`, `alert_id`, `level` (the level now), `value`, `threshold`, `unit`, `epoch`, `incident`,
/// `observed_at` and `points`, as far as known.
fn annotations(a: &CurrentAlert) -> BTreeMap<String, String> {
    let mut m = BTreeMap::new();
    m.insert("summary".to_string(), a.message.clone());
    m.insert("alert_id".to_string(), a.id.clone());
    m.insert("level".to_string(), a.level.as_str().to_string());
    if let Some(v) = a.value {
        m.insert("value".to_string(), number(v));
    }
    if let Some(v) = a.threshold {
        m.insert("threshold".to_string(), number(v));
    }
    if !a.unit.is_empty() {
        m.insert("unit".to_string(), a.unit.clone());
    }
    if let Some(e) = a.epoch {
        m.insert("epoch".to_string(), e.to_string());
    }
    if let Some(o) = a.observed_at {
        m.insert("observed_at".to_string(), t(o));
    }
    if !a.points.is_empty() {
        m.insert("points".to_string(), a.points.join(","));
    }
    if let Some(i) = &a.incident {
        m.insert("incident".to_string(), i.key.clone());
    }
    m
}

/// What Alertmanager is to hold of one alert at `now`, with firing alerts held for `hold`
/// (`endsAt` = now + hold; [`HOLD_PERIODS`] × the re-post period):
/// - open or acknowledged: every level from `watch` to its level firing; the levels above it
///   that it reached before (a de-escalation) resolved at its latest change, for `hold` after it;
/// - resolved: every level it reached, resolved at its resolution, for `hold` after it (until
///   the `endsAt` Alertmanager held has passed); nothing afterwards.
pub fn postable_alerts(
    a: &CurrentAlert,
    now: DateTime<Utc>,
    hold: Duration,
    public_url: Option<&str>,
) -> Vec<PostableAlert> {
    told(a, now, hold, public_url)
        .into_iter()
        .map(|(_, p)| p)
        .collect()
}

/// [`postable_alerts`], each with whether it is posted firing.
fn told(
    a: &CurrentAlert,
    now: DateTime<Utc>,
    hold: Duration,
    public_url: Option<&str>,
) -> Vec<(bool, PostableAlert)> {
    let annotations = annotations(a);
    let generator_url =
        link_of(public_url, &a.site, &a.id, a.incident.as_ref()).unwrap_or_default();
    let ended = a.changed_at.min(now);
    let still_told = now < a.changed_at + hold;
    LEVELS
        .into_iter()
        .filter(|l| *l <= a.peak_level.max(a.level))
        .filter_map(|level| {
            let firing = !a.resolved && level <= a.level;
            if !firing && !still_told {
                return None;
            }
            Some((
                firing,
                PostableAlert {
                    labels: labels(
                        &a.rule,
                        &a.site,
                        a.point.as_deref(),
                        a.group.as_deref(),
                        level,
                    ),
                    annotations: annotations.clone(),
                    starts_at: t(a.raised_at),
                    ends_at: t(if firing { now + hold } else { ended }),
                    generator_url: generator_url.clone(),
                },
            ))
        })
        .collect()
}

/// The body of one re-post: the [`postable_alerts`] of every alert, one entry per label set.
/// An alert resolved and a new one of the same subject and rule share their labels; the firing
/// entry wins (Alertmanager would keep whichever came last).
pub fn resend_body(
    alerts: &[CurrentAlert],
    now: DateTime<Utc>,
    hold: Duration,
    public_url: Option<&str>,
) -> Vec<PostableAlert> {
    let mut by_labels: BTreeMap<BTreeMap<String, String>, (bool, PostableAlert)> = BTreeMap::new();
    for a in alerts {
        for (firing, p) in told(a, now, hold, public_url) {
            match by_labels.get(&p.labels) {
                Some((true, _)) if !firing => {}
                _ => {
                    by_labels.insert(p.labels.clone(), (firing, p));
                }
            }
        }
    }
    by_labels.into_values().map(|(_, p)| p).collect()
}

/// One alert of Alertmanager's API v2 `POST /api/v2/alerts` body (`postableAlert`): the body is
/// a JSON array of these.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PostableAlert {
    /// Identity and routing labels ([`labels`]): `alertname` (`cliffwatch_{rule}`), `site`,
    /// `point` (point alerts), `group` (group alerts), `rule`, `severity` (the level).
    pub labels: BTreeMap<String, String>,
    /// `summary`, `alert_id`, `level`, `value`, `threshold`, `unit`, `epoch`, `observed_at`,
    /// `points` and `incident` (`block:B1`, …) when known.
    pub annotations: BTreeMap<String, String>,
    /// When the alert was raised, RFC 3339.
    #[serde(rename = "startsAt")]
    pub starts_at: String,
    /// Firing: a few re-post periods ahead ([`HOLD_PERIODS`]); resolved: the resolution's time.
    #[serde(rename = "endsAt")]
    pub ends_at: String,
    /// The alert's dashboard page (omitted when no public URL is configured).
    #[serde(
        rename = "generatorURL",
        default,
        skip_serializing_if = "String::is_empty"
    )]
    pub generator_url: String,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(s: &str) -> DateTime<Utc> {
        DateTime::parse_from_rfc3339(s).unwrap().to_utc()
    }

    fn alert(level: AlertLevel, peak: AlertLevel, resolved: bool) -> CurrentAlert {
        CurrentAlert {
            id: "cliff:T009:displacement_mm:2".into(),
            site: "cliff".into(),
            point: Some("T009".into()),
            group: None,
            points: vec![],
            rule: "displacement_mm".into(),
            level,
            peak_level: peak,
            value: Some(12.34567),
            threshold: Some(10.0),
            unit: "mm".into(),
            epoch: Some(2),
            observed_at: Some(at("2026-11-02T09:00:00Z")),
            message: "moved".into(),
            raised_at: at("2026-12-01T10:00:00Z"),
            changed_at: at("2026-12-01T11:00:00Z"),
            resolved,
            incident: None,
        }
    }

    fn severities(body: &[PostableAlert], firing: bool, now: DateTime<Utc>) -> Vec<String> {
        body.iter()
            .filter(|p| (p.ends_at > t(now)) == firing)
            .map(|p| p.labels["severity"].clone())
            .collect()
    }

    /// Values Alertmanager 0.25 gave (`fingerprint` of `GET /api/v2/alerts` after posting these
    /// label sets), and the empty set's FNV-1a offset.
    #[test]
    fn fingerprint_is_alertmanagers() {
        assert_eq!(fingerprint(&BTreeMap::new()), "cbf29ce484222325");
        let one = BTreeMap::from([("alertname".to_string(), "x".to_string())]);
        assert_eq!(fingerprint(&one), "d240efc3896bf266");
        let point = labels(
            "displacement_mm",
            "cliff",
            Some("T009"),
            None,
            AlertLevel::Watch,
        );
        assert_eq!(fingerprint(&point), "3ba11736b11921cc");
    }

    #[test]
    fn an_escalated_alert_keeps_its_lower_levels_firing() {
        let now = at("2026-12-01T12:00:00Z");
        let hold = Duration::seconds(240);
        let body = postable_alerts(
            &alert(AlertLevel::Alarm, AlertLevel::Alarm, false),
            now,
            hold,
            Some("https://cw.example.org/"),
        );
        assert_eq!(
            severities(&body, true, now),
            ["watch", "warning", "alarm"],
            "{body:?}"
        );
        for p in &body {
            assert_eq!(p.ends_at, "2026-12-01T12:04:00Z");
            assert_eq!(p.starts_at, "2026-12-01T10:00:00Z");
            assert_eq!(
                p.generator_url,
                "https://cw.example.org/sites/cliff/alerts/cliff%3AT009%3Adisplacement_mm%3A2"
            );
            assert_eq!(p.annotations["value"], "12.346");
            assert_eq!(p.annotations["threshold"], "10");
        }
    }

    #[test]
    fn a_deescalated_level_is_resolved_for_one_hold_then_dropped() {
        let a = alert(AlertLevel::Watch, AlertLevel::Warning, false);
        let hold = Duration::seconds(240);
        let soon = a.changed_at + Duration::seconds(100);
        let body = postable_alerts(&a, soon, hold, None);
        assert_eq!(severities(&body, true, soon), ["watch"]);
        assert_eq!(severities(&body, false, soon), ["warning"]);
        assert!(body.iter().all(|p| p.generator_url.is_empty()));
        let later = a.changed_at + Duration::seconds(241);
        let body = postable_alerts(&a, later, hold, None);
        assert_eq!(severities(&body, false, later), Vec::<String>::new());
        assert_eq!(severities(&body, true, later), ["watch"]);
    }

    #[test]
    fn a_resolved_alert_is_posted_resolved_until_its_hold_passed() {
        let a = alert(AlertLevel::Warning, AlertLevel::Warning, true);
        let hold = Duration::seconds(240);
        let soon = a.changed_at + Duration::seconds(10);
        let body = postable_alerts(&a, soon, hold, None);
        assert_eq!(severities(&body, false, soon), ["watch", "warning"]);
        assert!(body.iter().all(|p| p.ends_at == t(a.changed_at)));
        assert!(postable_alerts(&a, a.changed_at + hold, hold, None).is_empty());
    }

    #[test]
    fn a_new_alert_wins_over_the_resolved_one_of_the_same_subject() {
        let old = alert(AlertLevel::Watch, AlertLevel::Watch, true);
        let mut new = alert(AlertLevel::Watch, AlertLevel::Watch, false);
        new.id.push_str(":2");
        let now = old.changed_at + Duration::seconds(5);
        for order in [[old.clone(), new.clone()], [new.clone(), old.clone()]] {
            let body = resend_body(&order, now, Duration::seconds(240), None);
            assert_eq!(body.len(), 1, "{body:?}");
            assert_eq!(body[0].annotations["alert_id"], new.id);
        }
    }

    #[test]
    fn numbers_have_no_trailing_noise() {
        assert_eq!(number(2.1), "2.1");
        assert_eq!(number(2.0), "2");
        assert_eq!(number(-0.0001), "0");
        assert_eq!(number(0.1 + 0.2), "0.3");
    }
}
