//! Liveness, readiness and the Prometheus metrics.

use std::sync::OnceLock;

use axum::extract::State;
use axum::http::{header, StatusCode};
use axum::response::IntoResponse;
use metrics_exporter_prometheus::{Matcher, PrometheusBuilder, PrometheusHandle};

use super::schemas::Status;
use crate::http::error::ApiError;
use crate::http::AppState;

/// Upper bounds (s) of the adjustment-time histogram's buckets: from a small epoch's tenth of a
/// second to the default compute budget (120 s).
const ADJUSTMENT_BUCKETS: [f64; 12] = [
    0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0, 10.0, 20.0, 30.0, 60.0, 120.0,
];

/// The process-wide Prometheus recorder (installed once, shared by every server of the process),
/// every series labelled `node` with the name the first server of the process gives.
pub fn metrics_handle(node: &str) -> PrometheusHandle {
    static HANDLE: OnceLock<PrometheusHandle> = OnceLock::new();
    HANDLE
        .get_or_init(|| {
            let recorder = PrometheusBuilder::new()
                .add_global_label("node", node)
                .set_buckets_for_metric(
                    Matcher::Full("cliffwatch_adjustment_seconds".into()),
                    &ADJUSTMENT_BUCKETS,
                )
                .expect("the buckets are not empty")
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
    metrics::describe_gauge!(
        "cliffwatch_open_alerts",
        "open and acknowledged alerts by site and level"
    );
    metrics::describe_gauge!(
        "cliffwatch_last_epoch_age_seconds",
        "time since the observation of each site's last epoch (s)"
    );
    metrics::describe_gauge!(
        "cliffwatch_site_schedule_seconds",
        "each site's expected time between epochs (s), where set"
    );
    metrics::describe_counter!(
        "cliffwatch_watch_folders_total",
        "watched-directory epoch folders taken, by site and outcome (done, failed, error)"
    );
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
    site_gauges(&state).await;
    (
        [(header::CONTENT_TYPE, "text/plain; version=0.0.4")],
        state.metrics.render(),
    )
}

/// The per-site gauges, read from the store at each scrape: open alerts by level (0 for a level
/// without one, so that a resolved alarm reads 0 rather than vanishing), the age of the last
/// epoch and the schedule (absent before the first epoch, or without a schedule). A store that
/// cannot be read leaves the last values.
async fn site_gauges(state: &AppState) {
    use crate::store::operations;
    use cliffwatch_core::analysis::AlertLevel;
    let db = state.store.reader();
    let (Ok(counts), Ok(sites)) = (
        operations::open_alert_counts(db).await,
        operations::site_freshness(db).await,
    ) else {
        return;
    };
    let now = chrono::Utc::now();
    for (site, schedule, last) in sites {
        for level in [AlertLevel::Watch, AlertLevel::Warning, AlertLevel::Alarm] {
            let n = counts
                .iter()
                .find(|(s, l, _)| *s == site && l == level.as_str())
                .map_or(0, |c| c.2);
            metrics::gauge!("cliffwatch_open_alerts", "site" => site.clone(), "level" => level.as_str())
                .set(n as f64);
        }
        // At 0 before a site's first folder, so that the first failure shows as an increase.
        for outcome in ["done", "failed"] {
            metrics::counter!("cliffwatch_watch_folders_total", "site" => site.clone(), "outcome" => outcome)
                .increment(0);
        }
        if let Some(t) = last.as_deref().and_then(crate::store::parse_timestamp) {
            metrics::gauge!("cliffwatch_last_epoch_age_seconds", "site" => site.clone())
                .set((now - t).num_milliseconds() as f64 / 1000.0);
        }
        if let Some(h) = schedule {
            metrics::gauge!("cliffwatch_site_schedule_seconds", "site" => site.clone())
                .set(h * 3600.0);
        }
    }
}
