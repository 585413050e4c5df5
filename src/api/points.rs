//! `GET /api/v1/sites/{site}/points`, `PUT .../points/{point}`, `GET .../points/{point}/displacements`.

use std::collections::HashMap;
use std::fmt::Write;

use axum::extract::State;
use axum::http::header;
use axum::response::{IntoResponse, Response};
use serde::{Deserialize, Serialize};
use serde_json::json;

use super::epochs::time_bound;
use super::error::{ApiError, ApiJson, ApiPath, ApiQuery};
use super::list::{Page, PageParams};
use super::sites::find;
use super::AppState;
use crate::photogrammetry::epoch::is_valid_identifier;
use crate::store::displacements::{self, Displacement};
use crate::store::points::{self, PointSettings};
use crate::store::webhooks::level_rank;
use crate::store::{alerts, display_timestamp, parse_timestamp, timestamp};

/// One line of the point list.
#[derive(Debug, Serialize)]
pub struct PointItem {
    /// Point name.
    pub point: String,
    /// `stable` or `monitored`.
    pub role: String,
    /// Group name.
    pub group: Option<String>,
    /// Direction of interest, site frame.
    pub direction: Option<[f64; 3]>,
    /// Latest coordinates: epoch, observed_at, X/Y/Z in m and σ in mm.
    pub latest: Option<serde_json::Value>,
    /// Latest displacement.
    pub displacement: Option<Displacement>,
    /// Highest level of its open or acknowledged alerts.
    pub alert_level: Option<String>,
}

/// `GET /api/v1/sites/{site}/points`: every point (by name) with its latest state.
#[utoipa::path(get, path = "/api/v1/sites/{site}/points", params(("site" = String, Path), ("limit" = Option<i64>, Query), ("cursor" = Option<String>, Query)),
    responses((status = 200, description = "{items: [point], next_cursor}"), (status = 404, description = "unknown site")))]
pub async fn list(
    State(state): State<AppState>,
    ApiPath(site): ApiPath<String>,
    ApiQuery(page): ApiQuery<PageParams>,
) -> Result<impl IntoResponse, ApiError> {
    find(&state, &site).await?;
    let db = state.store.reader();
    let cursor = page.cursor()?;
    let pts = points::list(db, &site, cursor.as_deref(), page.limit() + 1).await?;
    let page = Page::from_fetched(pts, page.limit(), |p| p.name.clone());
    let mut latest: HashMap<String, _> = points::latest_coordinates(db, &site)
        .await?
        .into_iter()
        .map(|c| (c.point.clone(), c))
        .collect();
    let mut disp: HashMap<String, Displacement> = displacements::latest(db, &site)
        .await?
        .into_iter()
        .map(|d| (d.point.clone(), d))
        .collect();
    let mut levels: HashMap<String, String> = HashMap::new();
    for (point, level) in alerts::active_levels(db, &site).await? {
        let e = levels.entry(point).or_default();
        if level_rank(&level) > level_rank(e) {
            *e = level;
        }
    }
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
    let n = direction?;
    let norm = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    (norm > 0.0).then(|| (d.dx_mm * n[0] + d.dy_mm * n[1] + d.dz_mm * n[2]) / norm)
}

/// `PUT /api/v1/sites/{site}/points/{point}`: sets role, group, direction of interest (creates the
/// point when new, so roles can be set before the first epoch).
#[utoipa::path(put, path = "/api/v1/sites/{site}/points/{point}", request_body = PointSettings, params(("site" = String, Path), ("point" = String, Path)),
    responses((status = 200, body = crate::store::points::Point), (status = 404, description = "unknown site"), (status = 422, description = "invalid settings")))]
pub async fn update(
    State(state): State<AppState>,
    ApiPath((site, point)): ApiPath<(String, String)>,
    ApiJson(settings): ApiJson<PointSettings>,
) -> Result<impl IntoResponse, ApiError> {
    find(&state, &site).await?;
    if !is_valid_identifier(&point) {
        return Err(ApiError::unprocessable(
            "invalid_point",
            format!("point '{point}': identifiers must match [A-Za-z0-9._-]{{1,64}}"),
        ));
    }
    if let Some(role) = &settings.role {
        if role != "stable" && role != "monitored" {
            return Err(ApiError::unprocessable(
                "invalid_point",
                format!("role '{role}': stable or monitored"),
            ));
        }
    }
    if let Some(d) = settings.direction {
        if d.iter().any(|v| !v.is_finite()) || d.iter().all(|v| *v == 0.0) {
            return Err(ApiError::unprocessable(
                "invalid_point",
                "direction: three finite numbers, not all zero",
            ));
        }
    }
    let mut tx = state.store.begin_write().await?;
    points::upsert(&mut *tx, &site, &point, &settings).await?;
    tx.commit().await.map_err(crate::store::StoreError::from)?;
    let stored = points::get(state.store.reader(), &site, &point).await?;
    Ok(axum::Json(stored))
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

/// Columns of the CSV time series.
pub const CSV_HEADER: &str = "epoch,observed_at,dx_mm,dy_mm,dz_mm,d_mm,sigma_dx_mm,sigma_dy_mm,sigma_dz_mm,sigma_mm,d_along_mm,significant,velocity_mm_per_day,time_to_failure_hours";

/// `GET /api/v1/sites/{site}/points/{point}/displacements`: the time series, oldest first.
#[utoipa::path(get, path = "/api/v1/sites/{site}/points/{point}/displacements",
    params(("site" = String, Path), ("point" = String, Path), ("from" = Option<String>, Query), ("to" = Option<String>, Query),
           ("format" = Option<String>, Query, description = "json or csv"), ("limit" = Option<i64>, Query), ("cursor" = Option<String>, Query)),
    responses((status = 200, description = "{items: [displacement], next_cursor} or text/csv"), (status = 404, description = "unknown site or point")))]
pub async fn displacements(
    State(state): State<AppState>,
    ApiPath((site, point)): ApiPath<(String, String)>,
    ApiQuery(q): ApiQuery<SeriesParams>,
) -> Result<Response, ApiError> {
    find(&state, &site).await?;
    let db = state.store.reader();
    let p = points::get(db, &site, &point)
        .await?
        .ok_or_else(|| ApiError::not_found(format!("site '{site}' has no point '{point}'")))?;
    let from = q
        .from
        .as_deref()
        .map(|s| time_bound(s, false))
        .transpose()?;
    let to = q.to.as_deref().map(|s| time_bound(s, true)).transpose()?;
    let csv = match q.format.as_deref() {
        None | Some("json") => false,
        Some("csv") => true,
        Some(other) => {
            return Err(ApiError::bad_request(format!(
                "format '{other}': json or csv"
            )))
        }
    };
    if csv {
        let rows = displacements::series(
            db,
            &site,
            &point,
            from.as_deref(),
            to.as_deref(),
            None,
            None,
        )
        .await?;
        let mut out = String::with_capacity(64 + rows.len() * 160);
        out.push_str(CSV_HEADER);
        out.push('\n');
        let opt = |v: Option<f64>| v.map(|v| v.to_string()).unwrap_or_default();
        for d in &rows {
            let _ = writeln!(
                out,
                "{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
                d.epoch,
                d.observed_at,
                d.dx_mm,
                d.dy_mm,
                d.dz_mm,
                d.d_mm,
                d.sigma_dx_mm,
                d.sigma_dy_mm,
                d.sigma_dz_mm,
                d.sigma_mm,
                opt(along(d, p.direction)),
                d.significant,
                opt(d.velocity_mm_per_day),
                opt(d.time_to_failure_hours)
            );
        }
        return Ok(([(header::CONTENT_TYPE, "text/csv; charset=utf-8")], out).into_response());
    }
    let page = PageParams {
        limit: q.limit,
        cursor: q.cursor,
    };
    let after = page.cursor()?;
    let mut rows = displacements::series(
        db,
        &site,
        &point,
        from.as_deref(),
        to.as_deref(),
        after.as_deref(),
        Some(page.limit() + 1),
    )
    .await?;
    for d in &mut rows {
        d.d_along_mm = along(d, p.direction);
    }
    let page = Page::from_fetched(rows, page.limit(), |d| {
        parse_timestamp(&d.observed_at)
            .map(timestamp)
            .unwrap_or_default()
    });
    Ok(axum::Json(page).into_response())
}
