//! `GET /api/v1/sites/{site}/points`, `PUT .../points/{point}`, `GET .../points/{point}/displacements`.

use std::collections::HashMap;

use std::pin::Pin;
use std::task::{Context, Poll};

use axum::body::{Body, Bytes};
use axum::extract::State;
use axum::http::header;
use axum::response::{IntoResponse, Response};
use serde::{Deserialize, Serialize};
use serde_json::json;

use super::list::{encode, Listing, Page, PageParams};
use super::sites::find;
use crate::http::error::{ApiError, ApiJson, ApiPath, ApiQuery};
use crate::http::time_bound::time_bound;
use crate::http::AppState;
use crate::store::displacements::{self, Displacement};
use crate::store::points::{self, PointSettings};
use crate::store::series::{self, SeriesFormat, SeriesQuery};
use crate::store::{alerts, display_timestamp};
use cliffwatch_core::analysis::{AlertLevel, PointRole};
use cliffwatch_core::photogrammetry::input::epoch::is_valid_identifier;

/// One line of the point list.
#[derive(Debug, Serialize, utoipa::ToSchema)]
pub struct PointItem {
    /// Point name.
    pub point: String,
    /// Its role.
    pub role: PointRole,
    /// Group name.
    pub group: Option<String>,
    /// Direction of interest, site frame.
    pub direction: Option<[f64; 3]>,
    /// Latest coordinates: epoch, observed_at, X/Y/Z in m and σ in mm.
    #[schema(value_type = Option<Object>)]
    pub latest: Option<serde_json::Value>,
    /// Latest displacement.
    pub displacement: Option<Displacement>,
    /// Highest level of its open or acknowledged alerts.
    pub alert_level: Option<AlertLevel>,
}

/// `GET /api/v1/sites/{site}/points`: every point (by name) with its latest state.
#[utoipa::path(get, path = "/api/v1/sites/{site}/points", operation_id = "list_points", params(("site" = String, Path), ("limit" = Option<i64>, Query, minimum = 1, description = "page size (default 100; above 1000 read as 1000)"), ("cursor" = Option<String>, Query)),
    responses((status = 200, description = "points by name", body = crate::api::list::Page<PointItem>), (status = 404, description = "unknown site", body = crate::api::schemas::ErrorBody)))]
pub async fn list(
    State(state): State<AppState>,
    ApiPath(site): ApiPath<String>,
    ApiQuery(page): ApiQuery<PageParams>,
) -> Result<impl IntoResponse, ApiError> {
    find(&state, &site).await?;
    let db = state.store.reader();
    let cursor = page.cursor(Listing::Points)?;
    let limit = page.limit()?;
    let pts = points::list(db, &site, cursor.as_deref(), limit + 1).await?;
    let page = Page::from_fetched(pts, limit, Listing::Points, |p| p.name.clone());
    let mut latest: HashMap<String, _> =
        points::latest_coordinates(&mut *state.store.read().await?, &site)
            .await?
            .into_iter()
            .map(|c| (c.point.clone(), c))
            .collect();
    let mut disp: HashMap<String, Displacement> =
        displacements::latest(&mut *state.store.read().await?, &site)
            .await?
            .into_iter()
            .map(|d| (d.point.clone(), d))
            .collect();
    let mut levels = alerts::active_levels(db, &site).await?;
    let items: Vec<PointItem> = page
        .items
        .into_iter()
        .map(|p| {
            let latest = latest.remove(&p.name).map(|c| {
                let s = |i: usize| c.covariance_m2[i][i].max(0.0).sqrt() * 1000.0;
                json!({"epoch": c.epoch, "observed_at": display_timestamp(&c.observed_at),
                       "X": c.xyz[0], "Y": c.xyz[1], "Z": c.xyz[2],
                       "sigma_X_mm": s(0), "sigma_Y_mm": s(1), "sigma_Z_mm": s(2)})
            });
            let mut displacement = disp.remove(&p.name);
            if let Some(d) = displacement.as_mut() {
                d.d_along_mm = along(d, p.direction);
            }
            PointItem {
                alert_level: levels.remove(&p.name),
                point: p.name,
                role: p.role,
                group: p.group,
                direction: p.direction,
                latest,
                displacement,
            }
        })
        .collect();
    Ok(axum::Json(Page {
        items,
        next_cursor: page.next_cursor,
    }))
}

fn along(d: &Displacement, direction: Option<[f64; 3]>) -> Option<f64> {
    series::along([d.dx_mm, d.dy_mm, d.dz_mm], direction)
}

/// `PUT /api/v1/sites/{site}/points/{point}`: sets role, group, direction of interest (creates the
/// point when new, so roles can be set before the first epoch; once the site has epochs, a point
/// none of them observed only with `"planned": true`, else 422 naming it). A change on a site with
/// epochs recomputes its series and alerts in the same transaction, as a reference change does.
#[utoipa::path(put, path = "/api/v1/sites/{site}/points/{point}", operation_id = "update_point", request_body = PointSettings, params(("site" = String, Path), ("point" = String, Path)),
    responses((status = 409, description = "the site is retired (code `site_retired`): it takes no more changes", body = crate::api::schemas::ErrorBody), (status = 200, body = crate::store::points::Point), (status = 404, description = "unknown site", body = crate::api::schemas::ErrorBody), (status = 422, description = "invalid settings, or a point the site has epochs but never measured, without \"planned\": true", body = crate::api::schemas::ErrorBody)))]
pub async fn update(
    State(state): State<AppState>,
    ApiPath((site, point)): ApiPath<(String, String)>,
    access: Option<axum::Extension<crate::http::auth::Access>>,
    ApiJson(settings): ApiJson<PointSettings>,
) -> Result<impl IntoResponse, ApiError> {
    find(&state, &site).await?;
    check_settings(&point, &settings)?;
    let actor = access.map(|a| a.0).unwrap_or_default().actor("api");
    let stored = crate::service::site_settings::set_point(
        &state.store,
        &site,
        &point,
        &settings,
        &actor,
        state.public_url(),
    )
    .await?;
    Ok(axum::Json(stored))
}

/// The point's name, group and direction checked, naming the one at fault.
fn check_settings(point: &str, settings: &PointSettings) -> Result<(), ApiError> {
    if !is_valid_identifier(point) {
        return Err(ApiError::unprocessable(
            "invalid_point",
            format!(
                "point '{}': identifiers must match [A-Za-z0-9._-]{{1,64}} and not be . or ..",
                cliffwatch_core::contract::truncate_for_message(point)
            ),
        ));
    }
    if let Some(Some(g)) = &settings.group {
        if !is_valid_identifier(g) {
            return Err(ApiError::unprocessable(
                "invalid_point",
                format!(
                    "group '{}': identifiers must match [A-Za-z0-9._-]{{1,64}} and not be . or ..",
                    cliffwatch_core::contract::truncate_for_message(g)
                ),
            ));
        }
    }
    if let Some(Some(d)) = settings.direction {
        if !cliffwatch_core::analysis::is_usable_direction(d) {
            return Err(ApiError::unprocessable(
                "invalid_point",
                cliffwatch_core::analysis::UNUSABLE_DIRECTION,
            ));
        }
    }
    Ok(())
}

/// `PUT /api/v1/sites/{site}/points`: sets several points at once, `{"T101": {"role":
/// "stable"}, "T102": {"role": "stable"}, …}` (each value the body of `PUT …/points/{point}`,
/// at most 10 000), in one transaction with one recompute: all are stored or none (422 naming
/// the first at fault).
#[utoipa::path(put, path = "/api/v1/sites/{site}/points", operation_id = "update_points", params(("site" = String, Path)),
    request_body(content = std::collections::BTreeMap<String, PointSettings>, description = "point name → its settings"),
    responses((status = 409, description = "the site is retired (code `site_retired`): it takes no more changes", body = crate::api::schemas::ErrorBody), (status = 200, description = "the points after, by name", body = UpdatedPoints),
        (status = 400, description = "not JSON", body = crate::api::schemas::ErrorBody),
        (status = 404, description = "unknown site", body = crate::api::schemas::ErrorBody),
        (status = 422, description = "invalid settings, a point the site has epochs but never measured without \"planned\": true, or more than 10 000 points; nothing stored", body = crate::api::schemas::ErrorBody)))]
pub async fn update_many(
    State(state): State<AppState>,
    ApiPath(site): ApiPath<String>,
    access: Option<axum::Extension<crate::http::auth::Access>>,
    ApiJson(raw): ApiJson<std::collections::BTreeMap<String, serde_json::Value>>,
) -> Result<impl IntoResponse, ApiError> {
    find(&state, &site).await?;
    // Each value an object of the single-point form (serde would read a struct from an array).
    let mut body = std::collections::BTreeMap::new();
    for (point, value) in raw {
        let named = |m: String| {
            ApiError::unprocessable(
                "invalid_point",
                format!(
                    "point '{}': {m}",
                    cliffwatch_core::contract::truncate_for_message(&point)
                ),
            )
        };
        if !value.is_object() {
            return Err(named(
                "its settings must be a JSON object such as {\"role\": \"stable\"}".into(),
            ));
        }
        let settings: PointSettings =
            serde_json::from_value(value).map_err(|e| named(e.to_string()))?;
        body.insert(point, settings);
    }
    let max = crate::service::site_settings::MAX_POINTS_PER_CHANGE;
    if body.len() > max {
        return Err(ApiError::unprocessable(
            "invalid_point",
            format!("{} points: at most {max} in one change", body.len()),
        ));
    }
    if body.is_empty() {
        return Err(ApiError::unprocessable(
            "invalid_point",
            "no point: the body maps point names to their settings, e.g. {\"T101\": {\"role\": \"stable\"}}",
        ));
    }
    for (point, settings) in &body {
        check_settings(point, settings).map_err(|mut e| {
            if !e.message.starts_with("point '") {
                e.message = format!(
                    "point '{}': {}",
                    cliffwatch_core::contract::truncate_for_message(point),
                    e.message
                );
            }
            e
        })?;
    }
    let actor = access.map(|a| a.0).unwrap_or_default().actor("api");
    let changes: Vec<(String, PointSettings)> = body.into_iter().collect();
    let items = crate::service::site_settings::set_points(
        &state.store,
        &site,
        &changes,
        &actor,
        state.public_url(),
    )
    .await?;
    Ok(axum::Json(UpdatedPoints { items }))
}

/// The answer of a bulk point change.
#[derive(Debug, serde::Serialize, utoipa::ToSchema)]
pub struct UpdatedPoints {
    /// The points after the change, by name.
    pub items: Vec<crate::store::points::Point>,
}

/// Query of the time series.
#[derive(Debug, Default, Deserialize)]
pub struct SeriesParams {
    /// Earliest observation time (RFC 3339 or date), inclusive.
    pub from: Option<String>,
    /// Latest observation time (RFC 3339 or date), inclusive.
    pub to: Option<String>,
    /// `json` (default) or `csv`.
    pub format: Option<String>,
    /// Page size of the JSON form (1..=1000, default 100). The CSV form is the whole range.
    pub limit: Option<i64>,
    /// Cursor of the JSON form.
    pub cursor: Option<String>,
}

impl SeriesParams {
    /// The range in store form (`from`, `to`) and the served format; 400 naming the bad value.
    pub fn range_and_format(
        &self,
    ) -> Result<(Option<String>, Option<String>, SeriesFormat), ApiError> {
        let from = self
            .from
            .as_deref()
            .map(|s| time_bound(s, false))
            .transpose()?;
        let to = self
            .to
            .as_deref()
            .map(|s| time_bound(s, true))
            .transpose()?;
        let format = match self.format.as_deref() {
            None | Some("json") => SeriesFormat::JsonItems,
            Some("csv") => SeriesFormat::Csv,
            Some(other) => {
                return Err(ApiError::bad_request(format!(
                    "format '{}': json or csv",
                    cliffwatch_core::contract::truncate_for_message(other)
                )))
            }
        };
        Ok((from, to, format))
    }
}

/// Columns of the CSV time series.
pub use crate::store::series::CSV_HEADER;

/// `GET /api/v1/sites/{site}/points/{point}/displacements`: the time series, oldest first.
#[utoipa::path(get, path = "/api/v1/sites/{site}/points/{point}/displacements", operation_id = "list_point_displacements",
    params(("site" = String, Path), ("point" = String, Path), ("from" = Option<String>, Query), ("to" = Option<String>, Query),
           ("format" = Option<String>, Query, description = "json or csv"), ("limit" = Option<i64>, Query, minimum = 1, description = "page size (default 100; above 1000 read as 1000)"), ("cursor" = Option<String>, Query)),
    responses((status = 200, description = "the time series, oldest first: a page (JSON) or the whole range (CSV, columns as CSV_HEADER)", content((crate::api::list::Page<crate::store::displacements::Displacement> = "application/json"), (String = "text/csv"))), (status = 400, description = "bad time bound, format or cursor", body = crate::api::schemas::ErrorBody), (status = 404, description = "unknown site or point", body = crate::api::schemas::ErrorBody)))]
pub async fn displacements(
    State(state): State<AppState>,
    ApiPath((site, point)): ApiPath<(String, String)>,
    ApiQuery(q): ApiQuery<SeriesParams>,
) -> Result<Response, ApiError> {
    find(&state, &site).await?;
    let db = state.store.reader();
    let p = points::get(db, &site, &point).await?.ok_or_else(|| {
        ApiError::not_found(format!(
            "site '{site}' has no point '{}'",
            cliffwatch_core::contract::truncate_for_message(&point)
        ))
    })?;
    let (from, to, format) = q.range_and_format()?;
    let csv = format == SeriesFormat::Csv;
    // checked for both formats, though CSV answers the whole range
    let page = PageParams {
        limit: q.limit,
        cursor: q.cursor,
    };
    let limit = page.limit()?;
    let mut query = SeriesQuery {
        site,
        point,
        from,
        to,
        after: None,
        limit: None,
        direction: p.direction,
        extremes_above: None,
    };
    if csv {
        // streamed: the first chunk (or the error that stopped the read) decides the status
        let mut rx = series::stream_csv(&state.store, query).await?;
        let first = rx
            .recv()
            .await
            .ok_or_else(|| ApiError::internal("series reader ended without an answer"))??;
        let body = Body::from_stream(Chunks {
            first: Some(first),
            rx,
        });
        return Ok(([(header::CONTENT_TYPE, "text/csv; charset=utf-8")], body).into_response());
    }
    query.after = page.cursor(Listing::Series)?;
    query.limit = Some(limit);
    let mut out = Vec::with_capacity(512 * limit as usize + 64);
    out.extend_from_slice(b"{\"items\":");
    let written = series::write(&state.store, query, SeriesFormat::JsonItems, out).await?;
    let mut out = written.out;
    out.extend_from_slice(b",\"next_cursor\":");
    let next = written
        .last_observed_at
        .filter(|_| written.more)
        .map(|last| encode(Listing::Series, &last));
    serde_json::to_writer(&mut out, &next).map_err(ApiError::internal)?;
    out.push(b'}');
    Ok(([(header::CONTENT_TYPE, "application/json")], out).into_response())
}

/// The chunks of a streamed series as a body stream: the first (already received), then the rest.
struct Chunks {
    first: Option<Bytes>,
    rx: tokio::sync::mpsc::Receiver<Result<Bytes, crate::store::StoreError>>,
}

impl futures_core::Stream for Chunks {
    type Item = Result<Bytes, crate::store::StoreError>;

    fn poll_next(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<Option<Self::Item>> {
        if let Some(first) = self.first.take() {
            return Poll::Ready(Some(Ok(first)));
        }
        self.rx.poll_recv(cx)
    }
}
