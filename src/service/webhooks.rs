//! Webhook endpoints added and removed through the API, each in one transaction, after the
//! endpoint is checked (also those of the configuration file, [`super::configured`]).

use crate::store::webhooks::{self, NewWebhook, Webhook, WebhookSource};
use crate::store::{Store, StoreError};

use super::ServiceError;

/// The refusal of an endpoint, with its message.
fn invalid(message: impl Into<String>) -> ServiceError {
    ServiceError::InvalidWebhook(message.into())
}

/// Longest webhook URL (characters): what browsers, proxies and receivers take everywhere.
pub const MAX_URL_CHARS: usize = 2048;
/// Longest webhook secret (characters): `whsec_` and the base64 of a key of up to 186 bytes
/// (Standard Webhooks' keys have 24 to 64).
pub const MAX_SECRET_CHARS: usize = 256;

/// Checks a webhook endpoint: an http(s) URL of at most [`MAX_URL_CHARS`] characters that parses
/// and names a host, and a `whsec_` secret of at most [`MAX_SECRET_CHARS`] whose base64 decodes to
/// the signing key (a secret that does not would fail every delivery, silently, at 3 a.m.). A
/// URL repeated in the message is cut ([`cliffwatch_core::contract::truncate_for_message`]).
pub fn validate_webhook(h: &NewWebhook) -> Result<(), ServiceError> {
    let chars = h.url.chars().count();
    if chars > MAX_URL_CHARS {
        return Err(invalid(format!(
            "url: {chars} characters; at most {MAX_URL_CHARS}"
        )));
    }
    let chars = h.secret.chars().count();
    if chars > MAX_SECRET_CHARS {
        return Err(invalid(format!(
            "secret: {chars} characters; at most {MAX_SECRET_CHARS}"
        )));
    }
    let parsed = url::Url::parse(&h.url).ok().filter(|u| {
        (u.scheme() == "http" || u.scheme() == "https")
            && u.host_str().is_some_and(|h| !h.is_empty())
    });
    // The host must be written after `//` (`http:///x` would be read as host `x`).
    let after = h
        .url
        .strip_prefix("http://")
        .or_else(|| h.url.strip_prefix("https://"));
    if parsed.is_none() || after.is_none_or(|rest| rest.starts_with('/')) {
        return Err(invalid(format!(
            "url '{}': an absolute http or https URL with a host",
            cliffwatch_core::contract::truncate_for_message(&h.url)
        )));
    }
    let decoded = h
        .secret
        .strip_prefix("whsec_")
        .map(|_| crate::webhooks::signing_key(&h.secret));
    match decoded {
        Some(Ok(key)) if key.len() >= 3 => Ok(()),
        Some(Err(e)) => Err(invalid(format!(
            "secret: whsec_ followed by standard base64, padded or not ({e})"
        ))),
        _ => Err(invalid("secret: whsec_<base64> of at least 3 bytes")),
    }
}

/// Adds `hook` after [`validate_webhook`]; the stored endpoint (its secret not shown).
pub async fn create_webhook(store: &Store, hook: &NewWebhook) -> Result<Webhook, ServiceError> {
    validate_webhook(hook)?;
    let mut tx = store.begin_write().await?;
    let id = webhooks::insert(&mut tx, hook, WebhookSource::Api).await?;
    tx.commit().await.map_err(StoreError::from)?;
    webhooks::list(store.reader())
        .await?
        .into_iter()
        .find(|w| w.id == id)
        .ok_or(ServiceError::UnknownWebhook(id))
}

/// Removes endpoint `id`, or [`ServiceError::UnknownWebhook`].
pub async fn delete_webhook(store: &Store, id: &str) -> Result<(), ServiceError> {
    let mut tx = store.begin_write().await?;
    if webhooks::delete(&mut tx, id).await?.is_none() {
        return Err(ServiceError::UnknownWebhook(id.to_string()));
    }
    tx.commit().await.map_err(StoreError::from)?;
    Ok(())
}
