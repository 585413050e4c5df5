//! The `test` event (`POST /api/v1/webhooks/{id}/test`): a body of the endpoint's format that
//! names no alert, to check that a receiver gets, verifies and routes what cliffwatch sends.

use std::collections::BTreeMap;

use chrono::{DateTime, Duration, SecondsFormat, Utc};

use super::alertmanager::PostableAlert;
use super::payload::{
    AlertmanagerAlert, AlertmanagerBody, PayloadFormat, WebhookData, WebhookPayload,
};
use cliffwatch_core::analysis::AlertLevel;

/// The `type` of the test event in the contract body.
pub const TEST_EVENT: &str = "test";

/// What the test event says.
const SUMMARY: &str = "Test notification from cliffwatch: no alert is open because of it.";

/// How long Alertmanager holds the test alert (it then resolves by itself), minutes.
const TEST_HOLD_MINUTES: i64 = 5;

fn t(x: DateTime<Utc>) -> String {
    x.to_rfc3339_opts(SecondsFormat::Secs, true)
}

/// The test event's body in `format`, at `now`, for endpoint `endpoint_id`:
/// - `standard`: `{"type": "test", "timestamp", "data"}` with `alert_id` and `rule` `test`,
///   level `watch`, an empty site;
/// - `alertmanager_webhook`: a firing version 4 body of one alert `cliffwatch_test`;
/// - `alertmanager_api_v2`: one postable alert `cliffwatch_test` (severity `watch`) firing for
///   5 minutes, then resolved by Alertmanager itself.
pub fn test_body(
    format: PayloadFormat,
    endpoint_id: &str,
    now: DateTime<Utc>,
) -> Result<String, serde_json::Error> {
    let mut labels = BTreeMap::new();
    labels.insert("alertname".to_string(), "cliffwatch_test".to_string());
    labels.insert(
        "severity".to_string(),
        AlertLevel::Watch.as_str().to_string(),
    );
    let annotations = BTreeMap::from([("summary".to_string(), SUMMARY.to_string())]);
    match format {
        PayloadFormat::Standard => serde_json::to_string(&WebhookPayload {
            event_type: TEST_EVENT.into(),
            timestamp: t(now),
            data: WebhookData {
                alert_id: TEST_EVENT.into(),
                site: String::new(),
                point: None,
                group: None,
                points: vec![],
                level: AlertLevel::Watch,
                rule: TEST_EVENT.into(),
                value: None,
                threshold: None,
                unit: String::new(),
                epoch: None,
                observed_at: None,
                message: SUMMARY.into(),
                acknowledged_by: None,
                comment: None,
                url: None,
                incident: None,
                incident_url: None,
                cleared_by: None,
            },
        }),
        PayloadFormat::AlertmanagerWebhook => serde_json::to_string(&AlertmanagerBody {
            version: "4".into(),
            group_key: "{}:{alertname=\"cliffwatch_test\"}".into(),
            truncated_alerts: 0,
            status: "firing".into(),
            receiver: endpoint_id.into(),
            group_labels: BTreeMap::from([(
                "alertname".to_string(),
                "cliffwatch_test".to_string(),
            )]),
            common_labels: labels.clone(),
            common_annotations: annotations.clone(),
            external_url: String::new(),
            alerts: vec![AlertmanagerAlert {
                status: "firing".into(),
                fingerprint: super::alertmanager::fingerprint(&labels),
                labels,
                annotations,
                starts_at: t(now),
                ends_at: "0001-01-01T00:00:00Z".into(),
                generator_url: String::new(),
            }],
        }),
        PayloadFormat::AlertmanagerApiV2 => serde_json::to_string(&[PostableAlert {
            labels,
            annotations,
            starts_at: t(now),
            ends_at: t(now + Duration::minutes(TEST_HOLD_MINUTES)),
            generator_url: String::new(),
        }]),
    }
}
