//! Standard Webhooks signatures (HMAC-SHA256, symmetric `whsec_` secrets).

use base64::engine::general_purpose::{GeneralPurpose, GeneralPurposeConfig, STANDARD};
use base64::engine::DecodePaddingMode;
use base64::{alphabet, Engine};
use hmac::{Hmac, Mac};
use sha2::Sha256;
use thiserror::Error;

/// Errors of the webhook helpers.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum WebhookError {
    /// The part after `whsec_` is not valid base64, or the key is empty.
    #[error("invalid webhook secret: {0}")]
    InvalidSecret(String),
    /// The payload could not be serialized.
    #[error("cannot serialize payload: {0}")]
    Serialize(String),
    /// The HTTP client could not be built.
    #[error("http client: {0}")]
    Client(String),
}

/// The standard base64 alphabet, padded or not (the Standard Webhooks libraries accept both),
/// canonical trailing bits only.
const SECRET_BASE64: GeneralPurpose = GeneralPurpose::new(
    &alphabet::STANDARD,
    GeneralPurposeConfig::new().with_decode_padding_mode(DecodePaddingMode::Indifferent),
);

/// Signing key of a secret: the base64-decoded part after `whsec_` (standard alphabet, padded or
/// not); a secret without the prefix is used as raw bytes (as the contract's test receiver does).
pub fn signing_key(secret: &str) -> Result<Vec<u8>, WebhookError> {
    let key = match secret.strip_prefix("whsec_") {
        Some(b64) => SECRET_BASE64
            .decode(b64)
            .map_err(|e| WebhookError::InvalidSecret(e.to_string()))?,
        None => secret.as_bytes().to_vec(),
    };
    if key.is_empty() {
        return Err(WebhookError::InvalidSecret("empty key".into()));
    }
    Ok(key)
}

fn mac(key: &[u8], msg_id: &str, timestamp: i64, body: &[u8]) -> Hmac<Sha256> {
    // HMAC accepts keys of any length; new_from_slice cannot fail for HMAC.
    let mut m = <Hmac<Sha256> as Mac>::new_from_slice(key)
        .unwrap_or_else(|_| unreachable!("HMAC takes any key length"));
    m.update(msg_id.as_bytes());
    m.update(b".");
    m.update(timestamp.to_string().as_bytes());
    m.update(b".");
    m.update(body);
    m
}

/// The `webhook-signature` header value `v1,<base64>` for message `msg_id` sent at `timestamp` (Unix
/// seconds) with `body`.
pub fn sign(
    secret: &str,
    msg_id: &str,
    timestamp: i64,
    body: &[u8],
) -> Result<String, WebhookError> {
    let key = signing_key(secret)?;
    let tag = mac(&key, msg_id, timestamp, body).finalize().into_bytes();
    Ok(format!("v1,{}", STANDARD.encode(tag)))
}

/// Verifies a `webhook-signature` header (space-separated `v1,<base64>` entries; any may match) in
/// constant time. Does not check the timestamp's age (the receiver's tolerance).
pub fn verify(secret: &str, msg_id: &str, timestamp: i64, body: &[u8], header: &str) -> bool {
    let Ok(key) = signing_key(secret) else {
        return false;
    };
    header.split_whitespace().any(|s| {
        let Some(b64) = s.strip_prefix("v1,") else {
            return false;
        };
        let Ok(tag) = STANDARD.decode(b64) else {
            return false;
        };
        mac(&key, msg_id, timestamp, body)
            .verify_slice(&tag)
            .is_ok()
    })
}
