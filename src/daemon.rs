//! The daemon: opens the database, applies the configuration, and runs its parts under one
//! shutdown signal ([`crate::shutdown`]): the HTTP server ([`crate::http`]: the API and the dashboard), the
//! watched directory ([`crate::watch`]), and the background loops of [`crate::workers`] (webhook
//! delivery, the Alertmanager re-posts, the campaign check, the retentions) and, on SQLite, the
//! WAL checkpoints
//! ([`store::wal_checkpoint`]).
//!
//! On shutdown the listener stops accepting, in-flight requests (uploads included) finish within
//! the grace period, the background parts stop, and the database is closed.

use std::future::Future;
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use thiserror::Error;
use tokio::net::TcpListener;

use crate::api::health;
use crate::config::{Config, ConfigError};
use crate::http::AppState;
use crate::service;
use crate::service::admission::UploadGate;
use crate::shutdown;
use crate::store::{self, Store, StoreError, StoreOptions};
use crate::workers;

/// The server cannot start or failed.
#[derive(Debug, Error)]
pub enum ServeError {
    /// Bad configuration.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// The database cannot be opened or migrated.
    #[error(transparent)]
    Store(#[from] StoreError),
    /// A site of the configuration is invalid.
    #[error("configured site '{0}': {1}")]
    Site(String, String),
    /// The listener failed.
    #[error("listening on {addr}: {source}")]
    Io {
        /// The address.
        addr: String,
        /// The cause.
        source: std::io::Error,
    },
}

/// A server bound to its address with its database open, not yet serving.
pub struct Bound {
    listener: TcpListener,
    addr: SocketAddr,
    state: AppState,
}

/// Checks the configuration, opens the database (applying migrations), registers configured sites
/// and webhooks, and binds the listener.
pub async fn bind(config: Config) -> Result<Bound, ServeError> {
    config.check()?;
    let addr = config.listen_addr()?;
    let options = StoreOptions {
        read_connections: config.read_connections,
        busy_timeout: Duration::from_millis(config.busy_timeout_ms),
        write_connections: config.database_write_connections,
    };
    let url = config.database_url();
    let store = Store::connect(&url, &options).await?;
    tracing::info!(database = %store::redacted_url(&url), backend = ?store.backend(), "database open");
    service::configured::apply_configured(&store, &config)
        .await
        .map_err(|e| match e {
            service::configured::ConfiguredError::Item(item, message) => {
                ServeError::Site(item, message)
            }
            service::configured::ConfiguredError::Store(e) => ServeError::Store(e),
        })?;
    service::recompute::recompute_outdated(&store, config.public_url.as_deref())
        .await
        .map_err(|e| ServeError::Site("(recompute at start)".into(), e.to_string()))?;
    let listener = TcpListener::bind(addr)
        .await
        .map_err(|source| ServeError::Io {
            addr: addr.to_string(),
            source,
        })?;
    let addr = listener.local_addr().map_err(|source| ServeError::Io {
        addr: addr.to_string(),
        source,
    })?;
    let metrics = health::metrics_handle(&config.node_name(addr.port()));
    let uploads = UploadGate::new(
        config.max_concurrent_uploads,
        Duration::try_from_secs_f64(config.upload_queue_secs).unwrap_or_default(),
    )
    .with_budget(Duration::from_secs(config.compute_budget_secs));
    tracing::info!(
        slots = uploads.size(),
        wait_secs = config.upload_queue_secs,
        "upload slots"
    );
    let state = AppState {
        store,
        config: Arc::new(config),
        metrics,
        uploads,
    };
    Ok(Bound {
        listener,
        addr,
        state,
    })
}

impl Bound {
    /// The bound address (the real port when the configuration said port 0).
    pub fn local_addr(&self) -> SocketAddr {
        self.addr
    }

    /// The shared state (database, configuration).
    pub fn state(&self) -> &AppState {
        &self.state
    }

    /// Serves until `shutdown` completes, then lets in-flight requests finish (at most
    /// `shutdown_grace_secs`) and closes the database.
    pub async fn run(
        self,
        shutdown: impl Future<Output = ()> + Send + 'static,
    ) -> Result<(), ServeError> {
        let Bound {
            listener,
            addr,
            state,
        } = self;
        let grace = Duration::from_secs(state.config.shutdown_grace_secs);
        let store = state.store.clone();
        let (trigger, stop) = shutdown::channel();
        tokio::spawn(async move {
            shutdown.await;
            trigger.trigger();
        });
        let mut parts = Vec::new();
        if let Some(dir) = &state.config.watch_dir {
            tracing::info!(watch_dir = %dir.display(), "watching directory");
            let mut opts = crate::watch::WatchOptions::new(dir.clone());
            opts.limits = service::ingest::EpochLimits::from_config(&state.config);
            opts.public_url = state.config.public_url.clone();
            let (store, stop) = (store.clone(), stop.clone());
            parts.push(tokio::spawn(async move {
                if let Err(e) = crate::watch::run(store, opts, stop).await {
                    tracing::error!(error = %e, "watched directory stopped");
                }
            }));
        }
        parts.push(tokio::spawn(workers::webhook_delivery::run(
            store.clone(),
            workers::webhook_delivery::WorkerConfig::from_config(&state.config),
            stop.clone(),
        )));
        parts.push(tokio::spawn(workers::alertmanager_resend::run(
            store.clone(),
            workers::alertmanager_resend::ResendConfig::from_config(&state.config),
            stop.clone(),
        )));
        parts.push(tokio::spawn(workers::overdue::run(
            store.clone(),
            Duration::from_secs(state.config.overdue_check_secs.max(1)),
            state.config.public_url.clone(),
            stop.clone(),
        )));
        let retention = workers::retention::Retention::from_config(&state.config);
        if retention.any() {
            parts.push(tokio::spawn(workers::retention::run(
                store.clone(),
                retention,
                stop.clone(),
            )));
        }
        let done_days = state.config.watch_done_retention_days;
        if let (Some(dir), true) = (&state.config.watch_dir, done_days > 0) {
            parts.push(tokio::spawn(workers::watch_retention::run(
                store.clone(),
                dir.clone(),
                Duration::from_secs(done_days.saturating_mul(86_400)),
                stop.clone(),
            )));
        }
        if store.backend() == store::Backend::Sqlite {
            parts.push(tokio::spawn(checkpoint_wal(store.clone(), stop.clone())));
        }
        let graceful = {
            let stop = stop.clone();
            async move {
                stop.requested().await;
                tracing::info!("shutting down: finishing in-flight requests");
            }
        };
        tracing::info!(%addr, "listening");
        let uploads = state.uploads.clone();
        // The one service: the API's and the dashboard's routes on the shared HTTP layer.
        let app = crate::http::router(state, crate::api::routes(), crate::dashboard::routes());
        let server = axum::serve(listener, app).with_graceful_shutdown(graceful);
        // The grace period covers the whole stop: the requests drain for all of it but the end
        // reserve, in which the background parts stop and the database closes.
        let reserve = END_RESERVE.min(grace / 2);
        let grace_over = async move {
            stop.requested().await;
            tokio::time::sleep(grace - reserve).await;
        };
        tokio::select! {
            r = server => r.map_err(|source| ServeError::Io { addr: addr.to_string(), source })?,
            _ = grace_over => tracing::warn!("grace period over: dropping the remaining connections"),
        }
        // Whatever still computes for an upload is no longer wanted: nothing of it is stored.
        uploads.stop_computing();
        // The parts see the same signal and get one deadline together; a webhook attempt in
        // flight is at most repeated later, a folder being taken is taken again at the next start.
        let parts_deadline = tokio::time::Instant::now() + reserve / 2;
        for part in parts {
            if tokio::time::timeout_at(parts_deadline, part).await.is_err() {
                tracing::warn!("a background part did not stop in time; leaving it");
            }
        }
        store.close().await;
        tracing::info!("stopped");
        Ok(())
    }
}

/// The end of the shutdown grace period (at most half of it) kept for the background parts
/// (watched directory, workers), which get half of it together, and the database's close. A part
/// between two steps stops at once; one inside a step (a webhook attempt, a folder's detection)
/// is left to the process's exit, which stores nothing half-way.
pub const END_RESERVE: Duration = Duration::from_secs(1);

/// SQLite: checkpoints the WAL every [`store::wal_checkpoint::CHECKPOINT_INTERVAL`] until
/// shutdown, so that no upload's commit does it ([`store::wal_checkpoint`]).
async fn checkpoint_wal(store: Store, stop: shutdown::Shutdown) {
    loop {
        if let Err(e) = store.checkpoint_wal().await {
            tracing::warn!(error = %e, "WAL checkpoint failed");
        }
        if stop.sleep(store::wal_checkpoint::CHECKPOINT_INTERVAL).await {
            break;
        }
    }
}

/// Binds and serves until `shutdown` completes (e.g. [`shutdown::signal`]).
pub async fn serve(
    config: Config,
    shutdown: impl Future<Output = ()> + Send + 'static,
) -> Result<(), ServeError> {
    bind(config).await?.run(shutdown).await
}
