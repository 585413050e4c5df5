//! One delivery attempt: a signed POST and the classification of its outcome.

use std::time::Duration;

use chrono::{DateTime, Utc};

use super::retry::parse_retry_after;
use super::sign::sign;

/// What one attempt came to.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum DeliveryOutcome {
    /// 2xx: done.
    Delivered {
        /// HTTP status.
        status: u16,
    },
    /// Not delivered (network error, timeout, any status but 2xx and 410): retry, after the
    /// server's `Retry-After` when given. A 400 or 404 is often a proxy or a deploy in between,
    /// and an alarm is not to be dropped on one answer.
    Retry {
        /// HTTP status (None for a network error or timeout).
        status: Option<u16>,
        /// The server's `Retry-After`, when given.
        retry_after: Option<Duration>,
        /// What happened.
        reason: String,
    },
    /// 410 Gone: disable the endpoint, drop its pending messages.
    Gone,
    /// Permanent failure (bad secret, unusable URL): do not retry this message.
    Failed {
        /// HTTP status, if any.
        status: Option<u16>,
        /// What happened.
        reason: String,
    },
}

/// The HTTP client for deliveries: `timeout` per POST, and redirects not followed. A followed
/// 301/302 turns the POST into a GET without the body, whose 2xx would count as delivered; a
/// redirect also lets the receiver send the daemon to an address nobody configured.
pub fn client(timeout: Duration) -> reqwest::Result<reqwest::Client> {
    reqwest::Client::builder()
        .timeout(timeout)
        .redirect(reqwest::redirect::Policy::none())
        .build()
}

/// What of a webhook URL may be logged: its scheme, host and port. The rest (user and
/// password, path, query) often carries a capability token, such as a chat service's
/// incoming-webhook path.
pub fn loggable_origin(url: &str) -> String {
    match url::Url::parse(url) {
        Ok(u) => u.origin().ascii_serialization(),
        Err(_) => "(unparsable URL)".into(),
    }
}

/// Classifies an HTTP status (and the `Retry-After` and `Location` header values) into an
/// outcome. A 3xx is retried with a reason naming where it pointed: the webhook's URL is to be
/// configured as the final one.
pub fn classify(
    status: u16,
    retry_after: Option<&str>,
    location: Option<&str>,
    now: DateTime<Utc>,
) -> DeliveryOutcome {
    match status {
        200..=299 => DeliveryOutcome::Delivered { status },
        410 => DeliveryOutcome::Gone,
        _ => DeliveryOutcome::Retry {
            status: Some(status),
            retry_after: retry_after.and_then(|v| parse_retry_after(v, now)),
            reason: match status {
                300..=399 => format!(
                    "HTTP {status}: redirect to {} not followed; configure the webhook with the final URL",
                    location.unwrap_or("(no Location)")
                ),
                _ => format!("HTTP {status}"),
            },
        },
    }
}

/// POSTs `body` to `url` signed with `secret` as message `msg_id` (reuse it on every retry of one event),
/// timestamped `now` (fresh per attempt, as Standard Webhooks expects), and classifies the outcome.
/// The client's timeout applies (build it with [`client`]).
pub async fn deliver(
    client: &reqwest::Client,
    url: &str,
    secret: &str,
    msg_id: &str,
    body: &[u8],
    now: DateTime<Utc>,
) -> DeliveryOutcome {
    let ts = now.timestamp();
    let signature = match sign(secret, msg_id, ts, body) {
        Ok(s) => s,
        Err(e) => {
            return DeliveryOutcome::Failed {
                status: None,
                reason: e.to_string(),
            }
        }
    };
    let resp = client
        .post(url)
        .header("content-type", "application/json")
        .header("webhook-id", msg_id)
        .header("webhook-timestamp", ts.to_string())
        .header("webhook-signature", signature)
        .body(body.to_vec())
        .send()
        .await;
    match resp {
        Ok(r) => {
            let status = r.status().as_u16();
            let header = |name: &str| {
                r.headers()
                    .get(name)
                    .and_then(|v| v.to_str().ok())
                    .map(str::to_string)
            };
            classify(
                status,
                header("retry-after").as_deref(),
                header("location").as_deref(),
                now,
            )
        }
        // the error's text without the URL: the reason is stored and shown by the API
        Err(e) if e.is_builder() => DeliveryOutcome::Failed {
            status: None,
            reason: e.without_url().to_string(),
        },
        Err(e) => DeliveryOutcome::Retry {
            status: None,
            retry_after: None,
            reason: e.without_url().to_string(),
        },
    }
}
