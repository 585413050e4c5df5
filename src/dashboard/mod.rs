//! The dashboard: server-rendered pages in the daemon itself, on the API's port, with nothing to
//! install and no request to any other host.
//!
//! Pages link down by plain `<a href>`: sites ([`sites_page`], `/`) → site ([`site_page`],
//! `/sites/{site}`: face plan, open alerts with acknowledgement, epochs, points) →
//! block ([`block_page`], `/sites/{site}/groups/{group}`: its motion, forecast history, members
//! and open alerts) → point ([`point_page`], `/sites/{site}/points/{point}`: plots of the series with ±2σ bands,
//! thresholds, alert markers, velocity and inverse velocity) → epoch ([`epoch_page`],
//! `/sites/{site}/epochs/{epoch}`: the adjustment report and the residuals of each image, and for
//! a watched epoch its images with the detected targets drawn over them, [`epoch_images`]), and
//! alert ([`alert_page`], `/sites/{site}/alerts/{id}`: its history with every acknowledgement), and
//! the site's changes ([`audit_trail`], `/sites/{site}/audit`); the
//! campaign report of a period ([`report_page`], `/sites/{site}/report?from=&to=`) prints on A4.
//!
//! Plots are drawn in the browser by the vendored uPlot from columnar JSON that
//! [`plot_data`] downsamples on the server ([`downsample`]), so a 10-year hourly history costs
//! the browser what a short one does. Templates are maud (checked at compile time, escaping
//! every value); assets are embedded ([`assets`]). Access follows the API's roles
//! ([`crate::http::auth`], [`crate::http::session`], [`sign_in`]); acknowledging needs `upload` and the
//! session's CSRF token ([`acknowledge`]); the site page's settings form ([`site_edit`]) needs
//! `admin` and the same token, as its retirement form.
//!
//! Pure parts (no I/O): [`face_plan`] (the face's plane), [`downsample`] (which epochs a plot
//! draws), [`image_preview`] (a station image made small), [`plan_svg`], [`time_plot_svg`], [`local_time`] and [`layout`] (markup).

pub(crate) mod acknowledge;
pub(crate) mod alert_filter;
pub(crate) mod alert_groups;
pub(crate) mod alert_page;
pub(crate) mod assets;
pub(crate) mod audit_trail;
pub(crate) mod block_page;
pub mod downsample;
pub(crate) mod epoch_images;
pub(crate) mod epoch_page;
pub(crate) mod face_plan;
pub(crate) mod headline;
pub(crate) mod health;
pub mod image_preview;
pub(crate) mod incident_panel;
pub(crate) mod layout;
#[cfg(test)]
mod level_colours;
pub(crate) mod local_time;
pub(crate) use crate::natural_order;
pub(crate) mod page;
pub(crate) mod plan_labels;
pub(crate) mod plan_page;
pub(crate) mod plan_svg;
pub(crate) mod plot_data;
pub(crate) mod point_page;
pub(crate) mod report_page;
pub(crate) mod report_sections;
pub(crate) mod sensitivity;
pub(crate) mod sign_in;
pub(crate) mod site_edit;
pub(crate) mod site_page;
pub(crate) mod sites_page;
pub(crate) mod time_plot_svg;

use axum::routing::{get, post};
use axum::Router;

use crate::http::AppState;

/// The dashboard's routes (put beside the API's by [`crate::http::router`], behind the same auth).
pub fn routes() -> Router<AppState> {
    Router::new()
        .route("/", get(sites_page::sites))
        .route("/sites/{site}", get(site_page::site))
        .route("/sites/{site}/points/{point}", get(point_page::point))
        .route("/sites/{site}/groups/{group}", get(block_page::block))
        .route("/sites/{site}/epochs/{epoch}", get(epoch_page::epoch))
        .route(
            "/sites/{site}/epochs/{epoch}/images/{station}",
            get(epoch_images::image),
        )
        .route("/sites/{site}/report", get(report_page::report))
        .route("/sites/{site}/plan", get(plan_page::plan))
        .route("/sites/{site}/alerts/{id}", get(alert_page::alert))
        .route("/sites/{site}/audit", get(audit_trail::audit))
        .route("/dashboard/plot/{site}/{point}", get(plot_data::plot))
        .route("/dashboard/alerts/{id}/ack", post(acknowledge::acknowledge))
        .route(
            "/dashboard/sites/{site}/incidents/{incident}/ack",
            post(acknowledge::acknowledge_incident),
        )
        .route("/dashboard/sites/{site}/settings", post(site_edit::save))
        .route("/dashboard/sites/{site}/retire", post(site_edit::retire))
        .route("/signin", get(sign_in::form).post(sign_in::sign_in))
        .route("/signout", post(sign_in::sign_out))
        .route("/assets/{file}", get(assets::asset))
}
