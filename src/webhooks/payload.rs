//! Webhook payloads: the contract body, endpoint filtering by level, the Alertmanager webhook body
//! (v4) and the Alertmanager API v2 body, and [`render`], the body of an endpoint's format.

use chrono::{DateTime, SecondsFormat, Utc};
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::collections::BTreeMap;

use super::alertmanager::{
    alert_page_url, fingerprint, incident_page_url, labels, link_of, number, postable_alerts,
    CurrentAlert, IncidentLink, PostableAlert, HOLD_PERIODS,
};
use cliffwatch_core::analysis::{AlertEvent, AlertEventType, AlertLevel};

/// Default re-post period of the Alertmanager API v2 endpoints, seconds
/// (`alertmanager_resend_secs`).
pub const DEFAULT_RESEND_SECS: i64 = 60;

/// Body format of an endpoint: what the delivery worker POSTs for each event. Every format is
/// signed the same way (Standard Webhooks headers), so a proxy in front of Alertmanager can verify
/// it; the serde names are the values of `format` in `POST /api/v1/webhooks` and `[[webhooks]]`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PayloadFormat {
    /// `standard`: the contract's body `{"type", "timestamp", "data"}` (default).
    #[default]
    Standard,
    /// `alertmanager_webhook`: the body Prometheus Alertmanager sends to its webhook receivers
    /// (version 4, [`alertmanager_body`]), for receivers built for Alertmanager.
    AlertmanagerWebhook,
    /// `alertmanager_api_v2`: the body of Alertmanager's `POST /api/v2/alerts` (a JSON array of
    /// postable alerts, [`alertmanager_alerts`]), for routing through Alertmanager or Grafana: the
    /// endpoint URL is e.g. `http://alertmanager:9093/api/v2/alerts`.
    AlertmanagerApiV2,
}

cliffwatch_core::contract_names!(PayloadFormat, "webhook body format" {
    Standard => "standard",
    AlertmanagerWebhook => "alertmanager_webhook",
    AlertmanagerApiV2 => "alertmanager_api_v2",
});

/// A webhook endpoint (`POST /api/v1/webhooks` or `[[webhooks]]`).
/// No `Debug`: it holds the signing secret, which must never reach a log.
#[derive(Clone, PartialEq, Serialize, Deserialize)]
pub struct WebhookEndpoint {
    /// Endpoint id.
    pub id: String,
    /// Target URL.
    pub url: String,
    /// `whsec_…` secret.
    pub secret: String,
    /// Lowest level delivered (default: all).
    #[serde(default)]
    pub min_level: Option<AlertLevel>,
    /// Body format.
    #[serde(default)]
    pub format: PayloadFormat,
    /// False after a 410 Gone.
    #[serde(default = "enabled")]
    pub enabled: bool,
}

fn enabled() -> bool {
    true
}

/// Whether the endpoint takes this event: enabled and the alert's peak level ≥ `min_level` (the peak, so
/// that an endpoint told of an alert also hears of its de-escalation and resolution).
pub fn accepts(endpoint: &WebhookEndpoint, event: &AlertEvent) -> bool {
    endpoint.enabled
        && endpoint
            .min_level
            .is_none_or(|m| event.alert.peak_level.max(event.alert.level) >= m)
}

/// `data` of the contract body.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct WebhookData {
    /// Alert id.
    pub alert_id: String,
    /// Site id.
    pub site: String,
    /// Point (null for site-level and block-group alerts).
    pub point: Option<String>,
    /// Block group of a group alert (absent otherwise).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub group: Option<String>,
    /// Points concerned by a site-level or group alert.
    #[serde(skip_serializing_if = "Vec::is_empty", default)]
    pub points: Vec<String>,
    /// Level.
    pub level: AlertLevel,
    /// Metric or site-level kind.
    pub rule: String,
    /// Value (unit in `unit`).
    pub value: Option<f64>,
    /// Threshold (unit in `unit`).
    pub threshold: Option<f64>,
    /// Unit of value and threshold.
    pub unit: String,
    /// Epoch id.
    pub epoch: Option<i64>,
    /// Observation time of the epoch, RFC 3339 UTC.
    pub observed_at: Option<String>,
    /// Summary.
    pub message: String,
    /// Who acknowledged the alert (`alert.acknowledged` only).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub acknowledged_by: Option<String>,
    /// The acknowledgement's comment, when one was given (`alert.acknowledged` only).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub comment: Option<String>,
    /// The alert's dashboard page under `public_url` (absent when no public URL is
    /// configured).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub url: Option<String>,
    /// The incident the alert belongs to: `block:B1` (a declared block with its points),
    /// `point:T203` (a point in no block) or `site`; what staff act on.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub incident: Option<String>,
    /// The incident's dashboard page under `public_url` (the block's, the point's or the
    /// site's; absent when no public URL is configured): the link to open.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub incident_url: Option<String>,
    /// For `alert.deescalated` and `alert.resolved` decided by the rules: the test that decided
    /// it (the rule's level, value, σ, threshold, confidence; absent otherwise, and in events
    /// recorded before it existed).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub cleared_by: Option<cliffwatch_core::analysis::ClearingTest>,
}

/// The contract body `{"type", "timestamp", "data"}`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct WebhookPayload {
    /// `alert.raised`, `alert.escalated`, …
    #[serde(rename = "type")]
    pub event_type: String,
    /// Event time, RFC 3339 UTC, seconds.
    pub timestamp: String,
    /// The alert.
    pub data: WebhookData,
}

fn t(x: DateTime<Utc>) -> String {
    x.to_rfc3339_opts(SecondsFormat::Secs, true)
}

impl WebhookPayload {
    /// Builds the body of an event; `public_url` (where people reach the dashboard) gives
    /// `data.url`, the alert's page, and with `incident` (the incident the alert belongs to)
    /// `data.incident_url`.
    pub fn from_event(
        event: &AlertEvent,
        public_url: Option<&str>,
        incident: Option<&IncidentLink>,
    ) -> Self {
        let a = &event.alert;
        let acknowledged = event.event_type == AlertEventType::Acknowledged;
        WebhookPayload {
            event_type: event.event_type.as_str().to_string(),
            timestamp: t(event.timestamp),
            data: WebhookData {
                alert_id: a.id.clone(),
                site: a.site.clone(),
                point: a.point.clone(),
                group: a.group.clone(),
                points: if a.point.is_none() {
                    a.points.clone()
                } else {
                    vec![]
                },
                level: a.level,
                rule: a.rule.as_str().to_string(),
                value: a.value,
                threshold: a.threshold,
                unit: a.unit.clone(),
                epoch: a.epoch,
                observed_at: a.observed_at.map(t),
                message: a.message.clone(),
                acknowledged_by: a.acknowledged_by.clone().filter(|_| acknowledged),
                comment: a.comment.clone().filter(|_| acknowledged),
                url: alert_page_url(public_url, &a.site, &a.id),
                incident: incident.map(|i| i.key.clone()),
                incident_url: incident.and_then(|i| incident_page_url(public_url, i)),
                cleared_by: event.cleared_by.clone(),
            },
        }
    }
}

/// Deterministic message id (`msg_` + 32 hex) of an event: the same event always gets the same
/// `webhook-id`, so a rebuilt outbox row keeps it too. The event time enters at full precision
/// (nanoseconds), not at the body's seconds: an alert that de-escalates and escalates back to
/// the same level within one second has two escalations, and each must keep its own message.
pub fn message_id(event: &AlertEvent) -> String {
    message_id_of(&[
        event.alert.id.as_bytes(),
        event.event_type.as_str().as_bytes(),
        event
            .timestamp
            .to_rfc3339_opts(SecondsFormat::Nanos, true)
            .as_bytes(),
        event.alert.level.as_str().as_bytes(),
    ])
}

/// A message id, `msg_` + 32 hex: the first 16 bytes of the SHA-256 of `parts` joined by `|`
/// (the same parts always give the same id).
pub fn message_id_of(parts: &[&[u8]]) -> String {
    let mut h = Sha256::new();
    for (k, p) in parts.iter().enumerate() {
        if k > 0 {
            h.update(b"|");
        }
        h.update(p);
    }
    let d = h.finalize();
    format!(
        "msg_{}",
        d[..16]
            .iter()
            .map(|b| format!("{b:02x}"))
            .collect::<String>()
    )
}

/// One alert of the Alertmanager body.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "camelCase")]
pub struct AlertmanagerAlert {
    /// `firing` or `resolved`.
    pub status: String,
    /// Labels: alertname, site, point, severity, rule.
    pub labels: BTreeMap<String, String>,
    /// Annotations: summary, value, threshold, unit, event.
    pub annotations: BTreeMap<String, String>,
    /// RFC 3339.
    pub starts_at: String,
    /// RFC 3339; `0001-01-01T00:00:00Z` while firing.
    pub ends_at: String,
    /// Link back (empty).
    #[serde(rename = "generatorURL")]
    pub generator_url: String,
    /// Alert id.
    pub fingerprint: String,
}

/// The Alertmanager webhook body (version 4).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "camelCase")]
pub struct AlertmanagerBody {
    /// "4".
    pub version: String,
    /// Group key (site and rule).
    pub group_key: String,
    /// Always 0.
    pub truncated_alerts: u32,
    /// `firing` or `resolved`.
    pub status: String,
    /// Receiver name (the endpoint id).
    pub receiver: String,
    /// Group labels.
    pub group_labels: BTreeMap<String, String>,
    /// Common labels.
    pub common_labels: BTreeMap<String, String>,
    /// Common annotations.
    pub common_annotations: BTreeMap<String, String>,
    /// External URL (empty).
    #[serde(rename = "externalURL")]
    pub external_url: String,
    /// The one alert.
    pub alerts: Vec<AlertmanagerAlert>,
}

/// The body of an event in an endpoint's format, serialized as sent: the contract body
/// ([`WebhookPayload`]), the Alertmanager webhook body with the endpoint id as `receiver`
/// ([`alertmanager_body`]), or the Alertmanager API v2 array ([`alertmanager_alerts`], held
/// [`HOLD_PERIODS`] default periods). `public_url`: where the dashboard is reached, for the
/// links to the alert's page (`None`: no link); `incident`: the incident the alert belongs to,
/// whose page the links open when known.
pub fn render(
    event: &AlertEvent,
    endpoint: &WebhookEndpoint,
    public_url: Option<&str>,
    incident: Option<&IncidentLink>,
) -> Result<String, serde_json::Error> {
    match endpoint.format {
        PayloadFormat::Standard => {
            serde_json::to_string(&WebhookPayload::from_event(event, public_url, incident))
        }
        PayloadFormat::AlertmanagerWebhook => serde_json::to_string(&alertmanager_body(
            event,
            &endpoint.id,
            public_url,
            incident,
        )),
        PayloadFormat::AlertmanagerApiV2 => serde_json::to_string(&alertmanager_alerts(
            event,
            public_url,
            incident,
            chrono::Duration::seconds(i64::from(HOLD_PERIODS) * DEFAULT_RESEND_SECS),
        )),
    }
}

/// Alertmanager-compatible body of an event (`resolved` for `alert.resolved`, else `firing`),
/// as Alertmanager sends it to a webhook receiver: `fingerprint` is Alertmanager's hash of the
/// labels ([`fingerprint`]), `generatorURL` the incident's dashboard page when `incident` is
/// known, else the alert's (empty without a public URL), `externalURL` the public URL.
pub fn alertmanager_body(
    event: &AlertEvent,
    receiver: &str,
    public_url: Option<&str>,
    incident: Option<&IncidentLink>,
) -> AlertmanagerBody {
    let a = &event.alert;
    let status = if event.event_type == AlertEventType::Resolved {
        "resolved"
    } else {
        "firing"
    };
    let labels = labels(
        a.rule.as_str(),
        &a.site,
        a.point.as_deref(),
        a.group.as_deref(),
        a.level,
    );
    let mut ann = BTreeMap::new();
    ann.insert("summary".to_string(), a.message.clone());
    ann.insert("event".to_string(), event.event_type.as_str().to_string());
    ann.insert("alert_id".to_string(), a.id.clone());
    if let Some(v) = a.value {
        ann.insert("value".to_string(), number(v));
    }
    if let Some(v) = a.threshold {
        ann.insert("threshold".to_string(), number(v));
    }
    ann.insert("unit".to_string(), a.unit.clone());
    if !a.points.is_empty() {
        ann.insert("points".to_string(), a.points.join(","));
    }
    if let Some(i) = incident {
        ann.insert("incident".to_string(), i.key.clone());
    }
    let mut group = BTreeMap::new();
    group.insert("site".to_string(), a.site.clone());
    group.insert("alertname".to_string(), labels["alertname"].clone());
    AlertmanagerBody {
        version: "4".into(),
        group_key: format!(
            "{{}}:{{alertname=\"{}\", site=\"{}\"}}",
            labels["alertname"], a.site
        ),
        truncated_alerts: 0,
        status: status.into(),
        receiver: receiver.into(),
        group_labels: group,
        common_labels: labels.clone(),
        common_annotations: ann.clone(),
        external_url: public_url
            .unwrap_or_default()
            .trim_end_matches('/')
            .to_string(),
        alerts: vec![AlertmanagerAlert {
            status: status.into(),
            fingerprint: fingerprint(&labels),
            labels,
            annotations: ann,
            starts_at: t(a.raised_at),
            ends_at: if status == "resolved" {
                t(event.timestamp)
            } else {
                "0001-01-01T00:00:00Z".into()
            },
            generator_url: link_of(public_url, &a.site, &a.id, incident).unwrap_or_default(),
        }],
    }
}

/// The alert of an event as it is after the event, in `incident` when known.
pub fn current_of_event(event: &AlertEvent, incident: Option<&IncidentLink>) -> CurrentAlert {
    let a = &event.alert;
    CurrentAlert {
        id: a.id.clone(),
        site: a.site.clone(),
        point: a.point.clone(),
        group: a.group.clone(),
        points: a.points.clone(),
        rule: a.rule.as_str().to_string(),
        level: a.level,
        peak_level: a.peak_level.max(a.level),
        value: a.value,
        threshold: a.threshold,
        unit: a.unit.clone(),
        epoch: a.epoch,
        observed_at: a.observed_at,
        message: a.message.clone(),
        raised_at: a.raised_at,
        changed_at: event.timestamp,
        resolved: event.event_type == AlertEventType::Resolved,
        incident: incident.cloned(),
    }
}

/// Alertmanager API v2 body of the alert an event left ([`postable_alerts`] at the event's
/// time, firing levels held for `hold`). The re-post loop sends the same from the store's
/// state every period; this is the body of one event, for tests and tools.
pub fn alertmanager_alerts(
    event: &AlertEvent,
    public_url: Option<&str>,
    incident: Option<&IncidentLink>,
    hold: chrono::Duration,
) -> Vec<PostableAlert> {
    postable_alerts(
        &current_of_event(event, incident),
        event.timestamp,
        hold,
        public_url,
    )
}
