//! The state every handler of the API and the dashboard shares.

use std::sync::Arc;

use metrics_exporter_prometheus::PrometheusHandle;

use crate::config::Config;
use crate::store::Store;

/// What every handler shares. Cheap to clone.
#[derive(Clone)]
pub struct AppState {
    /// The database.
    pub store: Store,
    /// The configuration in force.
    pub config: Arc<Config>,
    /// Renders `/metrics`.
    pub metrics: PrometheusHandle,
    /// The upload slots of this node.
    pub uploads: crate::service::admission::UploadGate,
}

impl AppState {
    /// Where people reach the dashboard (the configuration's `public_url`), which the use
    /// cases that write alert events link the events' bodies under; `None`: no links.
    pub fn public_url(&self) -> Option<&str> {
        self.config.public_url.as_deref()
    }
}
