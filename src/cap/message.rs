//! One alert as a CAP 1.2 message (OASIS Common Alerting Protocol, `urn:oasis:names:tc:emergency:cap:1.2`).

use chrono::{DateTime, Duration, Utc};

use super::area::SiteArea;
use super::xml::{cap_time, escape};
use cliffwatch_core::analysis::{AlertEventType, AlertKind, AlertLevel};

/// The message's description: the alert's message, then the measured value against its
/// threshold and the campaign it was measured at.
fn description(now: &Snapshot) -> String {
    let mut description = now.message.clone();
    if let (Some(v), Some(unit)) = (now.value, now.unit.as_deref()) {
        description.push_str(&format!("\nMeasured {}", quantity(v, unit)));
        if let Some(t) = now.threshold {
            description.push_str(&format!(" (threshold {})", quantity(t, unit)));
        }
        if let Some(o) = &now.observed_at {
            description.push_str(&format!(" at the campaign of {o}"));
        }
        description.push('.');
    }
    description
}

/// What the public is asked to do at this step.
fn instruction(step: &CapStep) -> &'static str {
    match (step.msg_type, step.reason, step.level) {
        (MsgType::Cancel, "resolved", _) => {
            "The measured movement is back within the thresholds; the warning is withdrawn."
        }
        (MsgType::Cancel, _, _) => {
            "The level fell below warning; the site stays under watch and the warning is withdrawn."
        }
        (_, _, AlertLevel::Alarm) => {
            "Keep out of the warning area until the all-clear. Follow the instructions of the authorities."
        }
        _ => "Movement beyond the warning threshold was measured. Expect closures of the warning area and follow local instructions.",
    }
}

/// The `cliffwatch:` parameters: site, point or group, level, rule and the measured value.
fn parameters(alert: &Subject<'_>, step: &CapStep) -> Vec<(&'static str, String)> {
    let now = &step.snapshot;
    let mut parameters: Vec<(&str, String)> = vec![("cliffwatch:site", alert.site.into())];
    if let Some(p) = alert.point {
        parameters.push(("cliffwatch:point", p.into()));
    }
    if let Some(g) = alert.group {
        parameters.push(("cliffwatch:group", g.into()));
    }
    parameters.push(("cliffwatch:level", step.level.to_string()));
    parameters.push(("cliffwatch:rule", alert.rule.into()));
    if let (Some(v), Some(unit)) = (now.value, now.unit.as_deref()) {
        parameters.push(("cliffwatch:value", quantity(v, unit)));
    }
    parameters
}

/// The `<area>`: the configured area's description, polygon and circle, else the site's name.
fn area(d: &mut String, ctx: &CapContext<'_>) {
    d.push_str("    <area>\n");
    let area_desc = ctx.area.map_or(ctx.site_name, |a| a.description.as_str());
    element(d, 3, "areaDesc", area_desc);
    if let Some(p) = ctx.area.and_then(SiteArea::cap_polygon) {
        element(d, 3, "polygon", &p);
    }
    if let Some(c) = ctx.area.and_then(SiteArea::cap_circle) {
        element(d, 3, "circle", &c);
    }
    d.push_str("    </area>\n");
}

/// CAP `msgType` of a message in an alert's thread.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MsgType {
    /// The alert became public (raised at, or escalated to, warning or alarm).
    Alert,
    /// Its public level changed.
    Update,
    /// It was resolved or fell back below warning.
    Cancel,
}

impl MsgType {
    /// The CAP name.
    pub fn as_str(self) -> &'static str {
        match self {
            MsgType::Alert => "Alert",
            MsgType::Update => "Update",
            MsgType::Cancel => "Cancel",
        }
    }
}

/// What an alert said at one change: the measured value against the rule's threshold at an
/// epoch, and its message (the outbox event's `data`).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Snapshot {
    /// The value that triggered (or cleared) the rule, in `unit`.
    pub value: Option<f64>,
    /// The rule's threshold, in `unit`.
    pub threshold: Option<f64>,
    /// `mm`, `mm/day` or `h`.
    pub unit: Option<String>,
    /// The epoch's observation time (RFC 3339).
    pub observed_at: Option<String>,
    /// The alert's message then.
    pub message: String,
}

/// A recorded change of an alert (an outbox event): its contract type (`alert.raised`, …), the
/// level after it, when it was recorded (UTC), and the alert as it was then.
#[derive(Debug, Clone, PartialEq)]
pub struct Change {
    /// What changed.
    pub event_type: AlertEventType,
    /// The level after the change.
    pub level: Option<AlertLevel>,
    /// When the change was recorded.
    pub at: DateTime<Utc>,
    /// The alert as the change left it.
    pub snapshot: Snapshot,
}

/// One CAP message of an alert's thread.
#[derive(Debug, Clone, PartialEq)]
pub struct CapStep {
    /// 1, 2, …: the message's place in the thread (its identifier is `<alert id>.<seq>`).
    pub seq: usize,
    /// Alert, Update or Cancel.
    pub msg_type: MsgType,
    /// The public level the message announces (for a Cancel: the level it withdraws).
    pub level: AlertLevel,
    /// Why a Cancel was sent: `resolved` or `below_warning`; empty otherwise.
    pub reason: &'static str,
    /// When it was sent (the change's time).
    pub sent: DateTime<Utc>,
    /// The alert as the change left it.
    pub snapshot: Snapshot,
}

/// A level the public is told about: warning or alarm.
fn public_level(level: Option<AlertLevel>) -> Option<AlertLevel> {
    level.filter(|l| *l >= AlertLevel::Warning)
}

/// The CAP thread of an alert from its changes, oldest first: a change that makes it public is
/// an Alert, a change of its public level an Update, its resolution or fall to `watch` a
/// Cancel; acknowledgements and changes below warning send nothing.
pub fn steps(changes: &[Change]) -> Vec<CapStep> {
    let mut out: Vec<CapStep> = Vec::new();
    let mut public: Option<AlertLevel> = None;
    for c in changes {
        if c.event_type == AlertEventType::Acknowledged {
            continue;
        }
        let resolved = c.event_type == AlertEventType::Resolved;
        let now_public = if resolved {
            None
        } else {
            public_level(c.level)
        };
        let step = match (public, now_public) {
            (None, Some(now)) => Some((MsgType::Alert, now, "")),
            (Some(before), Some(now)) if now != before => Some((MsgType::Update, now, "")),
            (Some(before), None) => Some((
                MsgType::Cancel,
                before,
                if resolved {
                    "resolved"
                } else {
                    "below_warning"
                },
            )),
            _ => None,
        };
        if let Some((msg_type, level, reason)) = step {
            out.push(CapStep {
                seq: out.len() + 1,
                msg_type,
                level,
                reason,
                sent: c.at,
                snapshot: c.snapshot.clone(),
            });
        }
        public = now_public;
    }
    out
}

/// The alert a thread is about: its id, site, point or block group, and rule's metric.
#[derive(Debug, Clone, Copy)]
pub struct Subject<'a> {
    /// The alert's id.
    pub id: &'a str,
    /// Site id.
    pub site: &'a str,
    /// The point of a point alert.
    pub point: Option<&'a str>,
    /// The block group of a group alert.
    pub group: Option<&'a str>,
    /// The rule's metric, e.g. `displacement_mm` or `time_to_failure_hours`.
    pub rule: &'a str,
}

/// What a message needs besides the alert: who sends it, in which status, the site, and where
/// a person can see more.
#[derive(Debug, Clone)]
pub struct CapContext<'a> {
    /// CAP `sender` (no spaces, commas, `<` or `&`), e.g. `cliffwatch@agency.example`.
    pub sender: &'a str,
    /// CAP `status`: `Actual`, `Exercise`, `System`, `Test` or `Draft`.
    pub status: &'a str,
    /// The site's display name.
    pub site_name: &'a str,
    /// The site's warning area, when configured.
    pub area: Option<&'a SiteArea>,
    /// The dashboard page of the site (absolute URL), when a public URL is configured.
    pub web: Option<String>,
}

/// Appends `<name>value</name>` (value escaped) on its own line, indented `depth` levels.
fn element(doc: &mut String, depth: usize, name: &str, value: &str) {
    for _ in 0..depth {
        doc.push_str("  ");
    }
    doc.push_str(&format!("<{name}>{}</{name}>\n", escape(value)));
}

/// The identifier of message `seq` of an alert.
pub fn identifier(alert_id: &str, seq: usize) -> String {
    format!("{alert_id}.{seq}")
}

/// Urgency, severity, certainty and response of a level, and of a Cancel.
fn grading(step: &CapStep) -> (&'static str, &'static str, &'static str, &'static str) {
    match (step.msg_type, step.level) {
        (MsgType::Cancel, _) => ("Past", "Minor", "Unlikely", "AllClear"),
        (_, AlertLevel::Alarm) => ("Immediate", "Severe", "Likely", "Avoid"),
        _ => ("Expected", "Moderate", "Possible", "Monitor"),
    }
}

fn subject(alert: &Subject<'_>) -> String {
    match (alert.point, alert.group) {
        (Some(p), _) => format!("point {p}"),
        (None, Some(g)) => format!("block {g}"),
        _ => "the site".into(),
    }
}

fn level_word(level: AlertLevel) -> &'static str {
    match level {
        AlertLevel::Alarm => "Alarm",
        AlertLevel::Warning => "Warning",
        AlertLevel::Watch => "Watch",
    }
}

/// A value at most 3 decimals, no trailing zeros, no negative zero (`2.1`, `12`, `0`).
fn number(v: f64) -> String {
    let r = (v * 1000.0).round() / 1000.0;
    if r == 0.0 {
        "0".into()
    } else {
        format!("{r}")
    }
}

/// A value with its unit (`12.5 mm`), or the bare number when the unit is empty.
fn quantity(v: f64, unit: &str) -> String {
    let unit = unit.trim();
    if unit.is_empty() {
        number(v)
    } else {
        format!("{} {unit}", number(v))
    }
}

/// The rules whose alerts the public feed carries: movement (displacement, velocity, time to
/// failure, of points and of blocks). Datum and system alerts (`reference_unstable`,
/// `campaign_overdue`, `analysis_failed`) stay internal: API, dashboard, webhooks.
pub const PUBLIC_RULES: [AlertKind; 4] = [
    AlertKind::DisplacementMm,
    AlertKind::DisplacementAlongMm,
    AlertKind::VelocityMmPerDay,
    AlertKind::TimeToFailureHours,
];

/// Whether alerts of `rule` (its contract name) are published in the CAP feed
/// ([`PUBLIC_RULES`]).
pub fn is_public_rule(rule: &str) -> bool {
    PUBLIC_RULES.iter().any(|k| k.as_str() == rule)
}

/// The headline of a message, e.g. `Alarm: rock slope movement at Kamo cliff (point 12)`.
pub fn headline(alert: &Subject<'_>, site_name: &str, step: &CapStep) -> String {
    let word = level_word(step.level);
    match step.msg_type {
        MsgType::Cancel => format!(
            "{word} withdrawn: rock slope movement at {site_name} ({})",
            subject(alert)
        ),
        _ => format!(
            "{word}: rock slope movement at {site_name} ({})",
            subject(alert)
        ),
    }
}

/// The forecast failure time of a time-to-failure alert (CAP `onset`): the epoch's time plus
/// the forecast hours.
fn onset(alert: &Subject<'_>, now: &Snapshot) -> Option<DateTime<Utc>> {
    if alert.rule != "time_to_failure_hours" {
        return None;
    }
    let hours = now
        .value
        .filter(|h| h.is_finite() && *h >= 0.0 && *h < 1e6)?;
    let observed = DateTime::parse_from_rfc3339(now.observed_at.as_deref()?).ok()?;
    Some(observed.with_timezone(&Utc) + Duration::seconds((hours * 3600.0).round() as i64))
}

/// Message `step` of the alert's thread `thread` as a CAP 1.2 document; the earlier messages
/// are its `references`, the alert id its `incidents`.
pub fn cap_message(
    alert: &Subject<'_>,
    ctx: &CapContext<'_>,
    thread: &[CapStep],
    step: &CapStep,
) -> String {
    let (urgency, severity, certainty, response) = grading(step);
    let headline = headline(alert, ctx.site_name, step);
    let now = &step.snapshot;
    let references: Vec<String> = thread
        .iter()
        .filter(|s| s.seq < step.seq)
        .map(|s| {
            format!(
                "{},{},{}",
                ctx.sender,
                identifier(alert.id, s.seq),
                cap_time(s.sent)
            )
        })
        .collect();

    let mut doc = String::with_capacity(4096);
    doc.push_str("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n");
    doc.push_str("<alert xmlns=\"urn:oasis:names:tc:emergency:cap:1.2\">\n");
    let d = &mut doc;
    element(d, 1, "identifier", &identifier(alert.id, step.seq));
    element(d, 1, "sender", ctx.sender);
    element(d, 1, "sent", &cap_time(step.sent));
    element(d, 1, "status", ctx.status);
    element(d, 1, "msgType", step.msg_type.as_str());
    element(d, 1, "source", "cliffwatch photogrammetric monitoring");
    element(d, 1, "scope", "Public");
    if !references.is_empty() {
        element(d, 1, "references", &references.join(" "));
    }
    element(d, 1, "incidents", alert.id);
    d.push_str("  <info>\n");
    element(d, 2, "language", "en-US");
    element(d, 2, "category", "Geo");
    element(d, 2, "event", "Rock slope movement");
    element(d, 2, "responseType", response);
    element(d, 2, "urgency", urgency);
    element(d, 2, "severity", severity);
    element(d, 2, "certainty", certainty);
    element(d, 2, "effective", &cap_time(step.sent));
    if step.msg_type != MsgType::Cancel {
        if let Some(t) = onset(alert, now) {
            element(d, 2, "onset", &cap_time(t));
        }
    }
    element(
        d,
        2,
        "senderName",
        &format!("cliffwatch: {}", ctx.site_name),
    );
    element(d, 2, "headline", &headline);
    element(d, 2, "description", &description(now));
    element(d, 2, "instruction", instruction(step));
    if let Some(web) = &ctx.web {
        element(d, 2, "web", web);
    }
    for (name, value) in &parameters(alert, step) {
        d.push_str("    <parameter>\n");
        element(d, 3, "valueName", name);
        element(d, 3, "value", value);
        d.push_str("    </parameter>\n");
    }
    area(d, ctx);
    doc.push_str("  </info>\n</alert>\n");
    doc
}

#[cfg(test)]
mod tests {
    use super::*;

    fn change(kind: &str, level: &str, minute: i64) -> Change {
        Change {
            event_type: kind.parse().unwrap(),
            level: Some(level.parse().unwrap()),
            at: DateTime::parse_from_rfc3339("2026-11-25T00:00:00Z")
                .unwrap()
                .with_timezone(&Utc)
                + Duration::minutes(minute),
            snapshot: Snapshot::default(),
        }
    }

    fn kinds(s: &[CapStep]) -> Vec<(MsgType, &str)> {
        s.iter().map(|s| (s.msg_type, s.level.as_str())).collect()
    }

    #[test]
    fn a_thread_goes_public_updates_and_cancels() {
        let s = steps(&[
            change("alert.raised", "watch", 0),
            change("alert.escalated", "warning", 1),
            change("alert.acknowledged", "warning", 2),
            change("alert.escalated", "alarm", 3),
            change("alert.deescalated", "warning", 4),
            change("alert.resolved", "warning", 5),
        ]);
        assert_eq!(
            kinds(&s),
            vec![
                (MsgType::Alert, "warning"),
                (MsgType::Update, "alarm"),
                (MsgType::Update, "warning"),
                (MsgType::Cancel, "warning"),
            ]
        );
        assert_eq!(
            s.iter().map(|s| s.seq).collect::<Vec<_>>(),
            vec![1, 2, 3, 4]
        );
        assert_eq!(s[3].reason, "resolved");
    }

    #[test]
    fn a_time_to_failure_alarm_carries_the_forecast_as_onset() {
        let mut raised = change("alert.raised", "alarm", 0);
        raised.snapshot = Snapshot {
            value: Some(48.0),
            threshold: Some(96.0),
            unit: Some("h".into()),
            observed_at: Some("2026-11-20T06:00:00Z".into()),
            message: "kamo/P7: time to failure 48 h".into(),
        };
        let thread = steps(&[raised]);
        let subject = Subject {
            id: "kamo:P7:time_to_failure_hours:3",
            site: "kamo",
            point: Some("P7"),
            group: None,
            rule: "time_to_failure_hours",
        };
        let ctx = CapContext {
            sender: "cliffwatch@agency.example",
            status: "Test",
            site_name: "Kamo",
            area: None,
            web: None,
        };
        let xml = cap_message(&subject, &ctx, &thread, &thread[0]);
        assert!(
            xml.contains("<onset>2026-11-22T06:00:00+00:00</onset>"),
            "{xml}"
        );
        assert!(xml.contains("<msgType>Alert</msgType>") && xml.contains("<status>Test</status>"));
        assert!(
            xml.contains("<severity>Severe</severity>")
                && xml.contains("<urgency>Immediate</urgency>")
        );
        assert!(
            xml.contains("<areaDesc>Kamo</areaDesc>"),
            "the site's name without an area"
        );
        assert!(
            !xml.contains("<references>"),
            "the first message references nothing"
        );
    }

    #[test]
    fn watch_only_alerts_send_nothing_and_a_fall_to_watch_cancels() {
        assert!(steps(&[
            change("alert.raised", "watch", 0),
            change("alert.resolved", "watch", 1)
        ])
        .is_empty());
        let s = steps(&[
            change("alert.raised", "alarm", 0),
            change("alert.deescalated", "watch", 1),
            change("alert.escalated", "warning", 2),
        ]);
        assert_eq!(
            kinds(&s),
            vec![
                (MsgType::Alert, "alarm"),
                (MsgType::Cancel, "alarm"),
                (MsgType::Alert, "warning"),
            ]
        );
        assert_eq!(s[1].reason, "below_warning");
    }
}
