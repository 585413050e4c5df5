//! Alert webhooks per the contract: Standard Webhooks signatures, the payload (and an optional
//! Alertmanager-compatible body), the retry policy as pure functions, and one delivery attempt.
//!
//! - [`sign`]: `webhook-signature: v1,<base64 HMAC-SHA256 of "{id}.{timestamp}.{body}">` with the key
//!   = base64-decoded part of the secret after `whsec_` (Standard Webhooks specification,
//!   <https://www.standardwebhooks.com>).
//! - [`payload`]: the contract body `{"type", "timestamp", "data": {...}}` built from an
//!   [`crate::analysis::AlertEvent`], per-endpoint level filtering, the Alertmanager webhook body (v4) and the
//!   Alertmanager API v2 body (`POST /api/v2/alerts`); [`render`] gives the body of an endpoint's
//!   [`PayloadFormat`].
//! - [`retry`]: exponential backoff with jitter, `Retry-After` as a floor, attempt limit.
//! - [`deliver`]: one signed HTTP POST and the classification of its outcome (delivered, retry after,
//!   gone on 410 → disable the endpoint, failed). The outbox worker (the service) stores the message id and
//!   reuses it on every retry.

pub(crate) mod deliver;
pub(crate) mod payload;
pub(crate) mod retry;
pub(crate) mod sign;

pub use deliver::{client, deliver, loggable_origin, DeliveryOutcome};
pub use payload::{
    accepts, alertmanager_alerts, alertmanager_body, message_id, render, AlertmanagerAlert,
    AlertmanagerBody, PayloadFormat, PostableAlert, WebhookData, WebhookEndpoint, WebhookPayload,
    ALERTMANAGER_FIRING_DAYS,
};
pub use retry::{backoff_delay, next_retry, parse_retry_after, RetryPolicy};
pub use sign::{sign, signing_key, verify, WebhookError};
