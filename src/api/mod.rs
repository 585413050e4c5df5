//! The HTTP API of the contract (`docs/api.md`): its axum routes and handlers, the
//! health endpoints, metrics and the OpenAPI description.
//!
//! Handlers only: each parses its request, calls a use case of [`crate::service`] or a read of
//! [`crate::store`], and answers. [`routes`] lists them; [`crate::http::router`] puts them beside
//! the dashboard's behind the shared auth and limits, and [`crate::daemon`] binds and runs it.
//! Auth, errors and the shared state live in [`crate::http`].

pub(crate) mod alerts;
pub(crate) mod cap;
pub(crate) mod epochs;
pub(crate) mod groups;
pub(crate) mod health;
pub(crate) mod incidents;
pub mod list;
pub(crate) mod openapi;
pub(crate) mod plan;
pub mod points;
pub(crate) mod schemas;
pub(crate) mod site_lifecycle;
pub(crate) mod sites;
pub(crate) mod webhooks;

use axum::routing::{get, post, put};
use axum::Router;

use crate::http::AppState;

/// The API's routes (the contract's paths, `/healthz`, `/readyz` and `/metrics`).
pub fn routes() -> Router<AppState> {
    Router::new()
        .route("/healthz", get(health::healthz))
        .route("/readyz", get(health::readyz))
        .route("/metrics", get(health::metrics))
        .route("/api/v1/openapi.json", get(openapi::openapi_json))
        .route("/api/v1/plan", post(plan::plan))
        .route("/api/v1/sites/{site}/plan", post(plan::site_plan))
        .route("/api/v1/sites", post(sites::create).get(sites::list))
        .route(
            "/api/v1/sites/{site}",
            get(sites::get_one)
                .patch(sites::update)
                .delete(site_lifecycle::delete),
        )
        .route("/api/v1/sites/{site}/audit", get(sites::audit))
        .route("/api/v1/sites/{site}/retire", post(site_lifecycle::retire))
        .route("/api/v1/sites/{site}/export", get(site_lifecycle::export))
        .route(
            "/api/v1/sites/{site}/epochs",
            post(epochs::upload).get(epochs::list),
        )
        .route("/api/v1/sites/{site}/epochs/{epoch}", get(epochs::get_one))
        .route("/api/v1/sites/{site}/reference", put(sites::set_reference))
        .route(
            "/api/v1/sites/{site}/points",
            get(points::list).put(points::update_many),
        )
        .route("/api/v1/sites/{site}/groups", get(groups::list))
        .route(
            "/api/v1/sites/{site}/groups/{group}",
            put(groups::put).get(groups::get_one).delete(groups::delete),
        )
        .route(
            "/api/v1/sites/{site}/groups/{group}/motion",
            get(groups::motion),
        )
        .route("/api/v1/sites/{site}/points/{point}", put(points::update))
        .route(
            "/api/v1/sites/{site}/points/{point}/displacements",
            get(points::displacements),
        )
        .route("/api/v1/sites/{site}/incidents", get(incidents::list))
        .route(
            "/api/v1/sites/{site}/incidents/{incident}/ack",
            post(incidents::acknowledge),
        )
        .route("/api/v1/alerts", get(alerts::list))
        .route("/api/v1/cap/feed.atom", get(cap::feed))
        .route("/api/v1/cap/alerts/{file}", get(cap::message))
        .route("/api/v1/alerts/{id}/ack", post(alerts::acknowledge))
        .route("/api/v1/alerts/{id}/events", get(alerts::events))
        .route(
            "/api/v1/webhooks",
            post(webhooks::create).get(webhooks::list),
        )
        .route(
            "/api/v1/webhooks/{id}",
            axum::routing::delete(webhooks::delete),
        )
        .route("/api/v1/webhooks/{id}/test", post(webhooks::test))
}
