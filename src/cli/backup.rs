//! `cliffwatch backup FILE [--config FILE] [--data-dir DIR] [--database-url URL]`: a consistent
//! online copy of a SQLite database (`VACUUM INTO`), safe while the server runs. A PostgreSQL
//! database is backed up with PostgreSQL's own tools; the command says how.

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
    /// Database URL (default: from the configuration; SQLite in the data directory).
    #[arg(long)]
    pub database_url: Option<String>,
}

/// How a PostgreSQL store is backed up (printed by `cliffwatch backup`, in the README).
pub const PG_DUMP_RECIPE: &str = "a PostgreSQL store is backed up with PostgreSQL's tools, e.g. \
`pg_dump --format=custom --file=cliffwatch.dump \"$DATABASE_URL\"` (restore: `pg_restore --dbname=URL \
cliffwatch.dump`), or the managed service's snapshots; `cliffwatch migrate-store` copies it to a \
SQLite file";

/// Runs `cliffwatch backup`.
pub fn run(args: BackupArgs) -> anyhow::Result<()> {
    let overrides = Overrides {
        data_dir: args.data_dir,
        database_url: args.database_url,
        ..Overrides::default()
    };
    let config =
        Config::load(args.config.as_deref(), &overrides).context("loading the configuration")?;
    let url = config.database_url();
    let Some(source) = cliffwatch::store::sqlite_path(&url).map(PathBuf::from) else {
        anyhow::bail!("{PG_DUMP_RECIPE}");
    };
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
