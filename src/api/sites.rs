//! `POST/GET /api/v1/sites`, `GET /api/v1/sites/{site}`, `PUT /api/v1/sites/{site}/reference`.

use axum::extract::State;
use axum::http::StatusCode;
use axum::response::IntoResponse;
use serde::Deserialize;
use utoipa::ToSchema;

use super::list::{Listing, Page, PageParams};
use crate::analysis::alerts::{MAX_CONFIDENCE, MIN_CONFIDENCE};
use crate::analysis::AlertRule;
use crate::http::error::{ApiError, ApiJson, ApiPath, ApiQuery};
use crate::http::AppState;
use crate::photogrammetry::input::epoch::is_valid_identifier;
use crate::service::ServiceError;
use crate::store::sites::{self, NewSite, Site};
use crate::store::StoreError;

/// Longest display name of a site (characters).
pub const MAX_NAME_CHARS: usize = 200;

/// Longest response text of a site (characters).
pub const MAX_RESPONSE_CHARS: usize = 2000;
/// Most contacts of a site.
pub const MAX_CONTACTS: usize = 20;
/// Longest contact entry (characters).
pub const MAX_CONTACT_CHARS: usize = 200;

/// 422 naming `field` when it holds the NUL character (PostgreSQL cannot store it).
fn no_nul(field: &str, text: &str) -> Result<(), ApiError> {
    if text.contains('\0') {
        return Err(ApiError::unprocessable(
            "invalid_site",
            format!("{field}: the NUL character (U+0000) is not allowed"),
        ));
    }
    Ok(())
}

/// 422 naming `field` when `text` is longer than `max` characters: every free-text field is
/// bounded, so that no page grows with what one request stored.
pub fn check_text(field: &str, text: &str, max: usize) -> Result<(), ApiError> {
    let n = text.chars().count();
    if n > max {
        return Err(ApiError::unprocessable(
            "invalid_site",
            format!("{field}: {n} characters; at most {max}"),
        ));
    }
    Ok(())
}

/// Checks a site definition (identifier, confidence, rule levels and metrics; the model is
/// checked by its type when the body is read).
pub fn check_site(s: &NewSite) -> Result<(), ApiError> {
    if !is_valid_identifier(&s.id) {
        return Err(ApiError::unprocessable(
            "invalid_site",
            format!(
                "id '{}': identifiers must match [A-Za-z0-9._-]{{1,64}} and not be . or ..",
                s.id
            ),
        ));
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
        return Err(ApiError::unprocessable(
            "invalid_site",
            format!(
                "contacts: {} entries; at most {MAX_CONTACTS}",
                contacts.len()
            ),
        ));
    }
    for (i, c) in contacts.iter().enumerate() {
        let field = format!("contacts[{i}]");
        if c.trim().is_empty() {
            return Err(ApiError::unprocessable(
                "invalid_site",
                format!("{field}: empty; a contact is 1 to {MAX_CONTACT_CHARS} characters"),
            ));
        }
        check_text(&field, c, MAX_CONTACT_CHARS)?;
        no_nul(&field, c)?;
    }
    if s.name.as_deref().is_some_and(|n| n.contains('\0')) {
        return Err(ApiError::unprocessable(
            "invalid_site",
            "name: the NUL character (U+0000) is not allowed",
        ));
    }
    if let Some(c) = s.confidence {
        if !(MIN_CONFIDENCE..=MAX_CONFIDENCE).contains(&c) {
            return Err(ApiError::unprocessable(
                "invalid_site",
                format!("confidence {c}: between 0.5 and 1 ({MIN_CONFIDENCE} to {MAX_CONFIDENCE})"),
            ));
        }
    }
    if let Some(k) = s.reference_epochs {
        if !(1..=100).contains(&k) {
            return Err(ApiError::unprocessable(
                "invalid_site",
                format!("reference_epochs {k}: between 1 and 100"),
            ));
        }
    }
    if let Some(h) = s.schedule_hours {
        if !(h > 0.0 && h.is_finite()) {
            return Err(ApiError::unprocessable(
                "invalid_site",
                format!("schedule_hours {h}: a finite number of hours > 0"),
            ));
        }
    }
    if let Some(q) = s.process_noise {
        if !(q > 0.0 && q.is_finite()) {
            return Err(ApiError::unprocessable(
                "invalid_site",
                format!("process_noise {q}: a finite number > 0"),
            ));
        }
    }
    if let Some(tz) = &s.time_zone {
        if tz.parse::<chrono_tz::Tz>().is_err() {
            return Err(ApiError::unprocessable(
                "invalid_site",
                format!(
                    "time_zone '{tz}': an IANA time zone name such as Asia/Tokyo or Europe/Zurich"
                ),
            ));
        }
    }
    if let Some(area) = &s.area {
        area.validate()
            .map_err(|e| ApiError::unprocessable("invalid_site", e))?;
    }
    for (i, rule) in s.alert_rules.iter().flatten().enumerate() {
        let level = rule.get("level").and_then(|v| v.as_str()).unwrap_or("");
        let metric = rule.get("metric").and_then(|v| v.as_str()).unwrap_or("");
        let has_bound = rule.get("above").is_some_and(|v| v.is_number())
            || rule.get("below").is_some_and(|v| v.is_number());
        if !["watch", "warning", "alarm"].contains(&level)
            || ![
                "displacement_mm",
                "displacement_along_mm",
                "velocity_mm_per_day",
                "time_to_failure_hours",
            ]
            .contains(&metric)
            || !has_bound
        {
            return Err(ApiError::unprocessable(
                "invalid_site",
                format!("alert_rules[{i}]: needs level (watch|warning|alarm), metric and a numeric above or below"),
            ));
        }
        if let Some(unknown) = rule.as_object().and_then(|o| {
            o.keys()
                .find(|k| !crate::analysis::alerts::RULE_MEMBERS.contains(&k.as_str()))
        }) {
            return Err(ApiError::unprocessable(
                "invalid_site",
                format!(
                    "alert_rules[{i}].{unknown}: unknown member; a rule has {}",
                    crate::analysis::alerts::RULE_MEMBERS.join(", ")
                ),
            ));
        }
        // The rule as the engine reads it: source, for_epochs, hysteresis on the right side.
        let parsed = serde_json::from_value::<AlertRule>(rule.clone())
            .map_err(|e| e.to_string())
            .and_then(|r| {
                r.validate().map_err(|e| match e {
                    crate::analysis::AnalysisError::InvalidConfig(m) => m,
                    other => other.to_string(),
                })
            });
        if let Err(e) = parsed {
            return Err(ApiError::unprocessable(
                "invalid_site",
                format!("alert_rules[{i}]: {e}"),
            ));
        }
    }
    Ok(())
}

/// `POST /api/v1/sites`: creates a site (201), or 409 when the id exists.
#[utoipa::path(post, path = "/api/v1/sites", operation_id = "create_site", request_body = NewSite,
    responses((status = 201, body = Site), (status = 409, description = "exists", body = crate::api::schemas::ErrorBody), (status = 422, description = "invalid", body = crate::api::schemas::ErrorBody)))]
pub async fn create(
    State(state): State<AppState>,
    ApiJson(site): ApiJson<NewSite>,
) -> Result<impl IntoResponse, ApiError> {
    check_site(&site)?;
    let mut tx = state.store.begin_write_site(&site.id).await?;
    if !sites::insert(&mut tx, &site).await? {
        return Err(ApiError::new(
            StatusCode::CONFLICT,
            "conflict",
            format!("site '{}' exists", site.id),
        ));
    }
    tx.commit().await.map_err(StoreError::from)?;
    let stored = sites::get(state.store.reader(), &site.id)
        .await?
        .ok_or_else(|| ApiError::internal("site vanished"))?;
    Ok((StatusCode::CREATED, axum::Json(stored)))
}

/// `GET /api/v1/sites`: every site, newest first.
#[utoipa::path(get, path = "/api/v1/sites", operation_id = "list_sites", params(("limit" = Option<i64>, Query, minimum = 1, description = "page size (default 100; above 1000 read as 1000)"), ("cursor" = Option<String>, Query)),
    responses((status = 200, description = "sites", body = crate::api::list::Page<crate::store::sites::Site>)))]
pub async fn list(
    State(state): State<AppState>,
    ApiQuery(page): ApiQuery<PageParams>,
) -> Result<impl IntoResponse, ApiError> {
    let cursor = page.cursor(Listing::Sites)?;
    let limit = page.limit()?;
    let after = cursor.as_deref().and_then(|c| c.split_once('|'));
    let items = sites::list(state.store.reader(), after, limit + 1).await?;
    let mut raw = Vec::with_capacity(items.len());
    for s in &items {
        raw.push(
            sites::created_at_raw(state.store.reader(), &s.id)
                .await?
                .unwrap_or_default(),
        );
    }
    let pairs: Vec<(String, Site)> = raw.into_iter().zip(items).collect();
    let page = Page::from_fetched(pairs, limit, Listing::Sites, |(t, s)| {
        format!("{t}|{}", s.id)
    });
    Ok(axum::Json(Page {
        items: page.items.into_iter().map(|(_, s)| s).collect(),
        next_cursor: page.next_cursor,
    }))
}

/// `GET /api/v1/sites/{site}`.
#[utoipa::path(get, path = "/api/v1/sites/{site}", operation_id = "get_site", params(("site" = String, Path)),
    responses((status = 200, body = Site), (status = 404, description = "unknown site", body = crate::api::schemas::ErrorBody)))]
pub async fn get_one(
    State(state): State<AppState>,
    ApiPath(site): ApiPath<String>,
) -> Result<impl IntoResponse, ApiError> {
    Ok(axum::Json(find(&state, &site).await?))
}

/// Reads a site or answers 404.
pub async fn find(state: &AppState, site: &str) -> Result<Site, ApiError> {
    // No site has an id outside the identifier rule: not asked of the database (PostgreSQL
    // would refuse a NUL in it as a value it cannot hold, where the answer is "no such site").
    if !is_valid_identifier(site) {
        return Err(ApiError::not_found(format!("unknown site '{site}'")));
    }
    sites::get(state.store.reader(), site)
        .await?
        .ok_or_else(|| ApiError::not_found(format!("unknown site '{site}'")))
}

/// Body of `PUT .../reference`: `{"epoch": ID}`, or `{"epoch": null}` / `{}` back to the
/// earliest epoch. No other member is taken: a misspelt one (`epoch_id`) would otherwise read as
/// a reset of the reference and recompute the site.
#[derive(Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct ReferenceBody {
    /// The reference epoch's integer id; null or absent: back to the earliest.
    #[serde(
        default,
        deserialize_with = "crate::contract::json_integer::optional_i64"
    )]
    pub epoch: Option<i64>,
}

/// `PUT /api/v1/sites/{site}/reference`: sets the reference epoch and recomputes displacements.
#[utoipa::path(put, path = "/api/v1/sites/{site}/reference", operation_id = "set_site_reference", request_body = ReferenceBody, params(("site" = String, Path)),
    responses((status = 200, body = Site), (status = 404, description = "unknown site", body = crate::api::schemas::ErrorBody),
        (status = 422, description = "an epoch the site does not have, or a member other than `epoch`", body = crate::api::schemas::ErrorBody)))]
pub async fn set_reference(
    State(state): State<AppState>,
    ApiPath(site): ApiPath<String>,
    ApiJson(body): ApiJson<ReferenceBody>,
) -> Result<impl IntoResponse, ApiError> {
    crate::service::site_settings::set_reference(&state.store, &site, body.epoch)
        .await
        .map_err(|e| match e {
            // Named in the body, like an unknown camera of an upload: 422, not 404.
            ServiceError::UnknownEpoch { .. } => {
                ApiError::unprocessable("unknown_epoch", e.to_string())
            }
            e => ApiError::from(e),
        })?;
    Ok(axum::Json(find(&state, &site).await?))
}
