//! Alert webhooks per the contract: Standard Webhooks signatures, the payload (and an optional
//! Alertmanager-compatible body), the retry policy as pure functions, and one delivery attempt.
//!
//! - [`sign`]: `webhook-signature: v1,<base64 HMAC-SHA256 of "{id}.{timestamp}.{body}">` with the key
//!   = base64-decoded part of the secret after `whsec_` (Standard Webhooks specification,
//!   <https://www.standardwebhooks.com>).
//! - [`payload`]: the contract body `{"type", "timestamp", "data": {...}}` built from an
//!   [`cliffwatch_core::analysis::AlertEvent`], per-endpoint level filtering, the Alertmanager webhook body (v4) and the
//!   Alertmanager API v2 body (`POST /api/v2/alerts`); [`render`] gives the body of an endpoint's
//!   [`PayloadFormat`].
//! - [`alertmanager`]: what Alertmanager is to hold of each alert now (every level up to the
//!   current one firing, `endsAt` a few re-post periods ahead), Alertmanager's fingerprint, the
//!   links to the alert's dashboard page.
//! - [`test_event`]: the body of a test notification in each format.
//! - [`retry`]: exponential backoff with jitter, `Retry-After` as a floor, attempt limit.
//! - [`deliver`]: one signed HTTP POST and the classification of its outcome (delivered, retry after,
//!   gone on 410 → disable the endpoint, failed). The outbox worker (the service) stores the message id and
//!   reuses it on every retry.

pub(crate) mod alertmanager;
pub(crate) mod deliver;
pub(crate) mod payload;
pub(crate) mod retry;
pub(crate) mod sign;
pub(crate) mod test_event;

pub use alertmanager::{
    alert_page_url, fingerprint, incident_page_url, labels, link_of, postable_alerts, resend_body,
    CurrentAlert, IncidentLink, PostableAlert, HOLD_PERIODS,
};
pub use deliver::{client, deliver, loggable_origin, DeliveryOutcome};
pub use payload::{
    accepts, alertmanager_alerts, alertmanager_body, current_of_event, message_id, message_id_of,
    render, AlertmanagerAlert, AlertmanagerBody, PayloadFormat, WebhookData, WebhookEndpoint,
    WebhookPayload, DEFAULT_RESEND_SECS,
};
pub use retry::{backoff_delay, next_retry, parse_retry_after, RetryPolicy};
pub use sign::{sign, signing_key, verify, WebhookError};
pub use test_event::{test_body, TEST_EVENT};

#[cfg(test)]
mod tests {
    /// The daemon's own contract names (payload formats, webhook sources) parse back to their
    /// value and equal the serde name the API carries.
    #[test]
    fn daemon_names_round_trip_and_match_serde() {
        fn round_trip<T>(all: &[T])
        where
            T: Copy + std::fmt::Debug + PartialEq + std::str::FromStr + serde::Serialize,
            T: std::fmt::Display,
        {
            for &v in all {
                let name = v.to_string();
                assert_eq!(name.parse::<T>().ok(), Some(v));
                assert_eq!(serde_json::to_value(v).unwrap(), serde_json::json!(name));
            }
            assert!("no such name".parse::<T>().is_err());
        }
        round_trip(super::PayloadFormat::ALL);
        round_trip(crate::store::webhooks::WebhookSource::ALL);
    }
}
