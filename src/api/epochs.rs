//! `POST /api/v1/sites/{site}/epochs` (upload, JSON or CSV), `GET .../epochs`, `GET .../epochs/{epoch}`.

use std::pin::Pin;

use axum::body::{Body, Bytes, HttpBody};
use axum::extract::State;
use axum::http::{header, HeaderMap, StatusCode};
use axum::response::IntoResponse;
use serde::Deserialize;

use super::list::{Listing, Page, PageParams};
use super::schemas::EpochSummary;
use super::sites::find;
use crate::http::error::{ApiError, ApiPath, ApiQuery};
use crate::http::AppState;
use crate::service::ingest::EpochLimits;
use crate::service::stored_epoch::{stored_epoch, StoredEpoch};
use crate::service::upload::{upload as take_upload, Upload, UploadForm};
use crate::store::{epochs, Store};

/// Bodies up to this many times the limit are read to the end before answering 413, so the client
/// sees the answer instead of a reset connection; larger ones are cut off.
const DRAIN_FACTOR: usize = 16;

/// Reads a body of at most `limit` bytes; over it, drains (up to [`DRAIN_FACTOR`] × limit) and
/// answers 413.
pub async fn read_limited(
    headers: &HeaderMap,
    body: Body,
    limit: usize,
) -> Result<Bytes, ApiError> {
    let declared = headers
        .get(header::CONTENT_LENGTH)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.parse::<usize>().ok());
    let drain_cap = limit.saturating_mul(DRAIN_FACTOR).max(256 << 20);
    if declared.is_some_and(|n| n > drain_cap) {
        return Err(ApiError::too_large(limit));
    }
    let mut body = body;
    let mut buf = Vec::with_capacity(declared.unwrap_or(0).min(limit));
    let mut total = 0usize;
    loop {
        let frame = std::future::poll_fn(|cx| Pin::new(&mut body).poll_frame(cx)).await;
        match frame {
            None => break,
            Some(Err(e)) => return Err(ApiError::bad_request(format!("reading the body: {e}"))),
            Some(Ok(frame)) => {
                if let Ok(data) = frame.into_data() {
                    total += data.len();
                    if total > drain_cap {
                        return Err(ApiError::too_large(limit));
                    }
                    if total <= limit {
                        buf.extend_from_slice(&data);
                    }
                }
            }
        }
    }
    if total > limit {
        return Err(ApiError::too_large(limit));
    }
    Ok(Bytes::from(buf))
}

/// Query of an upload: `observed_at` for the CSV form.
#[derive(Debug, Default, Deserialize)]
pub struct UploadParams {
    /// Observation time of a CSV upload (RFC 3339).
    pub observed_at: Option<String>,
    /// Camera of a CSV upload's images: needed when the site has several.
    pub camera: Option<String>,
}

/// `POST /api/v1/sites/{site}/epochs`: validates, adjusts and stores an epoch; 201 with its
/// summary, 200 when the same body was stored before, 409 for another body at the same time.
#[utoipa::path(post, path = "/api/v1/sites/{site}/epochs", operation_id = "upload_epoch", params(("site" = String, Path), ("observed_at" = Option<String>, Query, description = "CSV uploads only"), ("camera" = Option<String>, Query, pattern = "^[A-Za-z0-9._-]{1,64}$", description = "CSV uploads only: the camera of the images, needed when the site has several")),
    request_body(description = "the upload form (application/json) or CSV `image,point,x_mm,y_mm` (text/csv)", content((cliffwatch_core::photogrammetry::EpochInput = "application/json"), (String = "text/csv"))),
    responses((status = 201, description = "stored; the epoch summary", body = crate::api::schemas::EpochSummary), (status = 200, description = "the same body was stored before", body = crate::api::schemas::EpochSummary),
        (status = 400, description = "not JSON/CSV", body = crate::api::schemas::ErrorBody), (status = 404, description = "unknown site", body = crate::api::schemas::ErrorBody), (status = 409, description = "another body for this observed_at, a CSV upload to a site without cameras yet (upload a JSON epoch first), or a retired site (code `site_retired`)", body = crate::api::schemas::ErrorBody),
        (status = 413, description = "body too large, or an epoch with more points or observations than the node takes (`epoch_too_large`, naming `max_epoch_points` or `max_epoch_observations`); nothing computed or stored", body = crate::api::schemas::ErrorBody), (status = 422, description = "invalid or cannot be adjusted; a CSV upload to a site of several cameras without `camera`, or naming none of them", body = crate::api::schemas::ErrorBody),
        (status = 503, description = "every upload slot of the node stayed busy for `upload_queue_secs` (`overloaded`), the adjustment ran past `compute_budget_secs` (`compute_budget_exceeded`) or the node is stopping (`shutting_down`); nothing stored, retry after the `Retry-After` header's seconds", body = crate::api::schemas::ErrorBody, headers(("Retry-After" = u64, description = "seconds to wait before retrying")))))]
pub async fn upload(
    State(state): State<AppState>,
    ApiPath(site): ApiPath<String>,
    ApiQuery(params): ApiQuery<UploadParams>,
    headers: HeaderMap,
    body: Body,
) -> Result<impl IntoResponse, ApiError> {
    let result = upload_inner(&state, &site, params, &headers, body).await;
    let status = match &result {
        Ok((s, _)) => s.as_u16(),
        Err(e) => e.status.as_u16(),
    };
    metrics::counter!("cliffwatch_uploads_total", "status" => status.to_string()).increment(1);
    let (status, summary) = result?;
    let location = format!("/api/v1/sites/{site}/epochs/{}", summary.epoch.id);
    Ok((status, [(header::LOCATION, location)], axum::Json(summary)))
}

/// What an upload's body is, by its `Content-Type`: the CSV form (`text/csv`, with the query's
/// fields), JSON (`application/json` or a `+json` type), or another media type, which the upload
/// refuses (415).
fn upload_form(headers: &HeaderMap, params: UploadParams) -> UploadForm {
    let media = headers
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .map(|v| {
            v.split(';')
                .next()
                .unwrap_or_default()
                .trim()
                .to_ascii_lowercase()
        });
    match media.as_deref() {
        Some("text/csv") => UploadForm::Csv {
            observed_at: params.observed_at,
            camera: params.camera,
        },
        Some(m) if m == "application/json" || m.ends_with("+json") => UploadForm::Json,
        _ => UploadForm::Other(media),
    }
}

async fn upload_inner(
    state: &AppState,
    site: &str,
    params: UploadParams,
    headers: &HeaderMap,
    body: Body,
) -> Result<(StatusCode, EpochSummary), ApiError> {
    // The use case takes an upload slot once the body has arrived: a client sending slowly (a
    // field laptop on a cellular link) must not hold a slot while the CPU is idle.
    let bytes = read_limited(headers, body, state.config.body_limit_bytes).await?;
    let upload = Upload {
        form: upload_form(headers, params),
        body: bytes,
    };
    let limits = EpochLimits::from_config(&state.config);
    let (store, gate, public_url) = (&state.store, &state.uploads, state.public_url());
    let done = take_upload(store, gate, site, upload, limits, public_url).await?;
    let status = if done.created {
        StatusCode::CREATED
    } else {
        StatusCode::OK
    };
    Ok((status, summary_of(site, done.epoch)))
}

/// The summary of a stored epoch: list fields, the adjustment report (with the residuals when
/// read with them), its displacements and the alerts it raised.
fn summary_of(site: &str, stored: StoredEpoch) -> EpochSummary {
    EpochSummary {
        epoch: stored.item.into(),
        site: site.to_string(),
        global_test: stored.report.global_test(),
        report: stored.report,
        residuals: stored.residuals,
        displacements: stored.displacements,
        alerts: stored.alerts,
    }
}

/// The summary of stored epoch `id` of `site` ([`summary_of`]), with its residuals when
/// `residuals`; `None` when the site has no such epoch.
pub async fn summary(
    store: &Store,
    site: &str,
    id: i64,
    residuals: bool,
) -> Result<Option<EpochSummary>, ApiError> {
    let stored = stored_epoch(store, site, id, residuals).await?;
    Ok(stored.map(|e| summary_of(site, e)))
}

/// `GET /api/v1/sites/{site}/epochs`: newest first.
#[utoipa::path(get, path = "/api/v1/sites/{site}/epochs", operation_id = "list_epochs", params(("site" = String, Path), ("limit" = Option<i64>, Query, minimum = 1, description = "page size (default 100; above 1000 read as 1000)"), ("cursor" = Option<String>, Query)),
    responses((status = 200, description = "epochs, newest first", body = crate::api::list::Page<crate::store::epochs::EpochListItem>), (status = 404, description = "unknown site", body = crate::api::schemas::ErrorBody)))]
pub async fn list(
    State(state): State<AppState>,
    ApiPath(site): ApiPath<String>,
    ApiQuery(page): ApiQuery<PageParams>,
) -> Result<impl IntoResponse, ApiError> {
    find(&state, &site).await?;
    let cursor = page.cursor(Listing::Epochs)?;
    let limit = page.limit()?;
    let rows = epochs::list(state.store.reader(), &site, cursor.as_deref(), limit + 1).await?;
    let page = Page::from_fetched(rows, limit, Listing::Epochs, |(raw, _)| raw.clone());
    Ok(axum::Json(Page {
        items: page.items.into_iter().map(|(_, e)| e).collect(),
        next_cursor: page.next_cursor,
    }))
}

/// `GET /api/v1/sites/{site}/epochs/{epoch}`: the full report with residuals per observation.
#[utoipa::path(get, path = "/api/v1/sites/{site}/epochs/{epoch}", operation_id = "get_epoch", params(("site" = String, Path), ("epoch" = i64, Path)),
    responses((status = 200, description = "the epoch summary with the full report", body = crate::api::schemas::EpochSummary), (status = 404, description = "unknown site or epoch", body = crate::api::schemas::ErrorBody)))]
pub async fn get_one(
    State(state): State<AppState>,
    ApiPath((site, epoch)): ApiPath<(String, String)>,
) -> Result<impl IntoResponse, ApiError> {
    find(&state, &site).await?;
    let id: i64 = epoch.parse().map_err(|_| {
        ApiError::not_found(format!(
            "site '{site}' has no epoch '{}'",
            cliffwatch_core::contract::truncate_for_message(&epoch)
        ))
    })?;
    summary(&state.store, &site, id, true)
        .await?
        .map(axum::Json)
        .ok_or_else(|| ApiError::not_found(format!("site '{site}' has no epoch {id}")))
}
