//! `cliffwatch serve [--config FILE] [--listen ADDR:PORT] [--data-dir DIR] [--watch-dir DIR]`.

use std::path::PathBuf;

use anyhow::Context;
use cliffwatch::config::{Config, LogFormat, Overrides};
use cliffwatch::daemon::serve;
use cliffwatch::shutdown;

/// Arguments of `cliffwatch serve` (environment: `CLIFFWATCH_LISTEN`, `CLIFFWATCH_DATA_DIR`,
/// `CLIFFWATCH_WATCH_DIR`, `CLIFFWATCH_DATABASE_URL`, and `CLIFFWATCH_<OPTION>` for every option of `config/default.toml`).
#[derive(clap::Args)]
pub struct ServeArgs {
    /// Configuration file (TOML), layered over the embedded defaults.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Address and port to listen on (default 127.0.0.1:8080).
    #[arg(long)]
    pub listen: Option<String>,
    /// Data directory (default ./data).
    #[arg(long)]
    pub data_dir: Option<PathBuf>,
    /// Watched directory of image epochs (default: none).
    #[arg(long)]
    pub watch_dir: Option<PathBuf>,
    /// Database URL: sqlite://PATH or postgres://USER:PASSWORD@HOST:PORT/DB (default: SQLite
    /// file cliffwatch.db in the data directory).
    #[arg(long)]
    pub database_url: Option<String>,
}

/// Runs `cliffwatch serve` until SIGTERM or ctrl-c.
pub fn run(args: ServeArgs) -> anyhow::Result<()> {
    let overrides = Overrides {
        listen: args.listen,
        data_dir: args.data_dir,
        watch_dir: args.watch_dir,
        database_url: args.database_url,
    };
    let config =
        Config::load(args.config.as_deref(), &overrides).context("loading the configuration")?;
    init_tracing(config.log_format);
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .context("starting the runtime")?;
    let result = runtime.block_on(serve(config, shutdown::signal()));
    // Blocking tasks still running (an adjustment between two cancellation checks, an image
    // being decoded) are not waited for: the process ends now, and nothing they would write is
    // half-stored (each write is one transaction, begun after the computation).
    runtime.shutdown_timeout(std::time::Duration::from_millis(100));
    result?;
    Ok(())
}

/// Logs to stderr, human-readable or JSON, levels from `RUST_LOG` (default `info`).
pub fn init_tracing(format: LogFormat) {
    use tracing_subscriber::EnvFilter;
    let filter = EnvFilter::try_from_default_env().unwrap_or_else(|_| EnvFilter::new("info"));
    let builder = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr);
    match format {
        LogFormat::Json => builder.json().init(),
        LogFormat::Human => builder.init(),
    }
}
