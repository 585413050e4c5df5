//! `cliffwatch backup FILE [--config FILE] [--data-dir DIR]`: a consistent online copy of the
//! database (`VACUUM INTO`), safe while the server runs.

use std::path::PathBuf;
use std::time::Duration;

use anyhow::Context;
use cliffwatch::config::{Config, Overrides};

/// Arguments of `cliffwatch backup`.
#[derive(clap::Args)]
pub struct BackupArgs {
    /// Target file (must not exist).
    pub file: PathBuf,
    /// Configuration file (for `data_dir`).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Data directory of the database (default: from the configuration, ./data).
    #[arg(long)]
    pub data_dir: Option<PathBuf>,
}

/// Runs `cliffwatch backup`.
pub fn run(args: BackupArgs) -> anyhow::Result<()> {
    let overrides = Overrides {
        data_dir: args.data_dir,
        ..Overrides::default()
    };
    let config =
        Config::load(args.config.as_deref(), &overrides).context("loading the configuration")?;
    let source = config.database_path();
    anyhow::ensure!(source.exists(), "no database at {}", source.display());
    anyhow::ensure!(
        !args.file.exists(),
        "{} exists already",
        args.file.display()
    );
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .context("starting the runtime")?;
    runtime
        .block_on(cliffwatch::store::backup_file(
            &source,
            &args.file,
            Duration::from_millis(config.busy_timeout_ms),
        ))
        .with_context(|| format!("backing up {} to {}", source.display(), args.file.display()))?;
    eprintln!(
        "backup of {} written to {}",
        source.display(),
        args.file.display()
    );
    Ok(())
}
