//! `POST /api/v1/plan` (the pre-analysis of a plan in the body, as `cliffwatch plan` prints it)
//! and `POST /api/v1/sites/{site}/plan` (a what-if on a site's current network). Both need the
//! `read` role: they compute, and store nothing.

use axum::extract::State;
use axum::response::IntoResponse;
use serde::Deserialize;

use super::sites::find;
use crate::http::error::{ApiError, ApiJson, ApiPath};
use crate::http::AppState;
use crate::service::ingest::EpochLimits;
use crate::service::{plan, ServiceError};
use cliffwatch_core::plan::{Plan, PlanChange};

/// Body of `POST /api/v1/sites/{site}/plan`: the changes to the site's network, applied in
/// order (none: the site's own network).
#[derive(Debug, Default, Deserialize, utoipa::ToSchema)]
#[serde(deny_unknown_fields)]
pub struct WhatIf {
    /// Changes, in order.
    #[serde(default)]
    pub changes: Vec<PlanChange>,
}

/// `POST /api/v1/plan`: the pre-analysis of a planned camera network.
#[utoipa::path(post, path = "/api/v1/plan", operation_id = "plan", request_body = cliffwatch_core::plan::Plan,
    responses((status = 200, description = "the pre-analysis (as `cliffwatch plan` prints it)", body = cliffwatch_core::plan::PlanReport),
        (status = 400, description = "not JSON", body = crate::api::schemas::ErrorBody),
        (status = 413, description = "body too large, or more targets or stations × targets than the node takes of an epoch", body = crate::api::schemas::ErrorBody),
        (status = 415, description = "not application/json", body = crate::api::schemas::ErrorBody),
        (status = 422, description = "a plan that cannot be analysed (`invalid_plan`, naming the station, camera or target) or of the wrong shape (`invalid_body`)", body = crate::api::schemas::ErrorBody),
        (status = 503, description = "every upload slot stayed busy (`overloaded`) or the computation ran past `compute_budget_secs`; retry after `Retry-After`", body = crate::api::schemas::ErrorBody, headers(("Retry-After" = u64, description = "seconds to wait before retrying")))))]
pub async fn plan(
    State(state): State<AppState>,
    ApiJson(body): ApiJson<Plan>,
) -> Result<impl IntoResponse, ApiError> {
    let slot = state.uploads.enter().await.map_err(ServiceError::from)?;
    let limits = EpochLimits::from_config(&state.config);
    Ok(axum::Json(plan::analyse(body, limits, slot).await?))
}

/// `POST /api/v1/sites/{site}/plan`: the pre-analysis of the site's current network after the
/// body's changes.
#[utoipa::path(post, path = "/api/v1/sites/{site}/plan", operation_id = "site_plan", params(("site" = String, Path)),
    request_body = WhatIf,
    responses((status = 200, description = "the site's network, the changes, the pre-analysis and what the latest epoch achieved", body = crate::service::plan::SitePlan),
        (status = 400, description = "not JSON", body = crate::api::schemas::ErrorBody),
        (status = 404, description = "unknown site", body = crate::api::schemas::ErrorBody),
        (status = 409, description = "the site has no epoch, or its latest epoch's observations were deleted (`no_network`)", body = crate::api::schemas::ErrorBody),
        (status = 413, description = "body too large", body = crate::api::schemas::ErrorBody),
        (status = 415, description = "not application/json", body = crate::api::schemas::ErrorBody),
        (status = 422, description = "a change that cannot be applied, or a network that cannot be analysed (`invalid_plan`, naming the change, station or camera), or a body of the wrong shape (`invalid_body`)", body = crate::api::schemas::ErrorBody),
        (status = 503, description = "every upload slot stayed busy (`overloaded`) or the computation ran past `compute_budget_secs`; retry after `Retry-After`", body = crate::api::schemas::ErrorBody, headers(("Retry-After" = u64, description = "seconds to wait before retrying")))))]
pub async fn site_plan(
    State(state): State<AppState>,
    ApiPath(site): ApiPath<String>,
    ApiJson(body): ApiJson<WhatIf>,
) -> Result<impl IntoResponse, ApiError> {
    find(&state, &site).await?;
    let slot = state.uploads.enter().await.map_err(ServiceError::from)?;
    let limits = EpochLimits::from_config(&state.config);
    Ok(axum::Json(
        plan::what_if(&state.store, &site, body.changes, limits, slot).await?,
    ))
}
