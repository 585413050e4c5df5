//! Creating a site: its definition checked, naming the field at fault, and stored in one
//! transaction. The checks are also those of the sites in the configuration file
//! ([`super::configured`]).

use crate::store::sites::{self, NewSite, Site};
use crate::store::{Store, StoreError};
use cliffwatch_core::analysis::alerts::{MAX_CONFIDENCE, MIN_CONFIDENCE};
use cliffwatch_core::analysis::AlertRule;
use cliffwatch_core::photogrammetry::input::epoch::is_valid_identifier;

use super::ServiceError;

/// The refusal of a site definition, with its message.
fn invalid(message: impl Into<String>) -> ServiceError {
    ServiceError::InvalidSite(message.into())
}

/// Longest display name of a site (characters).
pub const MAX_NAME_CHARS: usize = 200;

/// Longest response text of a site (characters).
pub const MAX_RESPONSE_CHARS: usize = 2000;
/// Most contacts of a site.
pub const MAX_CONTACTS: usize = 20;
/// Longest contact entry (characters).
pub const MAX_CONTACT_CHARS: usize = 200;

/// Refused, naming `field`, when it holds the NUL character (PostgreSQL cannot store it).
fn no_nul(field: &str, text: &str) -> Result<(), ServiceError> {
    if text.contains('\0') {
        return Err(invalid(format!(
            "{field}: the NUL character (U+0000) is not allowed"
        )));
    }
    Ok(())
}

/// Refused, naming `field`, when `text` is longer than `max` characters: every free-text field is
/// bounded, so that no page grows with what one request stored.
pub fn check_text(field: &str, text: &str, max: usize) -> Result<(), ServiceError> {
    let n = text.chars().count();
    if n > max {
        return Err(invalid(format!("{field}: {n} characters; at most {max}")));
    }
    Ok(())
}

/// Checks a site definition, naming the field at fault (identifier, confidence, rule levels and metrics; the model is
/// checked by its type when the body is read).
pub fn validate_site(s: &NewSite) -> Result<(), ServiceError> {
    if !is_valid_identifier(&s.id) {
        return Err(invalid(format!(
            "id '{}': identifiers must match [A-Za-z0-9._-]{{1,64}} and not be . or ..",
            cliffwatch_core::contract::truncate_for_message(&s.id)
        )));
    }
    if let Some(n) = s.name.as_deref() {
        check_text("name", n, MAX_NAME_CHARS)?;
    }
    if let Some(t) = s.response_text.as_deref() {
        check_text("response_text", t, MAX_RESPONSE_CHARS)?;
        no_nul("response_text", t)?;
    }
    let contacts = s.contacts.as_deref().unwrap_or_default();
    if contacts.len() > MAX_CONTACTS {
        return Err(invalid(format!(
            "contacts: {} entries; at most {MAX_CONTACTS}",
            contacts.len()
        )));
    }
    for (i, c) in contacts.iter().enumerate() {
        let field = format!("contacts[{i}]");
        if c.trim().is_empty() {
            return Err(invalid(format!(
                "{field}: empty; a contact is 1 to {MAX_CONTACT_CHARS} characters"
            )));
        }
        check_text(&field, c, MAX_CONTACT_CHARS)?;
        no_nul(&field, c)?;
    }
    if s.name.as_deref().is_some_and(|n| n.contains('\0')) {
        return Err(invalid("name: the NUL character (U+0000) is not allowed"));
    }
    if let Some(c) = s.confidence {
        if !(MIN_CONFIDENCE..=MAX_CONFIDENCE).contains(&c) {
            return Err(invalid(format!(
                "confidence {c}: between 0.5 and 1 ({MIN_CONFIDENCE} to {MAX_CONFIDENCE})"
            )));
        }
    }
    if let Some(k) = s.reference_epochs {
        if !(1..=100).contains(&k) {
            return Err(invalid(format!("reference_epochs {k}: between 1 and 100")));
        }
    }
    if let Some(h) = s.schedule_hours {
        if !(h > 0.0 && h.is_finite()) {
            return Err(invalid(format!(
                "schedule_hours {h}: a finite number of hours > 0"
            )));
        }
    }
    if let Some(q) = s.process_noise {
        if !(q > 0.0 && q.is_finite()) {
            return Err(invalid(format!("process_noise {q}: a finite number > 0")));
        }
    }
    if let Some(tz) = &s.time_zone {
        if tz.parse::<chrono_tz::Tz>().is_err() {
            return Err(invalid(format!(
                "time_zone '{}': an IANA time zone name such as Asia/Tokyo or Europe/Zurich",
                cliffwatch_core::contract::truncate_for_message(tz)
            )));
        }
    }
    if let Some(frame) = &s.frame {
        frame.validate().map_err(invalid)?;
    }
    if let Some(detection) = &s.detection {
        detection.validate(None).map_err(invalid)?;
    }
    if let Some(area) = &s.area {
        area.validate().map_err(invalid)?;
    }
    for (i, rule) in s.alert_rules.iter().flatten().enumerate() {
        // The rule as the engine reads it; the message names the member at fault.
        AlertRule::from_json(rule).map_err(|e| invalid(e.at(&format!("alert_rules[{i}]"))))?;
    }
    Ok(())
}

/// Creates `site` after [`validate_site`]: the stored site, or [`ServiceError::SiteExists`].
pub async fn create_site(store: &Store, site: &NewSite) -> Result<Site, ServiceError> {
    validate_site(site)?;
    let mut tx = store.begin_write_site(&site.id).await?;
    if !sites::insert(&mut tx, site).await? {
        return Err(ServiceError::SiteExists(site.id.clone()));
    }
    tx.commit().await.map_err(StoreError::from)?;
    sites::get(store.reader(), &site.id)
        .await?
        .ok_or_else(|| ServiceError::UnknownSite(site.id.clone()))
}

/// Refuses a change of `site` once it is retired ([`ServiceError::RetiredSite`]).
pub fn ensure_in_service(site: &Site) -> Result<(), ServiceError> {
    match &site.retired_at {
        Some(at) => Err(ServiceError::RetiredSite {
            site: site.id.clone(),
            at: at.clone(),
            reason: site.retired_reason.clone().unwrap_or_default(),
        }),
        None => Ok(()),
    }
}
