//! Liveness, readiness and the Prometheus metrics.

use std::sync::OnceLock;

use axum::extract::State;
use axum::http::{header, StatusCode};
use axum::response::IntoResponse;
use metrics_exporter_prometheus::{PrometheusBuilder, PrometheusHandle};

use super::schemas::Status;
use crate::http::error::ApiError;
use crate::http::AppState;

/// The process-wide Prometheus recorder (installed once, shared by every server of the process),
/// every series labelled `node` with the name the first server of the process gives.
pub fn metrics_handle(node: &str) -> PrometheusHandle {
    static HANDLE: OnceLock<PrometheusHandle> = OnceLock::new();
    HANDLE
        .get_or_init(|| {
            let recorder = PrometheusBuilder::new()
                .add_global_label("node", node)
                .build_recorder();
            let handle = recorder.handle();
            // Another recorder may be installed already (tests): then ours only renders nothing.
            let _ = metrics::set_global_recorder(recorder);
            describe();
            register_at_zero();
            handle
        })
        .clone()
}

fn describe() {
    metrics::describe_counter!("cliffwatch_uploads_total", "epoch uploads by HTTP status");
    metrics::describe_counter!(
        "cliffwatch_adjustments_total",
        "bundle adjustments by outcome"
    );
    metrics::describe_histogram!(
        "cliffwatch_adjustment_seconds",
        "duration of one bundle adjustment (s)"
    );
    metrics::describe_gauge!(
        "cliffwatch_upload_slots_busy",
        "uploads being processed (of max_concurrent_uploads)"
    );
    metrics::describe_counter!("cliffwatch_alerts_raised_total", "alerts raised");
    metrics::describe_counter!(
        "cliffwatch_alertmanager_posts_total",
        "posts of every held alert to the alertmanager_api_v2 endpoints, by outcome"
    );
    metrics::describe_counter!(
        "cliffwatch_webhook_deliveries_total",
        "webhook delivery attempts by outcome"
    );
    metrics::describe_gauge!(
        "cliffwatch_webhook_queue_depth",
        "pending webhook deliveries"
    );
    metrics::describe_counter!(
        "cliffwatch_webhook_deliveries_pruned_total",
        "finished webhook deliveries deleted by the retention"
    );
    metrics::describe_counter!(
        "cliffwatch_epoch_observations_pruned_total",
        "epochs whose observations the retention deleted"
    );
    metrics::describe_counter!(
        "cliffwatch_watch_folders_pruned_total",
        "taken folders of the watched directory the retention deleted"
    );
}

/// Registers every series at zero, so that a fresh node's `/metrics` already has them and
/// `absent()` and `rate()` rules see them from the start: each counter with each of its label
/// values, each gauge, and the histogram (rendered once it has a sample; its `_count` is what
/// rules use).
fn register_at_zero() {
    for status in ["200", "201", "400", "404", "409", "413", "422", "503"] {
        metrics::counter!("cliffwatch_uploads_total", "status" => status).absolute(0);
    }
    for outcome in ["ok", "failed"] {
        metrics::counter!("cliffwatch_adjustments_total", "outcome" => outcome).absolute(0);
        metrics::counter!("cliffwatch_alertmanager_posts_total", "outcome" => outcome).absolute(0);
    }
    for outcome in ["ok", "retry", "failed"] {
        metrics::counter!("cliffwatch_webhook_deliveries_total", "outcome" => outcome).absolute(0);
    }
    for name in [
        "cliffwatch_alerts_raised_total",
        "cliffwatch_webhook_deliveries_pruned_total",
        "cliffwatch_epoch_observations_pruned_total",
        "cliffwatch_watch_folders_pruned_total",
    ] {
        metrics::counter!(name).absolute(0);
    }
    metrics::gauge!("cliffwatch_upload_slots_busy").increment(0.0);
    metrics::gauge!("cliffwatch_webhook_queue_depth").increment(0.0);
    let _ = metrics::histogram!("cliffwatch_adjustment_seconds");
}

/// `GET /healthz`: the process answers.
#[utoipa::path(get, path = "/healthz", operation_id = "get_healthz", responses((status = 200, description = "alive", body = crate::api::schemas::Status)))]
pub async fn healthz() -> impl IntoResponse {
    axum::Json(Status { status: "ok" })
}

/// `GET /readyz`: the database answers and the migrations are applied.
#[utoipa::path(get, path = "/readyz", operation_id = "get_readyz", responses((status = 200, description = "ready", body = crate::api::schemas::Status), (status = 503, description = "not ready", body = crate::api::schemas::ErrorBody)))]
pub async fn readyz(State(state): State<AppState>) -> Result<impl IntoResponse, ApiError> {
    match state.store.ready().await {
        Ok(true) => Ok(axum::Json(Status { status: "ready" })),
        Ok(false) => Err(ApiError::new(
            StatusCode::SERVICE_UNAVAILABLE,
            "not_ready",
            "migrations pending",
        )),
        Err(e) => Err(ApiError::new(
            StatusCode::SERVICE_UNAVAILABLE,
            "not_ready",
            e.to_string(),
        )),
    }
}

/// `GET /metrics`: Prometheus text format.
#[utoipa::path(get, path = "/metrics", operation_id = "get_metrics", responses((status = 200, description = "Prometheus text format", body = String, content_type = "text/plain")))]
pub async fn metrics(State(state): State<AppState>) -> impl IntoResponse {
    if let Ok(n) = crate::store::webhooks::pending(state.store.reader()).await {
        metrics::gauge!("cliffwatch_webhook_queue_depth").set(n as f64);
    }
    (
        [(header::CONTENT_TYPE, "text/plain; version=0.0.4")],
        state.metrics.render(),
    )
}
