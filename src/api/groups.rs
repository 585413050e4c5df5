//! `PUT /api/v1/sites/{site}/groups/{group}`, `GET /api/v1/sites/{site}/groups[/{group}]`: point
//! groups declared as rigid blocks. A block's motion is estimated from all its points each epoch;
//! rules naming the group (and rules without a group) apply to it.

use axum::extract::State;
use axum::http::header;
use axum::response::{IntoResponse, Response};
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use super::list::{encode, Listing, Page, PageParams};
use super::points::SeriesParams;
use super::sites::find;
use crate::http::error::{ApiError, ApiJson, ApiPath, ApiQuery};
use crate::http::AppState;
use crate::store::series::{format_rows, SeriesFormat};
use crate::store::{block_motions, groups, points};
use cliffwatch_core::analysis::{GroupConfig, GroupKind};
use cliffwatch_core::contract::truncate_for_message;
use cliffwatch_core::photogrammetry::input::epoch::is_valid_identifier;

/// Body of `PUT .../groups/{group}`.
#[derive(Debug, Clone, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct GroupBody {
    /// `block` (the only kind).
    #[schema(pattern = "^block$")]
    pub kind: String,
    /// Direction of interest of the block in the site frame (three finite numbers, not all zero).
    #[serde(default)]
    #[schema(min_items = 3, max_items = 3)]
    pub direction: Option<[f64; 3]>,
    /// Member points (identifiers); absent or empty: the points whose `group` names this group.
    #[serde(default)]
    pub points: Option<Vec<String>>,
    /// Process noise of the block's Kalman filter (mm²/day⁵, > 0); absent: the site's.
    #[serde(default)]
    #[schema(exclusive_minimum = 0.0)]
    pub process_noise: Option<f64>,
}

/// A stored group, with what the site's measurements say of its members.
#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct Group {
    /// Group name.
    pub name: String,
    /// `block`.
    pub kind: String,
    /// Direction of interest (site frame), when set.
    pub direction: Option<[f64; 3]>,
    /// Member points as declared (empty: by the points' `group`).
    pub points: Vec<String>,
    /// Process noise of the block's filter (mm²/day⁵), when set.
    pub process_noise: Option<f64>,
    /// The member points now: the declared list, else the points whose `group` names this group.
    pub members: Vec<String>,
    /// Members without coordinates in any epoch yet: misspelt, or not measured yet. The block has
    /// a motion only in epochs that measure at least 2 of its members (and its reference epoch
    /// those 2 too); with fewer it raises nothing and its points' own rules still apply.
    pub unmeasured_points: Vec<String>,
}

/// The groups with their members and the members never measured.
async fn describe(
    state: &AppState,
    site: &str,
    configs: Vec<GroupConfig>,
) -> Result<Vec<Group>, ApiError> {
    if configs.is_empty() {
        return Ok(Vec::new());
    }
    let mut db = state.store.read().await?;
    let point_configs = crate::service::analysis_inputs::point_configs(&mut db, site).await?;
    let measured: std::collections::HashSet<String> = points::latest_coordinates(&mut db, site)
        .await?
        .into_iter()
        .map(|c| c.point)
        .collect();
    Ok(configs
        .into_iter()
        .map(|g| {
            let members = g.members(&point_configs);
            let unmeasured_points = members
                .iter()
                .filter(|m| !measured.contains(*m))
                .cloned()
                .collect();
            Group {
                name: g.name,
                kind: match g.kind {
                    GroupKind::Block => "block".into(),
                },
                direction: g.direction,
                points: g.points,
                process_noise: g.process_noise,
                members,
                unmeasured_points,
            }
        })
        .collect())
}

/// [`describe`] of one group.
async fn describe_one(state: &AppState, site: &str, g: GroupConfig) -> Result<Group, ApiError> {
    describe(state, site, vec![g])
        .await?
        .pop()
        .ok_or_else(|| ApiError::internal("group vanished"))
}

fn invalid(message: String) -> ApiError {
    ApiError::unprocessable("invalid_group", message)
}

/// Checks a group body; the error names the field at fault.
fn check(name: &str, body: &GroupBody) -> Result<GroupConfig, ApiError> {
    if !is_valid_identifier(name) {
        return Err(invalid(format!(
            "group '{}': identifiers must match [A-Za-z0-9._-]{{1,64}} and not be . or ..",
            truncate_for_message(name)
        )));
    }
    if body.kind != "block" {
        return Err(invalid(format!(
            "kind '{}': block",
            truncate_for_message(&body.kind)
        )));
    }
    if let Some(d) = body.direction {
        if !cliffwatch_core::analysis::is_usable_direction(d) {
            return Err(invalid(
                cliffwatch_core::analysis::UNUSABLE_DIRECTION.into(),
            ));
        }
    }
    let points = body.points.clone().unwrap_or_default();
    if let Some(p) = points.iter().find(|p| !is_valid_identifier(p)) {
        return Err(invalid(format!(
            "points: '{}' is not an identifier ([A-Za-z0-9._-]{{1,64}}, not . or ..)",
            truncate_for_message(p)
        )));
    }
    if let Some(q) = body.process_noise {
        if !(q > 0.0 && q.is_finite()) {
            return Err(invalid(format!("process_noise {q}: a finite number > 0")));
        }
    }
    Ok(GroupConfig {
        name: name.to_string(),
        kind: GroupKind::Block,
        direction: body.direction,
        points,
        process_noise: body.process_noise,
    })
}

/// `PUT /api/v1/sites/{site}/groups/{group}`: declares (or replaces) a block group and recomputes
/// the site's series and alerts in the same transaction.
#[utoipa::path(put, path = "/api/v1/sites/{site}/groups/{group}", operation_id = "put_group", request_body = GroupBody,
    params(("site" = String, Path), ("group" = String, Path, pattern = "^[A-Za-z0-9._-]{1,64}$")),
    responses((status = 409, description = "the site is retired (code `site_retired`): it takes no more changes", body = crate::api::schemas::ErrorBody), (status = 200, body = Group),
              (status = 400, description = "not JSON", body = crate::api::schemas::ErrorBody),
              (status = 404, description = "unknown site", body = crate::api::schemas::ErrorBody),
              (status = 422, description = "invalid group (the field at fault is named)", body = crate::api::schemas::ErrorBody)))]
pub async fn put(
    State(state): State<AppState>,
    ApiPath((site, group)): ApiPath<(String, String)>,
    access: Option<axum::Extension<crate::http::auth::Access>>,
    ApiJson(body): ApiJson<GroupBody>,
) -> Result<impl IntoResponse, ApiError> {
    find(&state, &site).await?;
    let config = check(&group, &body)?;
    let actor = access.map(|a| a.0).unwrap_or_default().actor("api");
    crate::service::site_settings::declare_group(
        &state.store,
        &site,
        &config,
        &actor,
        state.public_url(),
    )
    .await?;
    let stored = groups::get(state.store.reader(), &site, &group)
        .await?
        .ok_or_else(|| ApiError::internal("group vanished"))?;
    Ok(axum::Json(describe_one(&state, &site, stored).await?))
}

/// `GET /api/v1/sites/{site}/groups`: the site's groups by name, a page of the contract's list
/// shape.
#[utoipa::path(get, path = "/api/v1/sites/{site}/groups", operation_id = "list_groups", params(("site" = String, Path), ("limit" = Option<i64>, Query, minimum = 1, description = "page size (default 100; above 1000 read as 1000)"), ("cursor" = Option<String>, Query)),
    responses((status = 200, description = "groups by name", body = Page<Group>),
              (status = 404, description = "unknown site", body = crate::api::schemas::ErrorBody)))]
pub async fn list(
    State(state): State<AppState>,
    ApiPath(site): ApiPath<String>,
    ApiQuery(page): ApiQuery<PageParams>,
) -> Result<impl IntoResponse, ApiError> {
    find(&state, &site).await?;
    let after = page.cursor(Listing::Groups)?;
    let limit = page.limit()?;
    let mut all = groups::list(state.store.reader(), &site).await?;
    all.sort_by(|a, b| a.name.cmp(&b.name));
    let fetched: Vec<GroupConfig> = all
        .into_iter()
        .filter(|g| after.as_ref().is_none_or(|a| g.name.as_str() > a.as_str()))
        .take(limit as usize + 1)
        .collect();
    let fetched = describe(&state, &site, fetched).await?;
    Ok(axum::Json(Page::from_fetched(
        fetched,
        limit,
        Listing::Groups,
        |g| g.name.clone(),
    )))
}

/// `GET /api/v1/sites/{site}/groups/{group}`: one group.
#[utoipa::path(get, path = "/api/v1/sites/{site}/groups/{group}", operation_id = "get_group", params(("site" = String, Path), ("group" = String, Path)),
    responses((status = 200, body = Group),
              (status = 404, description = "unknown site or group", body = crate::api::schemas::ErrorBody)))]
pub async fn get_one(
    State(state): State<AppState>,
    ApiPath((site, group)): ApiPath<(String, String)>,
) -> Result<impl IntoResponse, ApiError> {
    find(&state, &site).await?;
    let g = groups::get(state.store.reader(), &site, &group)
        .await?
        .ok_or_else(|| {
            ApiError::not_found(format!(
                "site '{site}' has no group '{}'",
                truncate_for_message(&group)
            ))
        })?;
    Ok(axum::Json(describe_one(&state, &site, g).await?))
}

/// `GET /api/v1/sites/{site}/groups/{group}/motion`: the block's motion series, oldest first, in
/// the form of a point's series (`point` names the group): the translation of the block with its
/// covariance, its length, velocity, time to failure and the filtered values.
#[utoipa::path(get, path = "/api/v1/sites/{site}/groups/{group}/motion", operation_id = "get_group_motion",
    params(("site" = String, Path), ("group" = String, Path), ("from" = Option<String>, Query), ("to" = Option<String>, Query),
           ("format" = Option<String>, Query, description = "json or csv"), ("limit" = Option<i64>, Query, minimum = 1, description = "page size (default 100; above 1000 read as 1000)"), ("cursor" = Option<String>, Query)),
    responses((status = 200, description = "the block's motion series, oldest first: a page (JSON) or the whole range (CSV, columns as the point series)", content((crate::api::list::Page<crate::store::displacements::Displacement> = "application/json"), (String = "text/csv"))),
              (status = 400, description = "bad time bound, format or cursor", body = crate::api::schemas::ErrorBody),
              (status = 404, description = "unknown site or group", body = crate::api::schemas::ErrorBody)))]
pub async fn motion(
    State(state): State<AppState>,
    ApiPath((site, group)): ApiPath<(String, String)>,
    ApiQuery(q): ApiQuery<SeriesParams>,
) -> Result<Response, ApiError> {
    find(&state, &site).await?;
    let db = state.store.reader();
    let g = groups::get(db, &site, &group).await?.ok_or_else(|| {
        ApiError::not_found(format!(
            "site '{site}' has no group '{}'",
            truncate_for_message(&group)
        ))
    })?;
    let (from, to, format) = q.range_and_format()?;
    // checked for both formats, though CSV answers the whole range
    let page = PageParams {
        limit: q.limit,
        cursor: q.cursor,
    };
    let limit = page.limit()?;
    if format == SeriesFormat::Csv {
        let rows = block_motions::series(
            db,
            &site,
            &group,
            from.as_deref(),
            to.as_deref(),
            None,
            None,
        )
        .await?;
        let body = format_rows(&rows, format, g.direction, &group);
        return Ok(([(header::CONTENT_TYPE, "text/csv; charset=utf-8")], body).into_response());
    }
    let after = page.cursor(Listing::Series)?;
    let mut rows = block_motions::series(
        db,
        &site,
        &group,
        from.as_deref(),
        to.as_deref(),
        after.as_deref(),
        Some(limit + 1),
    )
    .await?;
    let more = rows.len() > limit as usize;
    rows.truncate(limit as usize);
    let mut out = b"{\"items\":".to_vec();
    out.extend_from_slice(&format_rows(&rows, format, g.direction, &group));
    out.extend_from_slice(b",\"next_cursor\":");
    // the cursor is the last row's stored time
    let next = match rows.last().filter(|_| more) {
        Some(last) => Some(encode(
            Listing::Series,
            &crate::store::timestamp(
                crate::store::parse_timestamp(&last.observed_at)
                    .ok_or_else(|| ApiError::internal("stored time does not parse"))?,
            ),
        )),
        None => None,
    };
    serde_json::to_writer(&mut out, &next).map_err(ApiError::internal)?;
    out.push(b'}');
    Ok(([(header::CONTENT_TYPE, "application/json")], out).into_response())
}

/// `DELETE /api/v1/sites/{site}/groups/{group}`: deletes a group (its points stay, outside any
/// block) and recomputes the site's series and alerts in the same transaction; recorded in the
/// site's audit trail.
#[utoipa::path(delete, path = "/api/v1/sites/{site}/groups/{group}", operation_id = "delete_group",
    params(("site" = String, Path), ("group" = String, Path)),
    responses((status = 409, description = "the site is retired (code `site_retired`): it takes no more changes", body = crate::api::schemas::ErrorBody), (status = 204, description = "deleted"),
              (status = 404, description = "unknown site or group", body = crate::api::schemas::ErrorBody)))]
pub async fn delete(
    State(state): State<AppState>,
    ApiPath((site, group)): ApiPath<(String, String)>,
    access: Option<axum::Extension<crate::http::auth::Access>>,
) -> Result<impl IntoResponse, ApiError> {
    find(&state, &site).await?;
    let actor = access.map(|a| a.0).unwrap_or_default().actor("api");
    crate::service::site_admin::delete_group(
        &state.store,
        &site,
        &group,
        &actor,
        state.public_url(),
    )
    .await?;
    Ok(axum::http::StatusCode::NO_CONTENT)
}
